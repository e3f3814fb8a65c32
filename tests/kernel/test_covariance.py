"""Keypoint covariance: closed forms, propagation through transforms, Monte Carlo consistency."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from benchmark_modules import load
from laser_corners import CornerDetector, DetectorParams
from laser_corners.kernel.covariance import line_fit_covariance
from laser_corners.sim import corner_scan

_study = load("covariance_consistency")  # the Monte Carlo study, in benchmarks/
CHI2_2_95, covariance_consistency = _study.CHI2_2_95, _study.covariance_consistency


def test_line_fit_covariance_matches_ols_formula() -> None:
    rng = np.random.default_rng(0)
    v = rng.uniform(-1, 1, 30)
    design = np.column_stack([np.ones_like(v), v])
    expected = 0.01**2 * np.linalg.inv(design.T @ design)
    var0, cov01, var1 = line_fit_covariance(30.0, v.mean(), ((v - v.mean()) ** 2).sum(), 1e-4)
    assert np.allclose([var0, cov01, var1], [expected[0, 0], expected[0, 1], expected[1, 1]])


def test_covariance_is_positive_definite_at_zero_noise_and_rotates() -> None:
    kps = CornerDetector().detect(corner_scan(corner=(2.0, 1.0)))
    assert kps.cov.shape == (1, 2, 2)
    assert np.all(np.linalg.eigvalsh(kps.cov[0]) > 0.0)  # the floor: never singular
    assert kps.scale_index[0] >= 0
    moved = kps.transformed((0.0, 0.0, math.pi / 2))
    c = kps.cov[0]
    assert np.allclose(moved.cov[0], [[c[1, 1], -c[0, 1]], [-c[0, 1], c[0, 0]]])
    rec = kps.to_records()
    assert rec.cov_xx[0] == c[0, 0] and rec.cov_yy[0] == c[1, 1]


def test_covariance_grows_with_noise() -> None:
    rng = np.random.default_rng(3)
    clean = CornerDetector().detect(corner_scan(corner=(3.0, 1.0)))
    noisy = CornerDetector().detect(corner_scan(corner=(3.0, 1.0), noise_sigma=0.01, rng=rng))
    assert np.trace(noisy.cov[0]) > 4.0 * np.trace(clean.cov[0])


def test_monte_carlo_consistency_robust_and_paper() -> None:
    # noise uniform in [0, 0.03] m, ranges 0.5-8 m; the 95 % ellipse holds 92-98 % of the
    # true corners and the median NEES is in [0.7, 2] (chi2(2): 0.95 and 1.39)
    for params in (None, lambda scan, noise: DetectorParams()):
        res = covariance_consistency(
            n_trials=400, noises=(0.0, 0.03), continuous=True, params=params, seed=7
        )
        assert res.nees.size >= 300
        assert 0.92 <= res.inside_95 <= 0.98, res.inside_95
        assert 0.7 <= res.median_nees <= 2.0, res.median_nees
        assert CHI2_2_95 > 5.99


def test_covariance_columns_in_csv_and_parquet(tmp_path) -> None:  # type: ignore[no-untyped-def]
    import csv

    import pyarrow.parquet as pq

    from laser_corners.io.writers import CsvKeypointWriter, ParquetKeypointWriter

    scan = corner_scan(corner=(2.0, 1.0), noise_sigma=0.005, rng=np.random.default_rng(0))
    kps = CornerDetector().detect(scan)
    with CsvKeypointWriter(tmp_path / "k.csv", with_map=False) as w:
        w.write(0, scan, kps)
    with ParquetKeypointWriter(tmp_path / "k.parquet", with_map=False) as w:
        w.write_many(0, [scan, scan], [kps, kps])
    rows = list(csv.DictReader((tmp_path / "k.csv").open()))
    assert float(rows[0]["cov_xx"]) == kps.cov[0, 0, 0]
    assert float(rows[0]["cov_xy"]) == kps.cov[0, 0, 1]
    table = pq.read_table(tmp_path / "k.parquet").to_pydict()
    assert table["cov_yy"][:1] == [kps.cov[0, 1, 1]] and len(table["cov_yy"]) == 2 * len(kps)


def test_covariance_neighbourhoods_step_over_dropouts_like_the_detector() -> None:
    # a dropped beam beside the corner: with max_gap_beams = 2 the detector bridges it, and so
    # must the covariance's neighbourhoods (a run cut at the gap leaves a one-point wall)
    rng = np.random.default_rng(5)
    scan = corner_scan(corner=(3.0, 1.0), noise_sigma=0.005, rng=rng)
    det = CornerDetector(DetectorParams(max_gap_beams=2))
    whole = det.detect(scan)
    assert len(whole) == 1
    ranges = scan.ranges.copy()
    ranges[int(whole.beam_index[0]) + 2] = np.nan
    holed = det.detect(replace(scan, ranges=ranges))
    assert len(holed) == 1
    trace_whole, trace_holed = np.trace(whole.cov[0]), np.trace(holed.cov[0])
    assert 0.7 < trace_holed / trace_whole < 1.4
