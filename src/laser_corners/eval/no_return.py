""" "No return" readings that a recording stores as a number (a max-range sentinel).

Some scanners and converters write a beam without an echo as a fixed large range instead of
``inf``/NaN or a value ``>= range_max``: SICK LMS 2xx logs carry 81.91 m (8191 cm, the
all-ones 13-bit value), and ROS bags converted from them may declare a ``range_max`` above it.
Such readings are valid for :class:`~laser_corners.LaserScan` and would enter the maps as a wall
of points 82 m away. :func:`no_return_range` finds such a sentinel from the data alone: the
largest valid reading, repeated on many beams to within a few millimetres (real echoes spread
out), and :func:`without_no_returns` turns every reading at or beyond it into a gap.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence

import numpy as np

from laser_corners.scan import LaserScan

__all__ = ["no_return_range", "without_no_returns"]


def no_return_range(
    scans: Sequence[LaserScan], min_share: float = 0.002, min_count: int = 10, tol: float = 0.001
) -> float | None:
    """The range from which valid readings are "no return" sentinels, or ``None``.

    The sentinel is the largest valid reading when at least ``min_count`` readings, and at
    least ``min_share`` of all valid readings, lie within ``tol`` metres of it.

    Examples
    --------
    >>> import numpy as np
    >>> ranges = np.r_[np.linspace(1.0, 9.0, 90), np.full(90, 81.91)]
    >>> scan = LaserScan(ranges, -1.57, 0.0175, 0.0, 100.0)
    >>> round(no_return_range([scan]), 3)
    81.909
    >>> no_return_range([LaserScan(np.linspace(1.0, 9.0, 180), -1.57, 0.0175, 0.0, 100.0)])
    """
    values = [s.ranges[s.valid] for s in scans]
    if not values:
        return None
    ranges = np.concatenate(values)
    if ranges.size == 0:
        return None
    top = float(ranges.max())
    at_top = int(np.count_nonzero(ranges >= top - tol))
    if at_top >= max(min_count, min_share * ranges.size):
        return top - tol
    return None


def without_no_returns(scans: Sequence[LaserScan], limit: float) -> list[LaserScan]:
    """The scans with ``range_max`` lowered to ``limit``: readings at or beyond it become gaps."""
    return [dataclasses.replace(s, range_max=limit) if s.range_max > limit else s for s in scans]
