"""Named parameter presets: ``paper`` (the published defaults) and sensor-adapted ones.

``get_preset(name, scan)`` returns :class:`~laser_corners.DetectorParams`; presets that adapt
to the sensor take the scan's geometry from ``scan`` (any :class:`~laser_corners.LaserScan`
of the recording).
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from laser_corners.errors import InvalidParamsError
from laser_corners.params import PAPER_SCALES, DetectorParams
from laser_corners.scan import LaserScan

__all__ = ["AUTO_N_SCALES", "AUTO_TARGET_RANGE", "PRESETS", "auto_params", "get_preset"]

AUTO_TARGET_RANGE = 3.0
"""Range (m) at which the ``auto`` preset's smallest adapted scale holds ``min_points`` points."""
AUTO_N_SCALES = 17
"""Number of scales of the ``auto`` preset."""


def paper(scan: LaserScan | None = None) -> DetectorParams:
    """The paper's parameters, exactly (section III)."""
    return DetectorParams()


def auto_params(
    angle_increment: float,
    target_range: float = AUTO_TARGET_RANGE,
    base: DetectorParams | None = None,
) -> DetectorParams:
    """Parameters adapted to a scanner's angular resolution (the ``auto`` preset).

    The paper's scales (0.05-0.25 m with ``min_points`` = 5) assume a 0.25 deg scanner. With a
    coarser one, neighbourhoods hold too few points beyond a few metres. Here the point spacing
    on a wall facing the sensor at ``target_range`` is ``s = target_range * |angle_increment|``;
    the smallest adapted scale ``R0 = (min_points - 1) * s`` holds ``min_points`` points there,
    and the largest is ``5 * R0`` (the paper's ratio 0.25 / 0.05). The scales are
    :data:`AUTO_N_SCALES` values evenly spaced from ``min(0.05, R0)`` to ``max(0.25, 5 R0)``,
    so the paper's smallest scale stays for near corners. The lengths that grow with the point
    spacing (``max_point_distance``, ``max_centroid_distance``, ``merge_radius``) are multiplied
    by ``max(1, R0 / 0.05)``. ``max_fit_rmse`` (sensor noise), the angles, ``min_points`` and
    ``min_consecutive_scales`` keep the values of ``base``.

    Parameters
    ----------
    angle_increment : float
        The scan's angle increment, radians (sign ignored).
    target_range : float
        Range in metres, see above (default :data:`AUTO_TARGET_RANGE`).
    base : DetectorParams, optional
        Parameters to adapt (default: the paper's).

    Examples
    --------
    >>> import math
    >>> p = auto_params(math.radians(1.0))
    >>> round(p.scales[0], 3), round(p.scales[-1], 3), len(p.scales)
    (0.05, 1.047, 17)
    """
    base = base or DetectorParams()
    spacing = float(target_range) * abs(float(angle_increment))
    if not (math.isfinite(spacing) and spacing > 0.0):
        raise InvalidParamsError(
            f"auto preset: need a positive target range and angle increment, got "
            f"{target_range} m and {angle_increment} rad"
        )
    smallest = (base.min_points - 1) * spacing
    low = min(PAPER_SCALES[0], smallest)
    high = max(PAPER_SCALES[-1], 5.0 * smallest)
    scales = tuple(round(float(v), 6) for v in np.linspace(low, high, AUTO_N_SCALES))
    factor = max(1.0, smallest / PAPER_SCALES[0])
    return base.with_overrides(
        {
            "scales": scales,
            "max_point_distance": base.max_point_distance * factor,
            "max_centroid_distance": base.max_centroid_distance * factor,
            "merge_radius": base.merge_radius * factor,
        }
    )


def auto(scan: LaserScan | None = None) -> DetectorParams:
    """Scales and spacing-dependent lengths adapted to ``scan``'s angular resolution.

    See :func:`auto_params`; the target range is :data:`AUTO_TARGET_RANGE`.
    """
    if scan is None:
        raise InvalidParamsError("preset 'auto' needs a scan of the recording (its resolution)")
    return auto_params(scan.angle_increment)


PRESETS: dict[str, Callable[[LaserScan | None], DetectorParams]] = {
    "paper": paper,
    "auto": auto,
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
