"""Candidates -> keypoints: duplicate merging, optional refinement, the batch driver.

Decisions the paper leaves open (``docs/method.md``): per-point candidates whose keypoints
lie within ``merge_radius`` of each other are merged by single linkage; the merged keypoint
is the cluster's best candidate (lowest worst-fit RMSE, ties: more passing scales, then the
first in beam order). ``refine_radius`` (option, not in the paper) re-estimates each keypoint
from lines fitted to longer runs of each wall.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np
from numpy.typing import NDArray

from laser_corners.kernel.candidates import (
    C_K0,
    C_NSC,
    C_OPEN,
    C_ORIENT,
    C_RMSE,
    C_X,
    C_Y,
    NC,
    KernelConfig,
    candidates,
    polar_to_xy,
    unpack,
)
from laser_corners.kernel.linefit import intersect, select_from_sums

__all__ = [
    "NM",
    "detect_batch",
    "detect_into",
    "detect_scan",
    "detect_xy",
    "finish",
    "merge",
    "raw_rows",
    "refine",
]

# columns of the keypoint rows (float64, shape (M, NM))
M_X, M_Y, M_BEAM, M_OPEN, M_ORIENT, M_NSC, M_RMSE, M_NMERGED, M_K0 = range(9)
NM = 9
OUT_PER_BEAM = 2 + NM  # :func:`detect_scan`'s output: x, y, then up to one row per beam
# largest move of a keypoint by the refinement when merging is off (merge_radius = 0), metres
REFINE_MAX_SHIFT = 0.05


@nb.njit(cache=True, nogil=True, error_model="numpy")
def _row(out: NDArray[np.float64], m: int, cand: NDArray[np.float64], j: int) -> None:
    out[m, M_X] = cand[j, C_X]
    out[m, M_Y] = cand[j, C_Y]
    out[m, M_BEAM] = j
    out[m, M_OPEN] = cand[j, C_OPEN]
    out[m, M_ORIENT] = cand[j, C_ORIENT]
    out[m, M_NSC] = cand[j, C_NSC]
    out[m, M_RMSE] = cand[j, C_RMSE]
    out[m, M_NMERGED] = 1
    out[m, M_K0] = cand[j, C_K0]


@nb.njit(cache=True, nogil=True, error_model="numpy")
def raw_rows(cand: NDArray[np.float64], out: NDArray[np.float64]) -> int:
    """Copy every per-point candidate into ``out`` as an unmerged keypoint row."""
    m = 0
    for j in range(cand.shape[0]):
        if cand[j, C_NSC] > 0.0:
            _row(out, m, cand, j)
            m += 1
    return m


@nb.njit(cache=True, nogil=True, error_model="numpy")
def _find(parent: NDArray[np.int64], a: int) -> int:
    while parent[a] != a:
        parent[a] = parent[parent[a]]  # path halving
        a = parent[a]
    return a


@nb.njit(cache=True, nogil=True, error_model="numpy")
def _link_cells(cand, idx, order, parent, a0: int, a1: int, b0: int, b1: int, r2: float) -> None:
    """Link the clusters of two grid cells (members ``order[a0:a1]``, ``order[b0:b1]``) if
    any pair of their candidates lies within sqrt(``r2``); stops at the first such pair."""
    if _find(parent, order[a0]) == _find(parent, order[b0]):
        return
    for p in range(a0, a1):
        ja = idx[order[p]]
        for q in range(b0, b1):
            jb = idx[order[q]]
            d2 = (cand[ja, C_X] - cand[jb, C_X]) ** 2 + (cand[ja, C_Y] - cand[jb, C_Y]) ** 2
            if d2 <= r2:
                ra = _find(parent, order[a0])
                rb = _find(parent, order[b0])
                parent[max(ra, rb)] = min(ra, rb)
                return


@nb.njit(cache=True, nogil=True, error_model="numpy")
def _link(cand: NDArray[np.float64], idx: NDArray[np.int64], r2: float) -> NDArray[np.int64]:
    """Union-find parents of the single-linkage clusters of the candidates ``idx``.

    A grid of cells of side r/sqrt(2) (a hair less): candidates in one cell are within r of
    each other and are linked directly; two cells at most 2 apart are linked at their first
    pair within r. O(M log M) for M candidates, however densely they crowd one corner. Up to
    64 candidates (a scan of normal density) all pairs are compared instead (cheaper there).
    """
    m = idx.shape[0]
    parent = np.arange(m)
    if m == 0:
        return parent
    side = math.sqrt(r2) / math.sqrt(2.0) * (1.0 - 1e-6)
    xs = np.empty(m)
    ys = np.empty(m)
    for a in range(m):
        xs[a] = cand[idx[a], C_X]
        ys[a] = cand[idx[a], C_Y]
    cells = ((xs.max() - xs.min()) / side + 5.0) * ((ys.max() - ys.min()) / side + 5.0)
    if m <= 64 or not cells < 1e15:  # few candidates, or a radius far below their spread
        for a in range(m):
            for b in range(a + 1, m):
                dx = xs[a] - xs[b]
                dy = ys[a] - ys[b]
                if dx * dx + dy * dy <= r2:
                    ra = _find(parent, a)
                    rb = _find(parent, b)
                    parent[max(ra, rb)] = min(ra, rb)
        return parent
    gx = np.empty(m, dtype=np.int64)
    gy = np.empty(m, dtype=np.int64)
    for a in range(m):
        gx[a] = math.floor(xs[a] / side)
        gy[a] = math.floor(ys[a] / side)
    width = gy.max() - gy.min() + 5
    key = (gx - gx.min()) * width + (gy - gy.min() + 2)
    order = np.argsort(key, kind="mergesort")
    skey = key[order]
    runs = np.flatnonzero(np.diff(skey)) + 1  # starts of the cells' runs, after the first
    starts = np.empty(runs.shape[0] + 2, dtype=np.int64)
    starts[0] = 0
    starts[1:-1] = runs
    starts[-1] = m
    for c in range(starts.shape[0] - 1):
        for p in range(starts[c] + 1, starts[c + 1]):  # one cell: all within r
            ra = _find(parent, order[p])
            rb = _find(parent, order[starts[c]])
            parent[max(ra, rb)] = min(ra, rb)
    for c in range(starts.shape[0] - 1):
        a0 = starts[c]
        a1 = starts[c + 1]
        for dx in range(0, 3):
            for dy in range(-2, 3):
                if dx == 0 and dy <= 0:
                    continue  # each pair of cells once
                other = skey[a0] + dx * width + dy
                b0 = np.searchsorted(skey, other)
                if b0 >= m or skey[b0] != other:
                    continue
                b1 = np.searchsorted(skey, other, side="right")
                _link_cells(cand, idx, order, parent, a0, a1, b0, b1, r2)
    return parent


@nb.njit(cache=True, nogil=True, error_model="numpy")
def merge(cand: NDArray[np.float64], merge_radius: float, merged: NDArray[np.float64]) -> int:
    """Merge per-point candidates by single linkage within ``merge_radius``.

    Writes one row per merged keypoint into ``merged`` (NM columns), ordered by the beam index
    of each cluster's first candidate, and returns their count.
    """
    n = cand.shape[0]
    idx = np.empty(n, dtype=np.int64)
    m = 0
    for j in range(n):
        if cand[j, C_NSC] > 0.0:
            idx[m] = j
            m += 1
    if m == 0:  # no candidates: none of the tables below
        return 0
    idx = idx[:m]
    parent = _link(cand, idx, merge_radius * merge_radius)
    label = np.empty(m, dtype=np.int64)
    root_label = np.full(m, -1, dtype=np.int64)
    n_out = 0
    for a in range(m):
        r = _find(parent, a)
        if root_label[r] < 0:
            root_label[r] = n_out
            n_out += 1
        label[a] = root_label[r]
    count = np.zeros(n_out, dtype=np.int64)
    rep = np.full(n_out, -1, dtype=np.int64)
    worst = np.zeros(n_out)
    for a in range(m):
        c = label[a]
        j = idx[a]
        count[c] += 1
        worst[c] = max(worst[c], cand[j, C_RMSE])
        r = rep[c]
        if (
            r < 0
            or cand[j, C_RMSE] < cand[r, C_RMSE]
            or (cand[j, C_RMSE] == cand[r, C_RMSE] and cand[j, C_NSC] > cand[r, C_NSC])
        ):
            rep[c] = j
    for c in range(n_out):
        _row(merged, c, cand, rep[c])
        merged[c, M_RMSE] = worst[c]
        merged[c, M_NMERGED] = count[c]
    return n_out


@nb.njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _next(x: NDArray[np.float64], i: int, step: int, max_gap: int) -> int:
    """Next index of a walk from ``i`` towards ``step`` across at most ``max_gap`` gaps
    (-1 when the walk ends: scan end or a longer run of gaps)."""
    n = x.shape[0]
    i += step
    gaps = 0
    while 0 <= i < n and not math.isfinite(x[i]):
        gaps += 1
        if gaps > max_gap:
            return -1
        i += step
    return i if 0 <= i < n else -1


@nb.njit(cache=True, nogil=True, error_model="numpy")
def nearest(x, y, b: int, cx: float, cy: float, r2: float, max_gap: int) -> int:
    """The scan point nearest to (cx, cy), searched outwards from beam ``b`` within ``r2``."""
    apex = b
    best = (x[b] - cx) ** 2 + (y[b] - cy) ** 2
    for step in (-1, 1):
        i = _next(x, b, step, max_gap)
        while i >= 0:
            d2 = (x[i] - cx) ** 2 + (y[i] - cy) ** 2
            if d2 > r2:
                break
            if d2 < best:
                best = d2
                apex = i
            i = _next(x, i, step, max_gap)
    return apex


@nb.njit(cache=True, nogil=True, error_model="numpy")
def wall_sums(
    x,
    y,
    apex: int,
    step: int,
    cx: float,
    cy: float,
    r2: float,
    e2: float,
    max_gap: int,
    sums: NDArray[np.float64],
) -> int:
    """n, Σdx, Σdy, Σdx², Σdy², Σdxdy (relative to (cx, cy)) of one wall's run within
    ``r2`` of the keypoint, leaving out points closer than ``e2``; returns the index of the
    run's farthest counted point (``apex`` when none)."""
    sums[:] = 0.0
    far = apex
    i = _next(x, apex, step, max_gap)
    while i >= 0:
        dx = x[i] - cx
        dy = y[i] - cy
        d2 = dx * dx + dy * dy
        if d2 > r2:
            break
        if d2 >= e2:
            sums[0] += 1.0
            sums[1] += dx
            sums[2] += dy
            sums[3] += dx * dx
            sums[4] += dy * dy
            sums[5] += dx * dy
            far = i
        i = _next(x, i, step, max_gap)
    return far


