"""The numba kernel against the plain-Python reference implementation (same keypoints)."""

from __future__ import annotations

import math

import numpy as np
import pytest

import reference_detector as ref
from benchmark_modules import load
from laser_corners import CornerDetector, DetectorParams, LaserScan
from laser_corners.sim import UST_10LX, SensorProfile, World, corner_scan, rectangular_room

TOL = 1e-9

COARSE = SensorProfile("coarse", 180.0, 0.5, 0.05, 30.0, 10.0, 0.01)


def random_world(rng: np.random.Generator) -> World:
    """A room with random size and a few random rectangular/triangular obstacles."""
    w, d = rng.uniform(3, 9), rng.uniform(3, 9)
    room = [[-w / 2, -d / 2], [w / 2, -d / 2], [w / 2, d / 2], [-w / 2, d / 2]]
    world = World().add_polygon(room)
    for _ in range(rng.integers(1, 4)):
        cx, cy = rng.uniform(-w / 3, w / 3), rng.uniform(-d / 3, d / 3)
        if abs(cx) < 0.5 and abs(cy) < 0.5:
            continue
        n = int(rng.integers(3, 6))
        angles = np.sort(rng.uniform(0, 2 * np.pi, n))
        radius = rng.uniform(0.2, 0.6)
        world.add_polygon(np.c_[cx + radius * np.cos(angles), cy + radius * np.sin(angles)])
    return world


def assert_same(scan: LaserScan, params: DetectorParams) -> int:
    det = CornerDetector(params)
    keypoints, raw = det.detect(scan, return_candidates=True)
    expected_raw = ref.candidates(scan, params)
    assert raw.beam_index.tolist() == sorted(expected_raw)
    for i, j in enumerate(raw.beam_index):
        e = expected_raw[int(j)]
        assert np.allclose(raw.xy[i], e["xy"], atol=TOL, rtol=0)
        assert raw.n_scales[i] == e["n_scales"]
        assert raw.rmse[i] == pytest.approx(e["rmse"], abs=1e-9)
        assert raw.opening_angle_deg[i] == pytest.approx(e["opening"], abs=1e-6)
        assert math.cos(raw.orientation[i] - e["orientation"]) > 1 - 1e-9
    expected = ref.merge(expected_raw, params.merge_radius)
    assert len(keypoints) == len(expected)
    for i, e in enumerate(expected):
        assert np.allclose(keypoints.xy[i], e["xy"], atol=TOL, rtol=0)
        assert keypoints.beam_index[i] == e["beam"]
        assert keypoints.n_merged[i] == e["n_merged"]
        assert keypoints.rmse[i] == pytest.approx(e["rmse"], abs=1e-9)
    return len(raw)


@pytest.mark.parametrize("seed", range(6))
def test_kernel_matches_reference_on_simulated_scans(seed: int) -> None:
    rng = np.random.default_rng(seed)
    world = random_world(rng)
    sensor = UST_10LX if seed % 2 == 0 else COARSE
    pose = (rng.uniform(-0.4, 0.4), rng.uniform(-0.4, 0.4), rng.uniform(-np.pi, np.pi))
    noise = [0.0, 0.002, 0.005, 0.01, 0.02, 0.03][seed]
    scan = world.scan(pose, sensor, noise_sigma=noise, rng=rng)
    params = (
        DetectorParams()
        if sensor is UST_10LX
        else DetectorParams(scales=(0.1, 0.15, 0.2, 0.25, 0.3, 0.4), max_point_distance=0.08)
    )
    assert_same(scan, params)


def test_kernel_matches_reference_with_many_candidates() -> None:
    """A scan with several corners, gaps and noise: many candidates are compared."""
    scan = rectangular_room().scan((0.3, -0.2, 0.1), UST_10LX, 0.003, np.random.default_rng(1))
    ranges = scan.ranges.copy()
    ranges[100:104] = np.nan
    ranges[500] = np.inf
    ranges[700] = 0.0
    gappy = LaserScan(ranges, scan.angle_min, scan.angle_increment, scan.range_min, scan.range_max)
    assert assert_same(gappy, DetectorParams()) >= 5


