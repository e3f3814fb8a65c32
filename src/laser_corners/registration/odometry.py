"""The one odometry noise model of ``slam`` and ``localise``.

A step of wheel odometry of ``d`` metres turning ``θ`` radians has standard deviations
``sigma_xy · (d + 0.1)`` in x and y and ``sigma_yaw · (|θ| + d + 0.1)`` in heading: the error
grows with the distance and the turn, and a standing robot still gets the noise of 0.1 m (a
floor: wheels slip, stamps jitter). Across an odometry jump the prediction is barely trusted:
:data:`JUMP_SIGMAS`.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ["JUMP_SIGMAS", "odometry_information", "odometry_sigmas"]

JUMP_SIGMAS = np.array([1.0, 1.0, 0.5])
"""Standard deviations (m, m, rad) of the odometry prediction across a jump (a weak prior)."""


def odometry_sigmas(delta: ArrayLike, sigma_xy: float, sigma_yaw: float) -> NDArray[np.float64]:
    """Standard deviations (x, y, yaw) of the odometry step ``delta`` (x, y, yaw).

    Parameters
    ----------
    delta : array_like, shape (3,)
        The step in the frame of its start.
    sigma_xy : float
        Metres of error per metre travelled (``odometry_sigma_xy``).
    sigma_yaw : float
        Radians of error per radian turned and per metre travelled (``odometry_sigma_yaw``).
    """
    d = np.asarray(delta, dtype=np.float64)
    dist = math.hypot(d[0], d[1])
    sxy = sigma_xy * (dist + 0.1)
    return np.array([sxy, sxy, sigma_yaw * (abs(float(d[2])) + dist + 0.1)])


def odometry_information(
    delta: ArrayLike, sigma_xy: float, sigma_yaw: float, jump: bool = False
) -> NDArray[np.float64]:
    """Information (3x3, the inverse covariance) of the odometry step ``delta``; across a
    ``jump`` that of :data:`JUMP_SIGMAS`."""
    sig = JUMP_SIGMAS if jump else odometry_sigmas(delta, sigma_xy, sigma_yaw)
    return np.diag(1.0 / sig**2)
