"""Named parameter presets: ``paper`` (the published defaults) and sensor-adapted ones.

``get_preset(name, scan)`` returns :class:`~laser_corners.DetectorParams`; presets that adapt
to the sensor take the scan's geometry from ``scan`` (any :class:`~laser_corners.LaserScan`
of the recording).
"""

from __future__ import annotations

from collections.abc import Callable

from laser_corners.errors import InvalidParamsError
from laser_corners.params import DetectorParams
from laser_corners.scan import LaserScan

__all__ = ["PRESETS", "get_preset"]


def paper(scan: LaserScan | None = None) -> DetectorParams:
    """The paper's parameters, exactly (section III)."""
    return DetectorParams()


PRESETS: dict[str, Callable[[LaserScan | None], DetectorParams]] = {
    "paper": paper,
}
"""Preset name -> function of an optional scan giving the parameters."""


def get_preset(name: str, scan: LaserScan | None = None) -> DetectorParams:
    """Parameters of the preset ``name`` (adapted to ``scan``'s geometry where it applies)."""
    try:
        factory = PRESETS[name]
    except KeyError:
        raise InvalidParamsError(
            f"unknown preset {name!r}; choose one of: {', '.join(PRESETS)}"
        ) from None
    return factory(scan)
