"""Corners of scans for the place index (:mod:`laser_corners.registration.corners`): the query
buffer keeps the corners of its last metres of travel; scan corners in the base frame; one
corner per place and heading."""

from __future__ import annotations

import math

import numpy as np
import pytest

from laser_corners import CornerDetector
from laser_corners.pose import transform_points
from laser_corners.registration.corners import (
    Corners,
    QueryBuffer,
    corner_detector,
    merge_close,
    scan_corners,
)
from laser_corners.sim import corner_scan


def test_query_buffer_forgets_what_lies_beyond_its_travel() -> None:
    buffer = QueryBuffer(1.0)
    one = Corners(
        np.array([[1.0, 0.0]]), np.zeros(1), np.full(1, 90.0), np.zeros((1, 3), np.float32)
    )
    for k in range(30):
        buffer.add(np.array([0.1 * k, 0.0, 0.0]), one)
    query = buffer.query()
    # kept every 0.2 m over the last 1 m: the one corner seen from 5-6 places
    assert 5 <= len(query) <= 6
    assert np.all(query.xy[:, 0] <= 1.0 + 1e-9) and np.all(query.xy[:, 0] >= -0.01)


def corners(xy, orientation) -> Corners:
    n = len(orientation)
    return Corners(
        np.asarray(xy, dtype=np.float64).reshape(-1, 2),
        np.asarray(orientation, dtype=np.float64),
        np.full(n, 90.0),
        np.arange(2 * n, dtype=np.float32).reshape(n, 2),
    )


def test_scan_corners_are_the_detectors_keypoints_in_the_base_frame() -> None:
    scan = corner_scan()  # a right-angle corner at (2, 1) in the laser frame
    mount = np.array([0.3, 0.1, math.pi / 2])
    found = scan_corners(scan, corner_detector("paper", scan), mount)
    keypoints = CornerDetector("paper").detect(scan)
    assert len(found) == len(keypoints) == 1 and found.descriptor.dtype == np.float32
    np.testing.assert_allclose(found.xy[0], transform_points(keypoints.xy, tuple(mount))[0])
    np.testing.assert_allclose(found.xy[0], [0.3 - 1.0, 0.1 + 2.0], atol=0.02)
    assert found.orientation[0] == pytest.approx(
        math.remainder(keypoints.orientation[0] + math.pi / 2, math.tau)
    )
    assert corner_detector("auto", scan).params == CornerDetector.from_preset("auto", scan).params


def test_moved_joined_and_empty() -> None:
    a = corners([[1.0, 0.0]], [0.0])
    moved = a.moved(np.array([1.0, 1.0, math.pi]))
    np.testing.assert_allclose(moved.xy, [[0.0, 1.0]], atol=1e-12)
    assert abs(moved.orientation[0]) == pytest.approx(math.pi)
    both = Corners.joined([a, Corners.empty(2), moved])
    assert len(both) == 2 and both.descriptor.shape == (2, 2)
    assert len(Corners.joined([Corners.empty(3)])) == 0
    assert Corners.joined([Corners.empty(3)]).descriptor.shape == (0, 3)
    assert Corners.empty(4).moved(np.ones(3)).descriptor.shape == (0, 4)


def test_merge_close_keeps_one_corner_per_place_and_heading() -> None:
    many = corners(
        [[0.0, 0.0], [0.05, 0.0], [0.05, 0.0], [1.0, 0.0], [0.02, 0.01]],
        [0.0, 0.1, 2.0, 0.0, -0.05],
    )
    kept = merge_close(many, radius=0.1, yaw=0.3)
    # the 2nd and 5th are the 1st seen again; the 3rd faces elsewhere; the 4th is far away
    np.testing.assert_allclose(kept.xy, [[0.0, 0.0], [0.05, 0.0], [1.0, 0.0]])
    np.testing.assert_allclose(kept.orientation, [0.0, 2.0, 0.0])
    assert kept.descriptor.tolist() == [[0, 1], [4, 5], [6, 7]]
