"""The search window of a lost track (:mod:`laser_corners.localise.window`): dead reckoning,
linear growth of its deviations, its limits and its half-widths, on numbers worked by hand."""

from __future__ import annotations

import math

import numpy as np
import pytest

from laser_corners.localise.window import MIN_XY, MIN_YAW, Window
from laser_corners.registration.odometry import OdometryNoise

NOISE = OdometryNoise(sigma_xy=0.05, sigma_yaw=0.02)


def test_from_covariance_takes_the_largest_position_axis() -> None:
    covariance = np.diag([0.04, 0.09, 0.0025])
    covariance[0, 1] = covariance[1, 0] = 0.0  # axes 0.2 m and 0.3 m
    window = Window.from_covariance(np.array([1.0, 2.0, 0.5]), covariance)
    assert window.sigma_xy == pytest.approx(0.3) and window.sigma_yaw == pytest.approx(0.05)
    pose = np.array([1.0, 2.0, 0.5])
    assert Window.from_covariance(pose, np.diag([-1e-12, 0.0, -1e-12])).sigma_xy == 0.0


def test_move_dead_reckons_and_grows_linearly() -> None:
    window = Window(np.array([1.0, 0.0, math.pi / 2]), 0.1, 0.01)
    window.move(np.array([2.0, 0.0, 0.5]), NOISE)
    # 2 m along the heading (+y in the map), then turned by 0.5 rad
    np.testing.assert_allclose(window.pose, [1.0, 2.0, math.pi / 2 + 0.5], atol=1e-12)
    sigma_yaw = 0.01 + 0.02 * (2.0 + 0.5)
    assert window.sigma_yaw == pytest.approx(sigma_yaw)
    assert window.sigma_xy == pytest.approx(0.1 + 0.05 * 2.0 + sigma_yaw * 2.0)
    before = (window.sigma_xy, window.sigma_yaw)
    window.move(np.zeros(3), NOISE)  # standing still changes nothing
    assert (window.sigma_xy, window.sigma_yaw) == before


def test_open_compares_three_sigma_with_the_limits() -> None:
    window = Window(np.zeros(3), 0.5, 0.09)
    assert window.open(1.5, 0.3)
    assert not window.open(1.4, 0.3) and not window.open(1.5, 0.26)


def test_half_widths_have_a_floor_and_contains_wraps_the_heading() -> None:
    small = Window(np.array([0.0, 0.0, math.pi - 0.05]), 0.01, 0.001)
    assert small.half_widths == (MIN_XY, MIN_YAW)
    assert small.contains(np.array([0.4, 0.2, -math.pi + 0.05]))  # 0.1 rad apart over ±π
    assert not small.contains(np.array([0.5, 0.2, math.pi - 0.05]))  # 0.54 m away
    wide = Window(np.zeros(3), 1.0, 0.5)
    assert wide.half_widths == pytest.approx((3.0, 1.5))
    assert wide.contains(np.array([2.9, 0.0, -1.4])) and not wide.contains(np.zeros(3) + 3.1)