def test_kernel_matches_reference_on_random_ranges() -> None:
    """Random ranges (a piecewise-smooth random walk with gaps) under loose thresholds."""
    rng = np.random.default_rng(42)
    for _ in range(3):
        ranges = 2.0 + np.cumsum(rng.normal(0, 0.01, 400))
        ranges[rng.random(400) < 0.02] = np.nan
        scan = LaserScan(ranges, -1.5, 0.0075, 0.05, 20.0)
        params = DetectorParams(
            max_fit_rmse=0.05,
            min_angle_deg=20,
            max_angle_deg=160,
            max_point_distance=0.1,
            max_centroid_distance=0.05,
        )
        assert_same(scan, params)


def test_kernel_matches_reference_without_merging() -> None:
    scan = corner_scan(noise_sigma=0.004, rng=np.random.default_rng(3))
    params = DetectorParams(merge_radius=0.0)
    kps = CornerDetector(params).detect(scan)
    expected = ref.candidates(scan, params)
    assert kps.beam_index.tolist() == sorted(expected)
    assert (kps.n_merged == 1).all()


@pytest.mark.parametrize("max_gap", [1, 2, 4])
def test_kernel_matches_reference_when_bridging_dropouts(max_gap: int) -> None:
    """Option max_gap_beams: random dropouts (single beams and runs) bridged alike."""
    rng = np.random.default_rng(10 + max_gap)
    scan = rectangular_room().scan((0.2, 0.1, 0.3), UST_10LX, 0.003, rng)
    ranges = scan.ranges.copy()
    ranges[rng.random(ranges.size) < 0.05] = np.nan
    ranges[300:303] = np.nan
    ranges[::20] = np.inf
    gappy = LaserScan(ranges, scan.angle_min, scan.angle_increment, scan.range_min, scan.range_max)
    params = DetectorParams(max_gap_beams=max_gap)
    assert assert_same(gappy, params) >= 3
    assert assert_same(gappy, params.with_overrides({"min_extent_ratio": 0.6})) >= 1


def test_kernel_matches_reference_on_a_dense_scan() -> None:
    """A scan dense enough for the block-skipping walk (many points within each scale)."""
    world = World().add_polygon([[0.3, -0.4], [0.9, -0.4], [0.9, 0.5], [0.3, 0.5]])
    n = 1500
    inc = np.radians(60.0) / n
    angles = -np.radians(30.0) + inc * np.arange(n)
    ranges = world.cast((0.0, 0.0, 0.0), angles)
    ranges += np.random.default_rng(5).normal(0.0, 0.0005, n)
    ranges[700:702] = np.nan
    scan = LaserScan(ranges, -np.radians(30.0), inc, 0.02, 10.0)
    params = DetectorParams(
        scales=(0.05, 0.08, 0.11),
        min_consecutive_scales=2,
        max_point_distance=0.03,
        max_fit_rmse=0.01,
    )
    from laser_corners.kernel.neighbourhood import points_within as _points_within

    x, y = CornerDetector()._scan_xy(scan)
    assert _points_within(x, y, np.isfinite(x), params.scales[-1]) > 48  # the dense path
    assert assert_same(scan, params) >= 1


def test_kernel_matches_reference_with_many_sentinel_scales() -> None:
    """More than three sentinel scales (here 12 scales, runs of 2): the walk stores its
    running maxima and the other sentinels are counted from them."""
    scan = rectangular_room().scan((-0.3, 0.2, 1.0), UST_10LX, 0.005, np.random.default_rng(7))
    params = DetectorParams(
        scales=tuple(0.04 + 0.02 * k for k in range(12)), min_consecutive_scales=2
    )
    assert assert_same(scan, params) >= 3