@nb.njit(cache=True, nogil=True, error_model="numpy")
def refine(
    x: NDArray[np.float64],
    y: NDArray[np.float64],
    rows: NDArray[np.float64],
    n_rows: int,
    cfg: KernelConfig,
    max_shift: float,
) -> None:
    """Re-estimate keypoints from longer wall fits (option ``refine_radius``, not in the paper).

    For each keypoint row: the scan point nearest to it (searched outwards from its beam),
    then on each side of that point the run of consecutive valid points (across at most
    ``max_gap`` gaps) within ``refine_radius`` of the keypoint, leaving out those closer than
    ``refine_exclude``; both runs are fitted (eqs. 2-9) and intersected (eqs. 10-13). While a
    fit's RMSE exceeds ``max_fit_rmse`` (the run reaches past the next corner) the radius is
    halved, down to ``4 * refine_exclude``. The intersection replaces the keypoint when both
    runs have ``min_points`` points and it moved at most ``max_shift``.
    """
    e2 = cfg.refine_exclude * cfg.refine_exclude
    s2 = max_shift * max_shift
    max_mse = cfg.max_fit_rmse * cfg.max_fit_rmse
    sa = np.zeros(6)
    sd = np.zeros(6)
    for m in range(n_rows):
        cx = rows[m, M_X]
        cy = rows[m, M_Y]
        rad = cfg.refine_radius
        apex = nearest(x, y, int(rows[m, M_BEAM]), cx, cy, rad * rad, cfg.max_gap_beams)
        while rad >= 4.0 * cfg.refine_exclude:
            wall_sums(x, y, apex, -1, cx, cy, rad * rad, e2, cfg.max_gap_beams, sa)
            wall_sums(x, y, apex, 1, cx, cy, rad * rad, e2, cfg.max_gap_beams, sd)
            if sa[0] < cfg.min_points or sd[0] < cfg.min_points:
                break
            ma, a0, a1, mse_a = select_from_sums(sa[0], sa[1], sa[2], sa[3], sa[4], sa[5])
            md, d0, d1, mse_d = select_from_sums(sd[0], sd[1], sd[2], sd[3], sd[4], sd[5])
            if mse_a > max_mse or mse_d > max_mse:
                rad *= 0.5
                continue
            qx, qy, ok = intersect(ma, a0, a1, md, d0, d1)
            if ok and qx * qx + qy * qy <= s2:
                rows[m, M_X] = cx + qx
                rows[m, M_Y] = cy + qy
            break


