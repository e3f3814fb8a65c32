"""Whether a scan could have seen a point: the visibility test of every evaluation metric.

A point (sensor frame) is *in view* of a scan when it lies within ``[range_min, max_range]``,
between the first and the last beam (half a beam of margin) and, with occlusion, at most a
tolerance beyond the range measured by one of the two beams that bracket its bearing. Beams
without a return make nothing visible. Used by :mod:`laser_corners.eval.observability` and
:mod:`laser_corners.eval.repeatability`.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np
from numpy.typing import ArrayLike, NDArray

from laser_corners.scan import LaserScan

__all__ = ["View", "point_in_view", "points_in_view", "ranges_with_nan", "view_limit", "view_of"]


View = tuple[float, float, float, float, float, bool]
"""(angle_min, angle_increment, range_min, max_range, tolerance, occlusion): what decides
whether a scan sees a point (see :func:`point_in_view`)."""


def view_of(scan: LaserScan, tolerance: float, occlusion: bool, max_range: float | None) -> View:
    """The :data:`View` of a scan (``max_range`` caps its ``range_max``)."""
    return (
        scan.angle_min,
        scan.angle_increment,
        scan.range_min,
        view_limit(scan, max_range),
        float(tolerance),
        bool(occlusion),
    )


@nb.njit(cache=True)
def point_in_view(px: float, py: float, ranges: NDArray[np.float64], view: View) -> bool:
    """Whether a point (sensor frame) is in view; ``ranges`` has NaN for beams without return.

    The point must lie within ``[range_min, max_range]`` and between the first and the last
    beam (half a beam of margin). With ``occlusion`` it must also be at most ``tolerance``
    beyond the range measured by one of the two beams that bracket its bearing; beams without
    a return do not make a point visible.
    """
    angle_min, angle_increment, range_min, max_range, tolerance, occlusion = view
    d = math.sqrt(px * px + py * py)
    if d < range_min or d > max_range:
        return False
    n = ranges.shape[0]
    bearing = math.atan2(py, px)
    f = (bearing - angle_min) / angle_increment
    # the FOV may wrap: try the bearing and its +-2 pi aliases
    turns = 2.0 * math.pi / abs(angle_increment)
    found = False
    for shift in (0.0, turns, -turns):
        g = f + shift
        if -0.5 <= g <= n - 0.5:
            f = g
            found = True
            break
    if not found:
        return False
    if not occlusion:
        return True
    i0 = math.floor(f)
    for i in (i0, i0 + 1):
        if 0 <= i < n:
            r = ranges[i]
            if math.isfinite(r) and d <= r + tolerance:
                return True
    return False


@nb.njit(cache=True)
def _points_in_view(
    xy: NDArray[np.float64], ranges: NDArray[np.float64], view: View, out: NDArray[np.bool_]
) -> None:
    for k in range(xy.shape[0]):
        out[k] = point_in_view(xy[k, 0], xy[k, 1], ranges, view)


def ranges_with_nan(scan: LaserScan) -> NDArray[np.float64]:
    """The scan's ranges with NaN for beams without a valid return."""
    return np.where(scan.valid, scan.ranges, np.nan)


def view_limit(scan: LaserScan, max_range: float | None) -> float:
    """Farthest in-view distance: the scan's ``range_max`` (if finite), capped by ``max_range``."""
    limit = scan.range_max if math.isfinite(scan.range_max) else 1e9
    return limit if max_range is None else min(limit, float(max_range))


def points_in_view(
    scan: LaserScan,
    points: ArrayLike,
    tolerance: float = 0.06,
    occlusion: bool = True,
    max_range: float | None = None,
) -> NDArray[np.bool_]:
    """Which points (sensor frame of ``scan``) the scan could have seen.

    Parameters
    ----------
    scan : LaserScan
        The scan; its beams define the field of view.
    points : array_like, shape (M, 2)
        Points in the scan's sensor frame, metres.
    tolerance : float
        With ``occlusion``, how far beyond the measured range a point may lie and still count
        as seen (keypoints are line intersections, so they may sit slightly behind the hit).
    occlusion : bool
        Ray-cast against the scan itself: a point behind the measured surface, or along a beam
        without a return, is not in view.
    max_range : float, optional
        Ignore points farther than this (default: the scan's ``range_max``).

    Returns
    -------
    ndarray of bool, shape (M,)
    """
    xy = np.ascontiguousarray(np.asarray(points, dtype=np.float64).reshape(-1, 2))
    out = np.zeros(xy.shape[0], dtype=np.bool_)
    _points_in_view(xy, ranges_with_nan(scan), view_of(scan, tolerance, occlusion, max_range), out)
    return out
