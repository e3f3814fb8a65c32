"""Which map points a scan sees (:mod:`laser_corners.eval.visibility`): field of view, range,
occlusion, beams without a return."""

from __future__ import annotations

import math

import numpy as np

from laser_corners.eval.visibility import points_in_view
from laser_corners.scan import LaserScan


def wall_scan(distance: float, pose: tuple[float, float, float] | None = None) -> LaserScan:
    """181 beams over [-90, 90] deg, every beam hitting at ``distance`` (a circular wall)."""
    return LaserScan(np.full(181, distance), -math.pi / 2, math.radians(1.0), 0.05, 30.0, pose=pose)


def test_points_in_view_fov_range_and_occlusion() -> None:
    scan = wall_scan(2.0)
    pts = [[1.0, 0.0], [2.03, 0.0], [2.5, 0.0], [-1.0, 0.0], [0.0, 1.5], [0.01, 0.0]]
    seen = points_in_view(scan, pts, tolerance=0.06)
    # in front; just behind the surface (tolerance); occluded; behind the sensor; at +90 deg
    # (last beam); closer than range_min
    assert seen.tolist() == [True, True, False, False, True, False]
    assert points_in_view(scan, [[2.5, 0.0]], occlusion=False).tolist() == [True]
    assert points_in_view(scan, [[2.5, 0.0]], occlusion=False, max_range=2.4).tolist() == [False]


def test_points_in_view_beam_without_return_sees_nothing() -> None:
    ranges = np.full(181, 2.0)
    ranges[90] = np.nan  # the beam straight ahead has no return
    scan = LaserScan(ranges, -math.pi / 2, math.radians(1.0), 0.05, 30.0)
    assert points_in_view(scan, [[1.0, 0.0]]).tolist() == [True]  # the neighbour beam saw 2 m
    ranges[89:92] = np.nan
    scan = LaserScan(ranges, -math.pi / 2, math.radians(1.0), 0.05, 30.0)
    assert points_in_view(scan, [[1.0, 0.0]]).tolist() == [False]
