"""Revisits and the local window of the place-recognition evaluation.

Used by :mod:`laser_corners.eval.loops`:

* **window**: candidate ``j`` of query ``q`` is excluded when the robot travelled less than
  ``window_travel`` metres of path between the two scans (:func:`candidates`).
* **revisit**: query ``q`` has a revisit when some scan outside its window *sees* at least
  ``overlap`` of the query's scan points: a query point moved into that scan's sensor frame by
  the true poses lies inside its field of view and range, and that scan measured a return
  within ``tolerance`` of the point's range along that beam (same surface, not occluded).
  It depends on the scans and poses only, not on any detector (:func:`revisits`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numba as nb
import numpy as np
from numpy.typing import NDArray

from laser_corners.matching.verify import beam_of
from laser_corners.scan import LaserScan

__all__ = ["candidates", "revisits", "travel_distance"]


def travel_distance(poses: NDArray[np.float64]) -> NDArray[np.float64]:
    """Path length travelled from the first pose to each pose, metres."""
    p = np.asarray(poses, dtype=np.float64).reshape(-1, 3)
    steps = np.hypot(np.diff(p[:, 0]), np.diff(p[:, 1]))
    return np.concatenate([[0.0], np.cumsum(steps)])


def candidates(travel: NDArray[np.float64], query: int, window_travel: float) -> NDArray[np.int64]:
    """Scans outside the query's window: at least ``window_travel`` metres of path away."""
    return np.flatnonzero(np.abs(travel - travel[query]) >= window_travel).astype(np.int64)


@nb.njit(cache=True, nogil=True, parallel=True)
def _revisits(
    poses: NDArray[np.float64],
    travel: NDArray[np.float64],
    window: float,
    pts: NDArray[np.float64],
    pt_off: NDArray[np.int64],
    ranges: NDArray[np.float64],
    r_off: NDArray[np.int64],
    geom: NDArray[np.float64],
    overlap: float,
    tol: float,
    out: NDArray[np.int64],
) -> None:
    """``out[q]``: first candidate seeing ``overlap`` of query q's points, or -1."""
    n_scans = poses.shape[0]
    for q in nb.prange(n_scans):
        out[q] = -1
        n_pts = pt_off[q + 1] - pt_off[q]
        if n_pts == 0:
            continue
        cq, sq = math.cos(poses[q, 2]), math.sin(poses[q, 2])
        allowed_misses = int((1.0 - overlap) * n_pts)
        for j in range(n_scans):
            if abs(travel[j] - travel[q]) < window:
                continue
            cj, sj = math.cos(poses[j, 2]), math.sin(poses[j, 2])
            amin, ainc, rmin, rmax = geom[j, 0], geom[j, 1], geom[j, 2], geom[j, 3]
            n_beams = r_off[j + 1] - r_off[j]
            misses = 0
            for p in range(pt_off[q], pt_off[q + 1]):
                mx = poses[q, 0] + cq * pts[p, 0] - sq * pts[p, 1] - poses[j, 0]
                my = poses[q, 1] + sq * pts[p, 0] + cq * pts[p, 1] - poses[j, 1]
                x, y = cj * mx + sj * my, -sj * mx + cj * my
                r = math.sqrt(x * x + y * y)
                k = math.floor(beam_of(math.atan2(y, x), amin, ainc) + 0.5)
                seen = False
                if 0 <= k < n_beams and r < rmax:
                    rj = ranges[r_off[j] + k]
                    seen = rmin < rj < rmax and abs(rj - r) <= tol
                if not seen:
                    misses += 1
                    if misses > allowed_misses:
                        break
            if misses <= allowed_misses:
                out[q] = j
                break


def revisits(
    scans: Sequence[LaserScan],
    window_travel: float = 5.0,
    overlap: float = 0.5,
    tolerance: float = 0.3,
    max_points: int = 120,
) -> NDArray[np.int64]:
    """For each scan, a scan outside its window that sees ``overlap`` of its points, or -1.

    Parameters
    ----------
    scans : sequence of LaserScan
        Scans with poses (map frame).
    window_travel : float
        Window of :func:`candidates`, metres of path.
    overlap : float
        Share of the query's points the other scan must see.
    tolerance : float
        Range agreement of a seen point, metres.
    max_points : int
        The query's valid points are evenly thinned to at most this many.

    Returns
    -------
    ndarray of int, shape (S,)
    """
    poses = np.array([s.pose for s in scans], dtype=np.float64).reshape(-1, 3)
    pts_list = []
    for scan in scans:
        xy, valid = scan.to_cartesian()
        xy = xy[valid]
        if len(xy) > max_points:
            xy = xy[np.linspace(0, len(xy) - 1, max_points).round().astype(int)]
        pts_list.append(xy)
    pt_off = np.concatenate([[0], np.cumsum([len(p) for p in pts_list])]).astype(np.int64)
    r_off = np.concatenate([[0], np.cumsum([s.n_beams for s in scans])]).astype(np.int64)
    ranges = np.concatenate([np.nan_to_num(s.ranges, nan=-1.0, posinf=-1.0) for s in scans])
    geom = np.array([(s.angle_min, s.angle_increment, s.range_min, s.range_max) for s in scans])
    out = np.full(len(scans), -1, dtype=np.int64)
    _revisits(
        poses,
        travel_distance(poses),
        float(window_travel),
        np.ascontiguousarray(np.concatenate(pts_list), dtype=np.float64),
        pt_off,
        ranges.astype(np.float64),
        r_off,
        geom.astype(np.float64),
        float(overlap),
        float(tolerance),
        out,
    )
    return out
