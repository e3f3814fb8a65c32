"""What the localiser gives: :class:`LocaliserEstimate` per scan, :class:`Fix` per fix, and
its timing records (:func:`timing_record`: the last :data:`TIMINGS_KEPT` only)."""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

__all__ = ["TIMINGS_KEPT", "Fix", "LocaliserEstimate", "timing_record"]

TIMINGS_KEPT = 10_000
"""Entries a timing record keeps (:func:`timing_record`): the last 10,000 attempts, slices or
scans. A localiser running for days in the ROS 2 node would otherwise keep one per scan
without bound; how many there were comes from a counter, never from a record's length."""


def timing_record() -> deque[Any]:
    """An empty record of per-attempt (or per-scan) timings that keeps the last
    :data:`TIMINGS_KEPT` entries (the value when it is made), dropping the oldest.

    Returns
    -------
    collections.deque
        Empty, ``maxlen`` :data:`TIMINGS_KEPT`.
    """
    return deque(maxlen=TIMINGS_KEPT)


@dataclass
class LocaliserEstimate:
    """One pose estimate of :meth:`Localiser.add`.

    Attributes
    ----------
    pose : ndarray, shape (3,)
        Base pose ``(x, y, yaw)`` in the map frame.
    covariance : ndarray, shape (3, 3)
        Its covariance (map frame).
    status : str
        ``"relocalised"`` on the scan of a (first or new) fix, ``"local"`` for a scan that
        sees much unmapped space and is placed by the recent scans more than by the map
        (``localise.local``: chained to the last anchored pose, covariance growing), else
        ``"tracking"``.
    map_to_odom : ndarray, shape (3,)
        ``pose ∘ odometry⁻¹``: the map -> odom transform a ROS node publishes.
    scan_index : int
        Index of the scan among those given to :meth:`Localiser.add`.
    stamp : float
    agreement : float
        Share of the scan's points within ``inlier_distance`` of the map, or of the map and
        the local submap together (their points are disjoint).
    """

    pose: NDArray[np.float64]
    covariance: NDArray[np.float64]
    status: str
    map_to_odom: NDArray[np.float64]
    scan_index: int
    stamp: float
    agreement: float = 0.0


@dataclass
class Fix:
    """A fix (first or after lost): where, when and after how much travel."""

    scan_index: int
    stamp: float
    travel: float
    """Odometry travel (m) since the search started."""
    pose: tuple[float, float, float]
    windowed: bool = False
    """Found inside the window of the lost track's dead-reckoned pose (``localise.window``)."""
