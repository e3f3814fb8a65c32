"""The one odometry noise model of ``slam`` and ``localise``.

A step of wheel odometry of ``d`` metres turning ``θ`` radians has standard deviations
``sigma_xy · (d + 0.1)`` in x and y and ``sigma_yaw · (|θ| + d + 0.1)`` in heading: the error
grows with the distance and the turn, and a standing robot still gets the noise of 0.1 m (a
floor: wheels slip, stamps jitter). Across an odometry jump the prediction is barely trusted:
:data:`JUMP_SIGMAS`.
"""

from __future__ import annotations

import math
from typing import ClassVar

import numpy as np
from numpy.typing import ArrayLike, NDArray
from pydantic import Field

from laser_corners.options import Options

__all__ = ["JUMP_SIGMAS", "OdometryNoise", "odometry_information", "odometry_sigmas"]

JUMP_SIGMAS = np.array([1.0, 1.0, 0.5])
"""Standard deviations (m, m, rad) of the odometry prediction across a jump (a weak prior)."""


class OdometryNoise(Options):
    """The odometry's noise: the ``odometry`` group of :class:`~laser_corners.slam.SlamOptions`
    and :class:`~laser_corners.localise.LocaliseOptions`, one default in both (a fact of the
    robot's wheels, not of the estimator): ``--set odometry.sigma_xy=0.1``, a YAML
    ``odometry:`` table, the ROS 2 parameter ``odometry.sigma_xy``.

    Attributes
    ----------
    sigma_xy : float
        Metres of error per metre travelled (on 0.1 m more): weighs the odometry prediction
        (the ICP's prior), the odometry factors and the growth of a lost track's window.
    sigma_yaw : float
        Radians of error per radian turned, plus the same per metre travelled.

    Examples
    --------
    >>> OdometryNoise().with_overrides(["sigma_yaw=0.02"])
    OdometryNoise(sigma_xy=0.05, sigma_yaw=0.02)
    """

    title: ClassVar[str] = "OdometryNoise"
    what: ClassVar[str] = "option"

    sigma_xy: float = Field(0.05, ge=1e-4, le=10.0)
    sigma_yaw: float = Field(0.05, ge=1e-4, le=10.0)


def odometry_sigmas(delta: ArrayLike, noise: OdometryNoise) -> NDArray[np.float64]:
    """Standard deviations (x, y, yaw) of the odometry step ``delta`` (x, y, yaw).

    Parameters
    ----------
    delta : array_like, shape (3,)
        The step in the frame of its start.
    noise : OdometryNoise
        The noise per metre travelled and per radian turned.
    """
    d = np.asarray(delta, dtype=np.float64)
    dist = math.hypot(d[0], d[1])
    sxy = noise.sigma_xy * (dist + 0.1)
    return np.array([sxy, sxy, noise.sigma_yaw * (abs(float(d[2])) + dist + 0.1)])


def odometry_information(
    delta: ArrayLike, noise: OdometryNoise, jump: bool = False
) -> NDArray[np.float64]:
    """Information (3x3, the inverse covariance) of the odometry step ``delta`` with
    ``noise``; across a ``jump`` that of :data:`JUMP_SIGMAS`."""
    sig = JUMP_SIGMAS if jump else odometry_sigmas(delta, noise)
    return np.diag(1.0 / sig**2)