@pytest.mark.parametrize(
    ("n_scales", "m"), [(9, 1), (9, 2), (9, 4), (7, 3), (8, 3), (10, 3), (13, 3), (3, 3), (5, 5)]
)
def test_kernel_matches_reference_for_sentinel_layouts(n_scales: int, m: int) -> None:
    """Sentinels K-m, K-2m, ...: layouts of scale count and run length (one, two, three or
    more sentinels; scales above the highest sentinel; as many scales as m)."""
    scan = rectangular_room().scan((0.4, -0.2, 0.3), UST_10LX, 0.01, np.random.default_rng(m))
    params = DetectorParams(
        scales=tuple(0.05 + 0.025 * k for k in range(n_scales)), min_consecutive_scales=m
    )
    assert assert_same(scan, params) >= 1


@pytest.mark.parametrize("radius", [0.05, 0.2, 1e-15])
def test_grid_merge_equals_single_linkage_by_all_pairs(radius: float) -> None:
    """The kernel's grid-based merge against the reference's all-pairs single linkage."""
    from laser_corners.kernel.candidates import C_K0, C_NSC, C_OPEN, C_ORIENT, C_RMSE, C_X, C_Y, NC
    from laser_corners.kernel.merge import M_BEAM, M_NMERGED, M_X, M_Y, NM, merge

    rng = np.random.default_rng(3)
    n = 400
    centres = rng.uniform(-3, 3, (12, 2))
    xy = centres[rng.integers(0, 12, n)] + rng.normal(0, 0.05, (n, 2))
    xy[::7] = rng.uniform(-3, 3, (len(xy[::7]), 2))
    cand = np.zeros((n, NC))
    has = rng.random(n) < 0.8
    cand[:, C_X], cand[:, C_Y] = xy[:, 0], xy[:, 1]
    cand[:, C_NSC] = np.where(has, rng.integers(3, 6, n), 0)
    cand[:, C_RMSE] = rng.choice([0.001, 0.002, 0.003], n)
    cand[:, C_K0], cand[:, C_OPEN], cand[:, C_ORIENT] = 0, 90.0, 0.0
    rows = np.empty((n, NM))
    count = merge(cand, radius, rows)
    cands = {
        j: {"xy": (xy[j, 0], xy[j, 1]), "rmse": cand[j, C_RMSE], "n_scales": int(cand[j, C_NSC])}
        for j in np.flatnonzero(has)
    }
    expected = ref.merge(cands, radius)
    assert count == len(expected)
    for row, e in zip(rows[:count], expected, strict=True):
        assert row[M_BEAM] == e["beam"] and row[M_NMERGED] == e["n_merged"]
        assert (row[M_X], row[M_Y]) == e["xy"]


def _frozen_detector_class() -> type:
    """``CornerDetector`` of the frozen kernel of 91ca792 (checked against the reference by
    this file's tests at that commit): an independent implementation for large scans."""
    return load("frozen_kernel_91ca792").CornerDetector


def test_kernel_matches_frozen_kernel_on_a_100k_beam_scan() -> None:
    """100,000 beams over 360 degrees (the block-skipping walk, the grid merge) against the
    frozen kernel's plain walk and all-pairs merge: same candidates and keypoints."""
    n = 100_000
    inc = 2 * np.pi / n
    world = World().add_polygon(
        [[-3.0, -2.5], [4.0, -2.5], [4.0, 1.0], [1.5, 1.0], [1.5, 3.0], [-3.0, 3.0]]
    )
    ranges = world.cast((0.4, -0.3, 0.25), -np.pi + inc * np.arange(n))
    ranges += np.random.default_rng(2).normal(0.0, 0.001, n)
    ranges[5000:5003] = np.nan
    scan = LaserScan(ranges, -np.pi, inc, 0.02, 30.0)
    new_kp, new_raw = CornerDetector().detect(scan, return_candidates=True)
    old_kp, old_raw = _frozen_detector_class()().detect(scan, return_candidates=True)
    assert len(new_raw) > 1000 and len(new_kp) >= 5
    for new, old in ((new_raw, old_raw), (new_kp, old_kp)):
        assert new.beam_index.tolist() == old.beam_index.tolist()
        assert np.allclose(new.xy, old.xy, atol=TOL, rtol=0)
        assert (new.n_scales == old.n_scales).all() and (new.n_merged == old.n_merged).all()
