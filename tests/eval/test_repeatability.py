"""Repeatability (:mod:`laser_corners.eval.repeatability`): keypoints of one scan seen again in
another, counted by hand."""

from __future__ import annotations

import math

import numpy as np
import pytest

from laser_corners.eval.repeatability import pair_repeatability, repeatability
from laser_corners.scan import LaserScan


def wall_scan(distance: float, pose: tuple[float, float, float] | None = None) -> LaserScan:
    """181 beams over [-90, 90] deg, every beam hitting at ``distance`` (a circular wall)."""
    return LaserScan(np.full(181, distance), -math.pi / 2, math.radians(1.0), 0.05, 30.0, pose=pose)


def test_pair_repeatability_counts_visible_and_repeated() -> None:
    scan_b = wall_scan(5.0)
    pose_b_in_a = (1.0, 0.0, math.pi / 2)  # B is 1 m ahead of A, turned left
    # A's keypoints (A frame) -> B frame: (x, y) -> (y, 1 - x)
    kps_a = np.array(
        [
            [1.0, 2.0],  # B: (2, 0) ahead of B: visible
            [1.0, -2.0],  # B: (-2, 0) behind B: not visible
            [0.0, 1.0],  # B: (1, 1): visible
            [3.0, 1.0],  # B: (1, -2): visible
        ]
    )
    kps_b = np.array([[2.03, 0.0], [1.0, 1.08], [4.0, 4.0]])
    counts = pair_repeatability(kps_a, kps_b, scan_b, pose_b_in_a, radii=(0.05, 0.1))
    assert counts.n_a == 4
    assert counts.n_visible == 3
    assert counts.n_repeated == (1, 2)
    result = repeatability([kps_a, kps_b], [wall_scan(5.0), scan_b], [(0, 1, pose_b_in_a)])
    assert result.repeatability == pytest.approx((1 / 3, 2 / 3))
    assert result.keypoints_per_scan == pytest.approx(3.5)
    empty = repeatability([kps_a, kps_b], [scan_b, scan_b], [])
    assert empty.n_pairs == 0 and all(math.isnan(v) for v in empty.repeatability)
