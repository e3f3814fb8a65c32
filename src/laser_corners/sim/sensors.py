"""Sensor profiles of 2D laser scanners."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

__all__ = ["UST_10LX", "SensorProfile"]


@dataclass(frozen=True)
class SensorProfile:
    """Geometry and noise of a 2D laser scanner.

    Attributes
    ----------
    name : str
        Human-readable name.
    fov_deg : float
        Field of view, degrees, centred on the sensor's x axis.
    resolution_deg : float
        Angle between beams, degrees.
    range_min, range_max : float
        Valid range interval, metres.
    rate_hz : float
        Scan rate.
    range_noise_sigma : float
        Standard deviation of the Gaussian range noise, metres.
    """

    name: str
    fov_deg: float
    resolution_deg: float
    range_min: float
    range_max: float
    rate_hz: float
    range_noise_sigma: float

    @property
    def n_beams(self) -> int:
        """Number of beams (both ends of the field of view included)."""
        return round(self.fov_deg / self.resolution_deg) + 1

    @property
    def angle_min(self) -> float:
        """Angle of the first beam, radians."""
        return -math.radians(self.fov_deg) / 2.0

    @property
    def angle_increment(self) -> float:
        """Angle between beams, radians."""
        return math.radians(self.resolution_deg)

    @property
    def angles(self) -> NDArray[np.float64]:
        """Beam angles in the sensor frame, radians."""
        return self.angle_min + self.angle_increment * np.arange(self.n_beams)


UST_10LX = SensorProfile(
    name="Hokuyo UST-10LX",
    fov_deg=270.0,
    resolution_deg=0.25,
    range_min=0.06,
    range_max=10.0,
    rate_hz=40.0,
    range_noise_sigma=0.03,
)
"""Hokuyo UST-10LX: 270 deg, 0.25 deg (1081 beams), 0.06-10 m, 40 Hz, sigma 0.03 m (spec)."""
