"""Named parameter presets: ``paper`` (the published defaults) and sensor-adapted ones.

``robust`` adapts to the range noise it estimates from the scan and turns on the detector's
options beyond the paper (see ``docs/simulation-and-accuracy.md``).

``get_preset(name, scan)`` returns :class:`~laser_corners.DetectorParams`; presets that adapt
to the sensor take the scan's geometry from ``scan`` (any :class:`~laser_corners.LaserScan`
of the recording).
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from laser_corners.errors import InvalidParamsError
from laser_corners.noise import estimate_range_noise
from laser_corners.params import PAPER_SCALES, DetectorParams
from laser_corners.scan import LaserScan

__all__ = [
    "AUTO_N_SCALES",
    "AUTO_TARGET_RANGE",
    "PRESETS",
    "PRESET_MAX_GAP_BEAMS",
    "ROBUST_NOISE_FLOOR",
    "auto_params",
    "get_preset",
    "robust_params",
]

AUTO_TARGET_RANGE = 3.0
"""Range (m) at which the ``auto`` preset's smallest adapted scale holds ``min_points`` points."""
AUTO_N_SCALES = 17
"""Number of scales of the ``auto`` preset."""
PRESET_MAX_GAP_BEAMS = 2
"""``max_gap_beams`` of the ``auto`` and ``robust`` presets: neighbourhoods step over runs of
up to 2 dropped beams (measured with ``benchmarks/dropout_study.py``, see ``docs/method.md``)."""


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

    See :func:`auto_params`; the target range is :data:`AUTO_TARGET_RANGE`; neighbourhoods
    bridge runs of up to :data:`PRESET_MAX_GAP_BEAMS` dropped beams.
    """
    if scan is None:
        raise InvalidParamsError(
            "preset 'auto' needs a scan of the recording (its angular resolution): "
            "pass one, e.g. CornerDetector.from_preset('auto', scan)"
        )
    return auto_params(scan.angle_increment).with_overrides({"max_gap_beams": PRESET_MAX_GAP_BEAMS})


ROBUST_NOISE_FLOOR = 0.01
"""Noise sigma (m) up to which the ``robust`` preset keeps its base scales 0.1-0.25 m."""


def robust_params(noise_sigma: float) -> DetectorParams:
    """Parameters for a range noise of ``noise_sigma`` metres (the ``robust`` preset).

    Changes to the paper's values (see ``docs/simulation-and-accuracy.md``):

    * ``min_extent_ratio = 0.6``: a neighbourhood counts at scale R_k only if its far end
      lies at least 0.6·R_k from p_j. A run cut short by a gap, a jump or the end of the scan
      (legs, object edges, the field of view's ends) no longer passes at every larger scale
      with the same, few, points;
    * scales: 9 radii from 0.1 m to ``0.25 * max(1, sigma / 0.01)`` m: the line angle from n
      noisy points over a length L errs by about ``sigma * sqrt(12 / n) / L``, so the
      neighbourhoods grow with the noise;
    * ``max_fit_rmse = max(0.025, 1.75 sigma)``, ``max_point_distance = 0.05 + 2 sigma``,
      ``max_centroid_distance = 0.025 + 2 sigma``: tolerances that follow the noise;
    * ``refine_radius = 0.5``, ``refine_exclude = 0.03``: each merged keypoint is re-estimated
      from lines fitted to each wall's points within 0.5 m of it (those within 3 cm left out);
    * ``max_gap_beams = 2`` (:data:`PRESET_MAX_GAP_BEAMS`): runs of up to two dropped beams
      inside a neighbourhood (or a refinement run) are stepped over.

    Parameters
    ----------
    noise_sigma : float
        Range noise standard deviation, metres (e.g. from
        :func:`~laser_corners.noise.estimate_range_noise`).

    Examples
    --------
    >>> p = robust_params(0.03)
    >>> p.scales[0], p.scales[-1], round(p.max_fit_rmse, 4)
    (0.1, 0.75, 0.0525)
    """
    sigma = float(noise_sigma)
    if not (math.isfinite(sigma) and sigma >= 0.0):
        raise InvalidParamsError(f"robust preset: noise sigma must be >= 0, got {noise_sigma}")
    top = PAPER_SCALES[-1] * max(1.0, sigma / ROBUST_NOISE_FLOOR)
    scales = tuple(round(float(v), 6) for v in np.linspace(0.1, top, 9))
    return DetectorParams(
        scales=scales,
        max_fit_rmse=max(0.025, 1.75 * sigma),
        max_point_distance=0.05 + 2.0 * sigma,
        max_centroid_distance=0.025 + 2.0 * sigma,
        min_extent_ratio=0.6,
        refine_radius=0.5,
        refine_exclude=0.03,
        max_gap_beams=PRESET_MAX_GAP_BEAMS,
    )


def robust(scan: LaserScan | None = None) -> DetectorParams:
    """Noise-adapted thresholds, neighbourhood extent test and keypoint refinement.

    The range noise is estimated from ``scan`` itself
    (:func:`~laser_corners.noise.estimate_range_noise`); see :func:`robust_params`.
    """
    if scan is None:
        raise InvalidParamsError(
            "preset 'robust' needs a scan of the recording (its range noise): "
            "pass one, e.g. CornerDetector.from_preset('robust', scan)"
        )
    return robust_params(estimate_range_noise(scan))


PRESETS: dict[str, Callable[[LaserScan | None], DetectorParams]] = {
    "paper": paper,
    "auto": auto,
    "robust": robust,
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
