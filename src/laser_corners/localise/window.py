"""The search window of a lost track: :class:`Window` (issue 20, the later visit).

A track is lost when its scans stop agreeing with the map (the robot left the map, a door
closed since the map was made, or it was carried away). Until then its pose was good, and the
odometry keeps moving it: the *dead-reckoned* pose. Its uncertainty grows with the travel:
:class:`Window` keeps that pose and the standard deviations of its position and heading, grown
*linearly* (odometry errors are mostly systematic, a scale or a heading bias, so they add up
rather than average out) by the odometry noise per metre travelled and per radian turned, the
heading's uncertainty also moving the position by the distance driven. While its 3σ stays
under the localiser's limits, the search after a loss looks for the robot only inside it
(:meth:`~laser_corners.localise.mapmodel.MapModel.window_slices`): a look-alike elsewhere in
the map cannot compete, so a shorter travel suffices to tell the hypotheses inside the window
apart. A robot carried away (a kidnap the odometry does not show) is not in the window: its
hypotheses there do not agree with the map well enough to become a fix, the window grows past
its limits within metres, and the global search takes over.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from laser_corners.pose import compose_many, wrap_angle
from laser_corners.registration.odometry import OdometryNoise

__all__ = ["Window"]

MIN_XY = 0.5
"""Smallest half-width (m) of the window: the distance under which two hypotheses are one
(``distinct_xy``'s default), so that a window just opened still holds the hypotheses near
its centre."""
MIN_YAW = 0.2
"""Smallest half-width (rad) of the window (``distinct_yaw``'s default)."""


@dataclass
class Window:
    """The dead-reckoned pose of a lost track and its standard deviations.

    Attributes
    ----------
    pose : ndarray, shape (3,)
        Base pose in the map frame: the last tracked pose moved by the odometry since.
    sigma_xy : float
        Standard deviation (m) of the position (each axis).
    sigma_yaw : float
        Standard deviation (rad) of the heading.
    """

    pose: NDArray[np.float64]
    sigma_xy: float
    sigma_yaw: float

    @classmethod
    def from_covariance(cls, pose: NDArray, covariance: NDArray) -> Window:
        """A window at ``pose`` with the (map-frame) ``covariance`` of the last estimate."""
        sxy = math.sqrt(max(float(np.linalg.eigvalsh(covariance[:2, :2]).max()), 0.0))
        return cls(np.asarray(pose, float).copy(), sxy, math.sqrt(max(covariance[2, 2], 0.0)))

    def move(self, delta: NDArray, noise: OdometryNoise) -> None:
        """Apply one odometry step ``delta`` (base frame); grow the deviations linearly:
        heading by ``noise.sigma_yaw`` x (travel + turn), position by ``noise.sigma_xy`` x
        travel plus the heading's deviation x travel."""
        dist = math.hypot(float(delta[0]), float(delta[1]))
        self.pose = compose_many(self.pose, delta)
        self.sigma_yaw += noise.sigma_yaw * (dist + abs(float(delta[2])))
        self.sigma_xy += noise.sigma_xy * dist + self.sigma_yaw * dist

    def open(self, xy: float, yaw: float) -> bool:
        """Whether the 3σ of the position and heading are within ``xy`` (m) and ``yaw`` (rad)."""
        return 3.0 * self.sigma_xy <= xy and 3.0 * self.sigma_yaw <= yaw

    @property
    def half_widths(self) -> tuple[float, float]:
        """Half-widths (m, rad) of the window: 3σ, at least :data:`MIN_XY`, :data:`MIN_YAW`."""
        return max(3.0 * self.sigma_xy, MIN_XY), max(3.0 * self.sigma_yaw, MIN_YAW)

    def contains(self, pose: NDArray) -> bool:
        """Whether ``pose`` is inside the window (position and heading)."""
        xy, yaw = self.half_widths
        d = math.hypot(pose[0] - self.pose[0], pose[1] - self.pose[1])
        return d <= xy and abs(float(wrap_angle(float(pose[2] - self.pose[2])))) <= yaw
