"""Keyframe storage (:mod:`laser_corners.slam.keyframes`): travelled distance and the local map
of the keyframes' points moved to their estimates, against poses worked by hand."""

from __future__ import annotations

import math

import numpy as np

from laser_corners.pose import transform_points
from laser_corners.registration.points import ScanPoints
from laser_corners.sim import corner_scan
from laser_corners.slam.keyframes import KeyframeStore


def points(xy, has_normal) -> ScanPoints:
    xy = np.asarray(xy, dtype=np.float64)
    normals = np.where(np.asarray(has_normal)[:, None], [[0.0, 1.0]], 0.0)
    return ScanPoints(xy, normals, np.asarray(has_normal, dtype=bool))


def store_of(poses) -> KeyframeStore:
    store = KeyframeStore()
    scan = corner_scan()
    for i, pose in enumerate(poses):
        pts = points([[1.0, 0.0], [2.0, 0.0], [i, 1.0]], [True, True, False])
        store.add(scan, pts, index=10 * i, stamp=0.5 * i, odometry=pose, pose=np.array(pose))
        store.estimate = np.array(poses[: i + 1], dtype=np.float64)
    return store


def test_travelled_sums_the_steps_between_estimates() -> None:
    store = store_of([(0.0, 0.0, 0.0), (3.0, 4.0, 1.0), (3.0, 4.0, -2.0), (3.0, 5.0, 0.0)])
    assert len(store) == 4 and store.scan_index == [0, 10, 20, 30]
    np.testing.assert_allclose(store.travelled_array(), [0.0, 5.0, 5.0, 6.0])
    assert store.stamps == [0.0, 0.5, 1.0, 1.5] and store.odometry[1].dtype == np.float64


def test_local_map_moves_each_keyframes_points_to_its_estimate() -> None:
    poses = [(0.0, 0.0, 0.0), (1.0, 2.0, math.pi / 2), (-1.0, 0.5, math.pi)]
    store = store_of(poses)
    line, every = store.local_map(2)  # the last two keyframes
    expected = np.concatenate(
        [transform_points(p.xy, pose) for p, pose in zip(store.points[1:], poses[1:], strict=True)]
    )
    np.testing.assert_allclose(every.xy, expected, atol=1e-12)
    assert len(every) == 6 and len(line) == 4  # the points without a normal are overlap only
    np.testing.assert_allclose(line.xy, expected[[0, 1, 3, 4]], atol=1e-12)
    # normals (0, 1) turned by +90 and 180 degrees
    np.testing.assert_allclose(line.normals, [[-1, 0], [-1, 0], [0, -1], [0, -1]], atol=1e-12)
    assert np.all(every.normals == 0.0)
    whole, _ = store.local_map(10)
    assert len(whole) == 6  # n beyond the keyframes: all of them
    span, _ = store.span_map(0, 1)
    np.testing.assert_allclose(span.xy, [[1.0, 0.0], [2.0, 0.0]])


def test_a_frozen_maps_keyframes_near_the_pose_join_the_local_map() -> None:
    # keyframes 0 and 1 are a prior map's (at x = 0 and 5), 2 and 3 the session's (x = 30, 31)
    store = store_of([(0.0, 0.0, 0.0), (5.0, 0.0, 0.0), (30.0, 0.0, 0.0), (31.0, 0.0, 0.0)])
    store.first = 2
    _, every = store.local_map(5)
    assert len(every) == 6  # the session's keyframes only
    _, every = store.local_map(5, around=np.array([4.0, 0.0, 0.0]), reach=10.0)
    assert len(every) == 12  # both of the map's, within 10 m
    _, every = store.local_map(5, around=np.array([100.0, 0.0, 0.0]), reach=10.0)
    assert len(every) == 6  # none of the map's near
    # the n nearest of the map's: keyframe 1 (its point (1, 0) lands at x = 6), not 0
    _, every = store.local_map(1, around=np.array([4.0, 0.0, 0.0]), reach=10.0)
    assert len(every) == 6
    assert np.any(np.all(np.isclose(every.xy, [6.0, 0.0]), axis=1))
    assert not np.any(np.all(np.isclose(every.xy, [1.0, 0.0]), axis=1))
