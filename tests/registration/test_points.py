"""Scan points for alignment (:mod:`laser_corners.registration.points`): valid beams in the base
frame, thinning, line normals, and the point transforms, on scans of a known wall."""

from __future__ import annotations

import math

import numpy as np
import pytest

from laser_corners.pose import transform_points
from laser_corners.registration.points import rotate, scan_points, transform
from laser_corners.scan import LaserScan
from laser_corners.sim import corner_scan

INCREMENT = math.radians(0.5)


def wall_scan(distance: float = 2.0, n: int = 121) -> LaserScan:
    """A straight wall ``distance`` ahead (x = distance), beams over [-30, 30] degrees."""
    angles = -math.radians(30.0) + INCREMENT * np.arange(n)
    return LaserScan(distance / np.cos(angles), -math.radians(30.0), INCREMENT, 0.05, 30.0)


def test_points_lie_on_the_wall_in_the_base_frame_with_its_normal() -> None:
    mount = np.array([0.3, -0.1, math.pi / 2])  # laser 0.3 m ahead, turned left
    points = scan_points(wall_scan(), mount, 0.1, 20.0, spacing=0.0)
    assert points.xy.shape == (121, 2) and points.has_normal.all()
    # the wall x = 2 in the laser frame is y = 2 - 0.1 in the base frame (x -> y, then moved)
    np.testing.assert_allclose(points.xy[:, 1], 2.0 - 0.1, atol=1e-9)
    np.testing.assert_allclose(np.abs(points.normals[:, 1]), 1.0, atol=1e-9)
    np.testing.assert_allclose(points.normals[:, 0], 0.0, atol=1e-9)
    assert np.all(np.diff(points.xy[:, 0]) < 0)  # beam order, counter-clockwise in the laser


def test_thinning_keeps_consecutive_points_apart() -> None:
    dense = scan_points(wall_scan(), np.zeros(3), 0.1, 20.0, spacing=0.0)
    thin = scan_points(wall_scan(), np.zeros(3), 0.1, 20.0, spacing=0.1)
    assert 0 < len(thin.xy) < len(dense.xy)
    gaps = np.hypot(*np.diff(thin.xy, axis=0).T)
    assert gaps.min() >= 0.1 - 1e-12 and gaps.max() < 0.1 + 0.02  # beams are ~0.018 m apart
    np.testing.assert_array_equal(thin.xy[0], dense.xy[0])


def test_range_limits_and_invalid_beams_are_left_out() -> None:
    scan = wall_scan()
    ranges = scan.ranges.copy()
    ranges[:10] = np.nan
    ranges[10:20] = 50.0  # beyond the scan's range_max: no return
    cut = LaserScan(ranges, scan.angle_min, INCREMENT, 0.05, 30.0)
    assert len(scan_points(cut, np.zeros(3), 0.1, 20.0, 0.0).xy) == 101
    # max_range 2.1 keeps the beams within 2.1 m: |angle| < acos(2 / 2.1) = 17.75 deg
    near = scan_points(scan, np.zeros(3), 0.1, 2.1, 0.0)
    assert len(near.xy) == int(np.sum(scan.ranges < 2.1))
    empty = scan_points(scan, np.zeros(3), 5.0, 20.0, 0.0)
    assert empty.xy.shape == (0, 2) and empty.has_normal.shape == (0,)


def test_a_corner_point_has_no_line_normal() -> None:
    scan = corner_scan()  # two walls meeting at a right angle at (2, 1)
    points = scan_points(scan, np.zeros(3), 0.1, 20.0, spacing=0.0)
    corner = int(np.argmin(np.hypot(points.xy[:, 0] - 2.0, points.xy[:, 1] - 1.0)))
    assert not points.has_normal[corner]
    assert points.has_normal[:5].all() and points.has_normal[-5:].all()
    assert np.all(points.normals[~points.has_normal] == 0.0)


@pytest.mark.parametrize("pose", [(0.0, 0.0, 0.0), (1.0, -2.0, 0.7), (-3.0, 0.5, -2.9)])
def test_transform_and_rotate_agree_with_the_pose_module(pose) -> None:
    xy = np.array([[0.0, 0.0], [1.0, 0.0], [-2.0, 3.5]])
    np.testing.assert_allclose(transform(xy, np.array(pose)), transform_points(xy, pose))
    np.testing.assert_allclose(rotate(xy, pose[2]), transform_points(xy, (0.0, 0.0, pose[2])))
