"""Keypoints: the lazy covariance (computed on first access, kept, pickled, transformed)."""

from __future__ import annotations

import dataclasses
import math
import pickle

import numpy as np

from laser_corners import CornerDetector, DetectorParams, Keypoints
from laser_corners.sim import corner_scan


def _scan():  # type: ignore[no-untyped-def]
    return corner_scan(corner=(2.0, 1.0), noise_sigma=0.005, rng=np.random.default_rng(1))


def test_detect_defers_the_covariance_and_keeps_it() -> None:
    kps = CornerDetector().detect(_scan())
    assert len(kps) == 1 and kps._cov_is_lazy()
    cov = kps.cov
    assert not kps._cov_is_lazy() and kps.cov is cov  # computed once, then kept
    assert np.all(np.linalg.eigvalsh(cov[0]) > 0.0)
    again = CornerDetector().detect(_scan())
    assert np.array_equal(again.to_records().cov_xx, cov[:, 0, 0])  # records compute it too


def test_lazy_and_computed_covariances_agree_through_transform_and_pickle() -> None:
    scan = _scan()
    pose = (1.0, -2.0, 0.7)
    computed = CornerDetector().detect(scan)
    _ = computed.cov
    lazy = CornerDetector().detect(scan)
    moved_lazy = lazy.transformed(pose).transformed((0.0, 0.0, -0.2))
    assert moved_lazy._cov_is_lazy() and lazy._cov_is_lazy()
    moved = computed.transformed(pose).transformed((0.0, 0.0, -0.2))
    assert np.array_equal(moved_lazy.cov, moved.cov)
    assert np.array_equal(moved_lazy.xy, moved.xy) and moved_lazy.frame_id == "map"
    for kps in (lazy, computed):
        back = pickle.loads(pickle.dumps(kps))
        assert np.array_equal(back.xy, computed.xy)
        assert np.array_equal(back.cov, computed.cov)
    assert lazy._cov_is_lazy()  # pickling a lazy one does not compute it


def test_hand_built_keypoints_keep_nan_or_given_covariances() -> None:
    z = np.zeros(1)
    zi = np.zeros(1, dtype=np.int64)
    plain = Keypoints(np.array([[1.0, 2.0]]), zi, z, z, zi, z, zi)
    assert plain.cov.shape == (1, 2, 2) and np.isnan(plain.cov).all()
    assert np.isnan(plain.transformed((0.0, 0.0, 1.0)).cov).all()
    given = Keypoints(np.array([[1.0, 2.0]]), zi, z, z, zi, z, zi, cov=np.eye(2)[None])
    moved = given.transformed((0.0, 0.0, math.pi / 2))
    assert np.allclose(moved.cov[0], np.eye(2))
    assert np.isnan(Keypoints.empty().cov).all() and Keypoints.empty().cov.shape == (0, 2, 2)
    with np.testing.assert_raises(ValueError):
        Keypoints(np.array([[1.0, 2.0]]), zi, z, z, zi, z, zi, cov=np.eye(2))
    replaced = dataclasses.replace(CornerDetector().detect(_scan()), frame_id="odom")
    assert replaced.frame_id == "odom" and np.isfinite(replaced.cov).all()
    assert "cov" in [f.name for f in dataclasses.fields(Keypoints)]


def test_raw_candidates_and_points_have_covariances() -> None:
    det = CornerDetector(DetectorParams())
    kps, raw = det.detect(_scan(), return_candidates=True)
    assert len(raw) >= len(kps) == 1
    assert np.isfinite(raw.cov).all() and np.isfinite(kps.cov).all()
    xy = np.asfortranarray(np.column_stack(det._scan_xy(_scan())))
    before = xy.copy()
    pts = det.detect_points(xy)
    assert np.isfinite(pts.cov).all()
    assert np.array_equal(xy, before, equal_nan=True)  # the caller's points are not touched
