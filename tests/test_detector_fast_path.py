"""The per-scan fast path of ``CornerDetector.detect``: the cached geometry, the early exit
on scans with too few valid points, and keypoint arrays made on first access."""

from __future__ import annotations

import pickle

import numba
import numpy as np

from laser_corners import CornerDetector, DetectorParams, LaserScan
from laser_corners.sim import corner_scan

FIELDS = (
    "xy",
    "beam_index",
    "opening_angle_deg",
    "orientation",
    "n_scales",
    "rmse",
    "n_merged",
    "scale_index",
)


def _scan() -> LaserScan:
    return corner_scan(corner=(2.0, 1.0), noise_sigma=0.005, rng=np.random.default_rng(3))


def _assert_same(a, b) -> None:  # type: ignore[no-untyped-def]
    assert len(a) == len(b)
    for name in FIELDS:
        got, want = getattr(a, name), getattr(b, name)
        assert got.dtype == want.dtype and got.shape == want.shape, name
        assert np.array_equal(got, want), name
    assert np.array_equal(a.cov, b.cov)


def test_geometry_cache_follows_every_geometry_field() -> None:
    detector = CornerDetector()
    scan = _scan()
    first = detector.detect(scan)
    assert len(first) == 1
    r = scan.ranges
    # same beams, range_max below every return: all gaps, whatever was cached before
    near = LaserScan(r, scan.angle_min, scan.angle_increment, scan.range_min, 1.0)
    assert len(detector.detect(near)) == 0
    # the beams turned by a quarter turn: the keypoint turns with them
    turned = LaserScan(
        r, scan.angle_min + np.pi / 2, scan.angle_increment, scan.range_min, scan.range_max
    )
    xy = detector.detect(turned).xy
    assert np.allclose(xy, [[-first.xy[0, 1], first.xy[0, 0]]], atol=1e-9)
    shorter = LaserScan(
        r[:-1], scan.angle_min, scan.angle_increment, scan.range_min, scan.range_max
    )
    assert len(detector.detect(shorter)) == 1
    _assert_same(detector.detect(scan), CornerDetector().detect(scan))


def test_deferred_arrays_equal_the_eager_ones() -> None:
    scan = _scan()
    detector = CornerDetector()
    kps = detector.detect(scan)
    assert len(kps) == 1 and "_source" in kps.__dict__  # len() made no array
    eager, _ = detector.detect(scan, return_candidates=True)  # arrays made at once
    assert "_source" not in eager.__dict__
    _assert_same(kps, eager)
    assert "_source" not in kps.__dict__ and kps.xy.flags.c_contiguous
    unread = detector.detect(scan)
    restored = pickle.loads(pickle.dumps(unread))
    _assert_same(restored, eager)
    _assert_same(unread.transformed((0.0, 0.0, 0.0), frame_id=""), eager)


def test_no_keypoints_are_empty_arrays_of_the_right_types() -> None:
    detector = CornerDetector()
    scan = LaserScan(np.full(180, 30.0), -np.pi / 2, np.pi / 180, 0.1, 30.0)  # no returns
    kps = detector.detect(scan)
    assert len(kps) == 0
    assert kps.xy.shape == (0, 2) and kps.cov.shape == (0, 2, 2)
    assert kps.beam_index.dtype == np.int64 and kps.rmse.dtype == np.float64
    assert len(kps.to_records()) == 0


def test_early_exit_agrees_with_the_full_kernel_around_its_threshold() -> None:
    """A scan with fewer valid points than 2 * min_points - 1 skips the kernel; around that
    count ``detect`` must equal ``detect_points`` (which always runs the whole kernel)."""
    params = DetectorParams(min_points=3, scales=(0.05, 0.1, 0.15), min_consecutive_scales=2)
    detector = CornerDetector(params)
    base = corner_scan(corner=(1.0, 0.5))
    centre = int(np.argmin(np.abs(base.angles - np.arctan2(0.5, 1.0))))
    found = []
    for n_valid in range(2, 9):
        ranges = np.full(base.n_beams, np.nan)
        lo = centre - n_valid // 2
        ranges[lo : lo + n_valid] = base.ranges[lo : lo + n_valid]
        scan = LaserScan(
            ranges, base.angle_min, base.angle_increment, base.range_min, base.range_max
        )
        xy, _ = scan.to_cartesian()
        kps = detector.detect(scan)
        want = detector.detect_points(xy)
        assert np.array_equal(kps.xy, want.xy) and np.array_equal(kps.n_scales, want.n_scales)
        found.append(len(kps))
    assert found[:4] == [0, 0, 0, 1]  # 5 = 2 * min_points - 1 valid points: one corner


def test_detect_many_defers_like_detect() -> None:
    scans = [_scan(), corner_scan(corner=(1.5, -1.0))]
    detector = CornerDetector()
    batch = detector.detect_many(scans)
    for scan, got in zip(scans, batch, strict=True):
        assert "_source" in got.__dict__ and got._cov_is_lazy()
        _assert_same(got, detector.detect(scan))


def test_detect_many_with_one_numba_thread_equals_detect() -> None:
    """With one numba thread ``detect_many`` takes ``detect``'s path, scan by scan."""
    scans = [_scan(), corner_scan(corner=(1.5, -1.0)), corner_scan(corner=(2.5, 0.5))]
    detector = CornerDetector()
    threads = numba.get_num_threads()
    numba.set_num_threads(1)
    try:
        batch = detector.detect_many(scans)
    finally:
        numba.set_num_threads(threads)
    assert sum(len(kps) for kps in batch) == 3
    for scan, got in zip(scans, batch, strict=True):
        _assert_same(got, detector.detect(scan))
