"""Revisits (:mod:`laser_corners.eval.revisits`): the travel window and the overlap test, on
hand-made scans."""

from __future__ import annotations

import math

import numpy as np

from laser_corners.eval.revisits import candidates, revisits, travel_distance
from laser_corners.scan import LaserScan


def test_window_excludes_the_last_metres_of_travel() -> None:
    poses = np.array([[0, 0, 0], [1, 0, 0], [1, 0, 1.0], [3, 0, 0], [6, 0, 0], [10, 0, 0.0]])
    travel = travel_distance(poses)
    assert travel.tolist() == [0, 1, 1, 3, 6, 10]
    # standing still / turning on the spot (scans 1, 2) never leaves the window
    assert candidates(travel, 1, 3.0).tolist() == [4, 5]
    assert candidates(travel, 5, 5.0).tolist() == [0, 1, 2, 3]
    assert candidates(travel, 3, 0.5).tolist() == [0, 1, 2, 4, 5]


def test_revisit_overlap_any_scan_direction() -> None:
    # a wall 3 m ahead (x = 3); scan B 6 m further back, with a mirrored beam order
    # (negative increment), and C like B with angles wrapped by 2 pi, see all of A's points;
    # A sees only the middle 41 % of B's longer stretch of wall (the rest is outside its view)
    n = 181
    angles = np.radians(np.linspace(-45.0, 45.0, n))
    ranges_a = 3.0 / np.cos(angles)
    a = LaserScan(ranges_a, math.radians(-45.0), math.radians(0.5), 0.0, 50.0, pose=(0, 0, 0))
    ranges_b = (9.0 / np.cos(angles))[::-1]
    b = LaserScan(
        ranges_b, math.radians(45.0), -math.radians(0.5), 0.0, 50.0, pose=(-6.0, 0.0, 0.0)
    )
    c = LaserScan(
        ranges_b,
        math.radians(45.0) + math.tau,
        -math.radians(0.5),
        0.0,
        50.0,
        pose=(-6.0, 0.0, 0.0),
    )
    assert revisits([a, b], window_travel=1.0).tolist() == [1, -1]
    assert revisits([a, c], window_travel=1.0).tolist() == [1, -1]
    assert revisits([a, b], window_travel=1.0, overlap=0.4).tolist() == [1, 0]
    # a scan whose range ends before the wall sees none of it
    far = LaserScan(
        ranges_b, math.radians(45.0), -math.radians(0.5), 0.0, 5.0, pose=(-6.0, 0.0, 0.0)
    )
    assert revisits([a, far], window_travel=1.0)[0] == -1
