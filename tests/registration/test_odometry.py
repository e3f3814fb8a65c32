"""The one odometry noise model (``registration.odometry``)."""

from __future__ import annotations

import numpy as np
import pytest

from laser_corners.registration.odometry import (
    JUMP_SIGMAS,
    odometry_information,
    odometry_sigmas,
)


def test_sigmas_grow_with_distance_and_turn_from_a_floor() -> None:
    still = odometry_sigmas([0.0, 0.0, 0.0], 0.05, 0.02)
    assert still == pytest.approx([0.005, 0.005, 0.002])  # the 0.1 m floor
    moved = odometry_sigmas([3.0, 4.0, -0.5], 0.05, 0.02)
    assert moved == pytest.approx([0.05 * 5.1, 0.05 * 5.1, 0.02 * (0.5 + 5.0 + 0.1)])


def test_information_is_the_inverse_covariance_and_weak_across_a_jump() -> None:
    delta = [1.0, 0.0, 0.3]
    info = odometry_information(delta, 0.05, 0.02)
    cov = np.diag(odometry_sigmas(delta, 0.05, 0.02) ** 2)
    assert info @ cov == pytest.approx(np.eye(3))
    assert odometry_information(delta, 0.05, 0.02, jump=True) == pytest.approx(
        np.diag(1.0 / JUMP_SIGMAS**2)
    )
