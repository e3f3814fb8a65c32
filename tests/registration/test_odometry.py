"""The one odometry noise model (``registration.odometry``)."""

from __future__ import annotations

import numpy as np
import pytest

from laser_corners.errors import InvalidParamsError
from laser_corners.localise.options import LocaliseOptions
from laser_corners.registration.odometry import (
    JUMP_SIGMAS,
    OdometryNoise,
    odometry_information,
    odometry_sigmas,
)
from laser_corners.slam.options import SlamOptions

NOISE = OdometryNoise(sigma_xy=0.05, sigma_yaw=0.02)


def test_sigmas_grow_with_distance_and_turn_from_a_floor() -> None:
    still = odometry_sigmas([0.0, 0.0, 0.0], NOISE)
    assert still == pytest.approx([0.005, 0.005, 0.002])  # the 0.1 m floor
    moved = odometry_sigmas([3.0, 4.0, -0.5], NOISE)
    assert moved == pytest.approx([0.05 * 5.1, 0.05 * 5.1, 0.02 * (0.5 + 5.0 + 0.1)])


def test_information_is_the_inverse_covariance_and_weak_across_a_jump() -> None:
    delta = [1.0, 0.0, 0.3]
    info = odometry_information(delta, NOISE)
    cov = np.diag(odometry_sigmas(delta, NOISE) ** 2)
    assert info @ cov == pytest.approx(np.eye(3))
    assert odometry_information(delta, NOISE, jump=True) == pytest.approx(
        np.diag(1.0 / JUMP_SIGMAS**2)
    )


def test_the_noise_is_one_group_of_both_options_with_one_default() -> None:
    assert SlamOptions().odometry == LocaliseOptions().odometry == OdometryNoise()
    assert OdometryNoise() == OdometryNoise(sigma_xy=0.05, sigma_yaw=0.05)
    for cls in (SlamOptions, LocaliseOptions):
        changed = cls().with_overrides(["odometry.sigma_yaw=0.02"])
        assert changed.odometry == OdometryNoise(sigma_xy=0.05, sigma_yaw=0.02)
        for old in ("odometry_sigma_xy", "odometry_sigma_yaw"):
            with pytest.raises(InvalidParamsError, match=f"unknown option '{old}'"):
                cls().with_overrides([f"{old}=0.1"])


def test_noise_bounds_are_refused_in_one_line_naming_the_field() -> None:
    for field in ("sigma_xy", "sigma_yaw"):
        with pytest.raises(InvalidParamsError, match=f"OdometryNoise.{field}: input should be"):
            OdometryNoise(**{field: 0.0})
        with pytest.raises(InvalidParamsError, match=f"odometry: OdometryNoise.{field}") as info:
            LocaliseOptions().with_overrides([f"odometry.{field}=11"])
        assert "\n" not in str(info.value)
