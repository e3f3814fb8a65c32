"""Sensor profiles of 2D laser scanners."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from laser_corners.errors import InvalidParamsError

__all__ = [
    "HOKUYO_270_0352",
    "SENSORS",
    "SICK_LMS_05DEG",
    "SICK_LMS_1DEG",
    "UST_10LX",
    "SensorProfile",
    "get_sensor",
]


@dataclass(frozen=True)
class SensorProfile:
    """Geometry and noise of a 2D laser scanner.

    Attributes
    ----------
    name : str
        Human-readable name.
    fov_deg : float
        Field of view, degrees, centred on the sensor's x axis (unless ``angle_min_deg``).
    resolution_deg : float
        Angle between beams, degrees.
    range_min, range_max : float
        Valid range interval, metres.
    rate_hz : float
        Scan rate.
    range_noise_sigma : float
        Standard deviation of the Gaussian range noise, metres.
    angle_min_deg : float, optional
        Angle of the first beam, degrees, when the field of view is not centred
        (default: ``-fov_deg / 2``).
    """

    name: str
    fov_deg: float
    resolution_deg: float
    range_min: float
    range_max: float
    rate_hz: float
    range_noise_sigma: float
    angle_min_deg: float | None = None

    @property
    def n_beams(self) -> int:
        """Number of beams (both ends of the field of view included)."""
        return round(self.fov_deg / self.resolution_deg) + 1

    @property
    def angle_min(self) -> float:
        """Angle of the first beam, radians."""
        if self.angle_min_deg is not None:
            return math.radians(self.angle_min_deg)
        return -math.radians(self.fov_deg) / 2.0

    @property
    def angle_increment(self) -> float:
        """Angle between beams, radians."""
        return math.radians(self.resolution_deg)

    @property
    def angles(self) -> NDArray[np.float64]:
        """Beam angles in the sensor frame, radians."""
        return self.angle_min + self.angle_increment * np.arange(self.n_beams)

    def in_fov(self, bearing: NDArray[np.float64]) -> NDArray[np.bool_]:
        """Whether each bearing (radians, sensor frame, in [-pi, pi]) lies in the field of view."""
        lo = self.angle_min
        hi = lo + self.angle_increment * (self.n_beams - 1)
        return (bearing >= lo - 1e-12) & (bearing <= hi + 1e-12)


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

SICK_LMS_1DEG = SensorProfile(
    name="SICK LMS 180 deg / 1 deg (CARMEN era)",
    fov_deg=179.0,
    resolution_deg=1.0,
    range_min=0.0,
    range_max=50.0,
    rate_hz=5.0,
    range_noise_sigma=0.01,
)
"""SICK LMS 2xx as in intel/aces logs: 180 beams at 1 deg over 179 deg, 50 m, sigma 0.01 m."""

SICK_LMS_05DEG = SensorProfile(
    name="SICK LMS 180 deg / 0.5 deg (CARMEN era)",
    fov_deg=179.5,
    resolution_deg=0.5,
    range_min=0.0,
    range_max=50.0,
    rate_hz=5.0,
    range_noise_sigma=0.01,
)
"""SICK LMS 2xx as in the fr079 log: 360 beams at 0.5 deg over 179.5 deg, sigma 0.01 m."""

HOKUYO_270_0352 = SensorProfile(
    name="Hokuyo 270 deg / 0.352 deg (hokuyo270_rooms.bag)",
    fov_deg=767 * 0.3515625,
    resolution_deg=0.3515625,
    range_min=0.03,
    range_max=11.0,
    rate_hz=7.5,
    range_noise_sigma=0.03,
    angle_min_deg=-135.0,
)
"""The scanners of ``hokuyo270_rooms.bag``: 768 beams of 360/1024 deg from -135 deg, 0.03-11 m."""

SENSORS: dict[str, SensorProfile] = {
    "ust-10lx": UST_10LX,
    "sick-1deg": SICK_LMS_1DEG,
    "sick-0.5deg": SICK_LMS_05DEG,
    "hokuyo-0.352deg": HOKUYO_270_0352,
}
"""Sensor profiles by the name the CLI's ``--sensor`` option takes."""


def get_sensor(name: str) -> SensorProfile:
    """The sensor profile called ``name`` (a key of :data:`SENSORS`)."""
    try:
        return SENSORS[name]
    except KeyError:
        raise InvalidParamsError(
            f"unknown sensor {name!r}; choose one of: {', '.join(SENSORS)}"
        ) from None