@nb.njit(cache=True, nogil=True, error_model="numpy")
def finish(
    x: NDArray[np.float64],
    y: NDArray[np.float64],
    cand: NDArray[np.float64],
    packed: NDArray[np.float64],
    rows: NDArray[np.float64],
) -> int:
    """Candidates -> keypoint rows (merged, refined as configured); returns their count.

    ``packed`` is the configuration from :func:`~laser_corners.kernel.candidates.kernel_config`.
    """
    cfg = unpack(packed)
    if cfg.merge_radius > 0.0:
        n_out = merge(cand, cfg.merge_radius, rows)
    else:
        n_out = raw_rows(cand, rows)
    if cfg.refine_radius > 0.0:
        shift = cfg.merge_radius if cfg.merge_radius > 0.0 else REFINE_MAX_SHIFT
        refine(x, y, rows, n_out, cfg, shift)
    return n_out


@nb.njit(cache=True, nogil=True, error_model="numpy")
def detect_into(
    ranges,
    cos_a,
    sin_a,
    range_min: float,
    range_max: float,
    packed: NDArray[np.float64],
    x: NDArray[np.float64],
    y: NDArray[np.float64],
    rows: NDArray[np.float64],
) -> int:
    """One scan's ranges -> keypoint rows (returns their count), handing back the scan's points
    in ``x``, ``y`` (the detector keeps them for the covariances)."""
    n_valid = polar_to_xy(ranges, cos_a, sin_a, range_min, range_max, x, y)
    enough = n_valid >= 2 * unpack(packed).min_points - 1  # else no neighbourhood pair fills
    return detect_xy(x, y, packed, rows) if enough else 0


