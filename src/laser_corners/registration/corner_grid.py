"""The map's corners bucketed in cells and grouped into physical corners, and the numba
passes of a place query over them: descriptor matches (:func:`nearest`) and consensus votes
(:func:`count_votes`). No Python loop per corner pair; see
:mod:`~laser_corners.registration.place_index` for how they are used."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba
import numpy as np
from numpy.typing import NDArray

from laser_corners.registration.corners import Corners

__all__ = ["CornerGrid", "count_votes", "nearest"]


@numba.njit(cache=True, nogil=True, fastmath=True)
def _l1(a: NDArray[np.float32], b: NDArray[np.float32]) -> float:
    acc = np.float32(0.0)
    for c in range(a.shape[0]):
        acc += abs(a[c] - b[c])
    return acc


@numba.njit(cache=True, nogil=True)
def nearest(
    query: NDArray[np.float32],
    q_open: NDArray[np.float64],
    index: NDArray[np.float32],
    m_open: NDArray[np.float64],
    landmark: NDArray[np.int64],
    n_landmarks: int,
    max_open: float,
    max_distance: float,
    k: int,
) -> NDArray[np.int64]:
    """For each row of ``query``: the rows of ``index`` that are the best match (L1 distance)
    of the ``k`` nearest distinct landmarks (``landmark``: each row's physical corner), among
    rows with opening angles within ``max_open`` and distance at most ``max_distance``
    (-1 where fewer qualify). Distinct landmarks: a corner seen from many keyframes must not
    fill every place. Only the landmarks a query row reached are ranked and reset: the cost
    is that of the distances, not of the map's landmarks times ``k``."""
    nq = query.shape[0]
    found = np.full((nq, k), -1, dtype=np.int64)
    best = np.full(n_landmarks, np.inf)
    arg = np.full(n_landmarks, -1, dtype=np.int64)
    reached = np.empty(n_landmarks, dtype=np.int64)
    for q in range(nq):
        n = 0
        for m in range(index.shape[0]):
            if abs(q_open[q] - m_open[m]) > max_open:
                continue
            d = _l1(query[q], index[m])
            lm = landmark[m]
            if d <= max_distance and d < best[lm]:
                if arg[lm] < 0:
                    reached[n] = lm
                    n += 1
                best[lm] = d
                arg[lm] = m
        for j in range(k):  # the k smallest by selection (k is small), ties to the lower id
            pick = -1
            for t in range(n):
                lm = reached[t]
                if arg[lm] < 0:
                    continue
                if pick < 0 or best[lm] < best[pick] or (best[lm] == best[pick] and lm < pick):
                    pick = lm
            if pick < 0:
                break
            found[q, j] = arg[pick]
            arg[pick] = -1
        for t in range(n):
            best[reached[t]] = np.inf
            arg[reached[t]] = -1
    return found


@numba.njit(cache=True, nogil=True)
def _landmarks(
    xy: NDArray[np.float64],
    ori: NDArray[np.float64],
    origin: NDArray[np.float64],
    cell: float,
    ny: int,
    nx: int,
    start: NDArray[np.int64],
    order: NDArray[np.int64],
    radius: float,
    yaw_tol: float,
) -> tuple[NDArray[np.int64], int]:
    """A physical corner per group of observations: each unlabelled corner (in order) starts
    a landmark and takes every unlabelled corner within ``radius`` and ``yaw_tol`` of it."""
    n = xy.shape[0]
    label = np.full(n, -1, dtype=np.int64)
    count = 0
    r2 = radius * radius
    for i in range(n):
        if label[i] >= 0:
            continue
        label[i] = count
        ix = math.floor((xy[i, 0] - origin[0]) / cell)
        iy = math.floor((xy[i, 1] - origin[1]) / cell)
        for b in range(max(iy - 1, 0), min(iy + 2, ny)):
            for a in range(max(ix - 1, 0), min(ix + 2, nx)):
                key = b * nx + a
                for t in range(start[key], start[key + 1]):
                    m = order[t]
                    if label[m] >= 0:
                        continue
                    dx = xy[m, 0] - xy[i, 0]
                    dy = xy[m, 1] - xy[i, 1]
                    turn = (ori[m] - ori[i] + math.pi) % (2.0 * math.pi) - math.pi
                    if dx * dx + dy * dy <= r2 and abs(turn) <= yaw_tol:
                        label[m] = count
        count += 1
    return label, count


@dataclass
class CornerGrid:
    """Map corners bucketed in square cells (CSR: ``start[c]:start[c + 1]`` of ``order``),
    for the consensus lookups, and grouped into physical corners (``landmark``: the corners
    within ``radius`` and ``yaw`` of a first one, :func:`_landmarks`)."""

    corners: Corners
    origin: NDArray[np.float64]
    cell: float
    shape: tuple[int, int]
    start: NDArray[np.int64]
    order: NDArray[np.int64]
    landmark: NDArray[np.int64]
    n_landmarks: int
    views: NDArray[np.int64]
    """The observations the descriptor pass compares (at most :data:`VIEWS_PER_CORNER` of
    each physical corner, spread over the keyframes that saw it)."""

    def nearest(self, query: Corners, max_open: float, max_distance: float, k: int):
        """:func:`nearest` of ``query`` against :attr:`views`: (Q, k) rows of the corners."""
        m = self.corners
        found = nearest(
            np.ascontiguousarray(query.descriptor),
            np.ascontiguousarray(query.opening),
            np.ascontiguousarray(m.descriptor[self.views]),
            np.ascontiguousarray(m.opening[self.views]),
            np.ascontiguousarray(self.landmark[self.views]),
            self.n_landmarks,
            max_open,
            max_distance,
            k,
        )
        return np.where(found >= 0, self.views[np.maximum(found, 0)], -1)

    def votes(
        self, poses: NDArray[np.float64], query: Corners, radius: float, yaw: float
    ) -> NDArray[np.int64]:
        """:func:`count_votes` of ``poses`` (H, 3) for the ``query`` corners."""
        m = self.corners
        return count_votes(
            np.ascontiguousarray(poses),
            np.ascontiguousarray(query.xy),
            np.ascontiguousarray(query.orientation),
            np.ascontiguousarray(m.xy),
            np.ascontiguousarray(m.orientation),
            self.origin,
            self.cell,
            self.shape[0],
            self.shape[1],
            self.start,
            self.order,
            radius,
            yaw,
        )

    @classmethod
    def build(cls, corners: Corners, radius: float, yaw: float) -> CornerGrid:
        """The grid of ``corners``; observations within ``radius`` and ``yaw`` of a first
        one are one physical corner."""
        lo = corners.xy.min(axis=0) - radius
        span = corners.xy.max(axis=0) + radius - lo
        cell = max(radius, float(span.max()) / 4096.0)  # at most 4096 cells a side
        nx, ny = (np.floor(span / cell).astype(np.int64) + 1).tolist()
        ij = np.floor((corners.xy - lo) / cell).astype(np.int64)
        key = ij[:, 1] * nx + ij[:, 0]
        order = np.argsort(key, kind="stable")
        start = np.searchsorted(key[order], np.arange(nx * ny + 1)).astype(np.int64)
        xy = np.ascontiguousarray(corners.xy)
        ori = np.ascontiguousarray(corners.orientation)
        landmark, count = _landmarks(xy, ori, lo, cell, ny, nx, start, order, radius, yaw)
        views = _spread_views(landmark, VIEWS_PER_CORNER)
        return cls(corners, lo, cell, (ny, nx), start, order, landmark, count, views)


VIEWS_PER_CORNER = 4
"""Observations of one physical corner the descriptor pass compares at most: a corner seen
from a hundred keyframes costs as much as one seen from four (they look alike)."""


def _spread_views(landmark: NDArray[np.int64], most: int) -> NDArray[np.int64]:
    """Indices of at most ``most`` observations per landmark, spread over its observations
    (in their order: the keyframes'), sorted."""
    order = np.argsort(landmark, kind="stable")
    grouped = landmark[order]
    first = np.searchsorted(grouped, grouped, side="left")
    size = np.searchsorted(grouped, grouped, side="right") - first
    rank = np.arange(len(order)) - first
    bin_now = rank * most // size
    bin_before = (rank - 1) * most // size
    keep = (rank == 0) | (bin_now != bin_before)
    return np.sort(order[keep])


@numba.njit(cache=True, nogil=True)
def count_votes(
    poses: NDArray[np.float64],
    qxy: NDArray[np.float64],
    qori: NDArray[np.float64],
    mxy: NDArray[np.float64],
    mori: NDArray[np.float64],
    origin: NDArray[np.float64],
    cell: float,
    ny: int,
    nx: int,
    start: NDArray[np.int64],
    order: NDArray[np.int64],
    radius: float,
    yaw_tol: float,
) -> NDArray[np.int64]:
    """Per pose: the query corners landing within ``radius`` of a map corner whose bisector
    is within ``yaw_tol`` of theirs."""
    votes = np.zeros(poses.shape[0], dtype=np.int64)
    r2 = radius * radius
    for h in range(poses.shape[0]):
        c = math.cos(poses[h, 2])
        s = math.sin(poses[h, 2])
        for q in range(qxy.shape[0]):
            x = c * qxy[q, 0] - s * qxy[q, 1] + poses[h, 0]
            y = s * qxy[q, 0] + c * qxy[q, 1] + poses[h, 1]
            ori = qori[q] + poses[h, 2]
            ix = math.floor((x - origin[0]) / cell)
            iy = math.floor((y - origin[1]) / cell)
            hit = False
            for b in range(max(iy - 1, 0), min(iy + 2, ny)):
                for a in range(max(ix - 1, 0), min(ix + 2, nx)):
                    key = b * nx + a
                    for t in range(start[key], start[key + 1]):
                        m = order[t]
                        dx = mxy[m, 0] - x
                        dy = mxy[m, 1] - y
                        turn = (mori[m] - ori + math.pi) % (2.0 * math.pi) - math.pi
                        if dx * dx + dy * dy <= r2 and abs(turn) <= yaw_tol:
                            hit = True
                            break
                    if hit:
                        break
                if hit:
                    break
            votes[h] += hit
    return votes