@nb.njit(cache=True, nogil=True, error_model="numpy")
def detect_scan(
    ranges: NDArray[np.float64],
    geometry: NDArray[np.float64],
    packed: NDArray[np.float64],
    out: NDArray[np.float64],
) -> int:
    """:func:`detect_into` with four arguments (numba's dispatch cost grows with their number):
    ``geometry`` = the N cosines, the N sines, range_min, range_max; ``out`` (N ·
    :data:`OUT_PER_BEAM`) gets x (N), y (N), then the rows (NM each). Returns their count."""
    n = ranges.shape[0]
    cos_a, sin_a, limits = geometry[:n], geometry[n : 2 * n], geometry[2 * n :]
    rows = out[2 * n : 2 * n + n * NM].reshape((n, NM))
    x, y = out[:n], out[n : 2 * n]
    return detect_into(ranges, cos_a, sin_a, limits[0], limits[1], packed, x, y, rows)


# numba caches detect_xy (and the functions above and below that call it) with the phases'
# code linked in, keyed on this file alone; laser_corners.kernel_cache keys the cache folder
# by every kernel source, so an edit to neighbourhood.py, boxes.py or candidates.py is seen
@nb.njit(cache=True, nogil=True, error_model="numpy")
def detect_xy(
    x: NDArray[np.float64],
    y: NDArray[np.float64],
    packed: NDArray[np.float64],
    rows: NDArray[np.float64],
) -> int:
    """One scan's points (beam order, NaN for gaps) -> keypoint rows; returns their count."""
    cand = np.empty((x.shape[0], NC))
    candidates(x, y, packed, cand, np.empty((0, 0, 3)))
    return finish(x, y, cand, packed, rows)


@nb.njit(cache=True, parallel=True, error_model="numpy")
def detect_batch(
    ranges: NDArray[np.float64],
    geometry: NDArray[np.float64],
    packed: NDArray[np.float64],
    out: NDArray[np.float64],
    counts: NDArray[np.int64],
) -> None:
    """:func:`detect_scan` of every row of ``ranges`` into that row of ``out``, in parallel."""
    for s in nb.prange(ranges.shape[0]):
        counts[s] = detect_scan(ranges[s], geometry, packed, out[s])
