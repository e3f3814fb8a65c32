"""The detector's numba kernel: points -> per-point candidate keypoints (:func:`candidates`).

Phases, each a small ``@njit`` function composed here:

1. :func:`polar_to_xy`, then :func:`~laser_corners.kernel.neighbourhood.prepare`: gaps become NaN,
   coordinates are shifted by the scan's centroid, prefix sums of x, y, x², y², xy and of the
   valid-point count (every fit costs O(1));
2. :mod:`~laser_corners.kernel.neighbourhood`: the neighbourhood bounds of a point for every scale,
   one outward walk per side (:func:`~laser_corners.kernel.neighbourhood.counts`, 16 points at a
   time with bit masks; :func:`~laser_corners.kernel.neighbourhood.reach` with more than three
   sentinels; the block-skipping :func:`~laser_corners.kernel.neighbourhood.walk` for dense scans
   and gap bridging);
3. :func:`~laser_corners.kernel.scale_tests.screen`: a division-free necessary condition of the
   RMSE tests (eqs. 8-9) and of the angle test; scales that fail it fail the full test;
4. :func:`~laser_corners.kernel.scale_tests.full_test`: the exact per-scale test (eqs. 2-13,
   distance to p_j, opening angle);
5. :func:`~laser_corners.kernel.scale_tests.best_run`: the runs of consecutive passing scales, the
   centroid test, the winner.

A point needs ``min_consecutive_scales`` consecutive passing scales (m), so every such run
contains one of the *sentinel* scales K-m, K-2m, K-3m, ... (spaced m apart, the highest
in the last window of m scales: the walk of a point only has to reach R_{K-m}, not R_{K-1};
on the benchmark sets this is 8-21 % faster than sentinels K-1, K-1-m, ...). The
sentinels are screened first, and a point where all of them fail is done (most points of a
room lie on straight walls); only the others get every scale screened, after a second walk
to the largest scale.

The parameters reach the kernel through one conversion, :func:`kernel_config` (a packed
array), read inside the kernel as a :class:`KernelConfig` by :func:`unpack`.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numba as nb
import numpy as np
from numpy.typing import NDArray

from laser_corners.kernel.neighbourhood import (
    PAD,
    block_boxes,
    counts,
    extend,
    links,
    padded,
    points_within,
    prepare,
    reach,
    walk,
    within,
)
from laser_corners.kernel.scale_tests import best_run, full_test, keep_runs, screen
from laser_corners.params import DetectorParams

__all__ = ["KernelConfig", "candidates", "kernel_config", "polar_to_xy", "unpack"]

# columns of the per-point candidate table (float64, shape (N, NC))
C_X, C_Y, C_NSC, C_K0, C_RMSE, C_OPEN, C_ORIENT = range(7)
NC = 7


class KernelConfig(NamedTuple):
    """The detector parameters as the kernel sees them (built by :func:`unpack`)."""

    scales: NDArray[np.float64]
    min_points: int
    min_angle_deg: float
    max_angle_deg: float
    max_fit_rmse: float
    max_point_distance: float
    max_centroid_distance: float
    min_consecutive_scales: int
    min_extent_ratio: float
    max_gap_beams: int
    merge_radius: float
    refine_radius: float
    refine_exclude: float


_N_SCALARS = 12  # scalars before the scales in the packed configuration


def kernel_config(params: DetectorParams) -> NDArray[np.float64]:
    """The one conversion of :class:`~laser_corners.DetectorParams` into kernel arguments.

    A packed float64 array (the 12 scalars of :class:`KernelConfig` in order, then the
    scales): one array argument is the cheapest for numba's dispatcher to type, a tuple costs
    microseconds per call. Kernels read it with :func:`unpack`.
    """
    scalars = [
        params.min_points,
        params.min_angle_deg,
        params.max_angle_deg,
        params.max_fit_rmse,
        params.max_point_distance,
        params.max_centroid_distance,
        params.min_consecutive_scales,
        params.min_extent_ratio,
        params.max_gap_beams,
        params.merge_radius,
        params.refine_radius,
        params.refine_exclude,
    ]
    return np.array(scalars + list(params.scales), dtype=np.float64)


@nb.njit(cache=True, nogil=True, error_model="numpy")
def unpack(packed: NDArray[np.float64]) -> KernelConfig:
    """The :class:`KernelConfig` of a packed configuration from :func:`kernel_config`."""
    return KernelConfig(
        packed[_N_SCALARS:],
        int(packed[0]),
        packed[1],
        packed[2],
        packed[3],
        packed[4],
        packed[5],
        int(packed[6]),
        packed[7],
        int(packed[8]),
        packed[9],
        packed[10],
        packed[11],
    )


@nb.njit(cache=True, nogil=True, error_model="numpy")
def polar_to_xy(
    ranges: NDArray[np.float64],
    cos_a: NDArray[np.float64],
    sin_a: NDArray[np.float64],
    range_min: float,
    range_max: float,
    x: NDArray[np.float64],
    y: NDArray[np.float64],
) -> int:
    """Polar -> Cartesian in beam order; gaps (NaN, inf, <= range_min, >= range_max) -> NaN.
    Returns the number of valid points."""
    n_valid = 0
    for i in range(ranges.shape[0]):
        r = ranges[i]
        if math.isfinite(r) and r > range_min and r < range_max:
            x[i] = r * cos_a[i]
            y[i] = r * sin_a[i]
            n_valid += 1
        else:
            x[i] = math.nan
            y[i] = math.nan
    return n_valid


@nb.njit(cache=True, nogil=True, error_model="numpy")
def _limits(cfg: KernelConfig) -> tuple:
    """Derived thresholds: (full-test limits, loose screen mse, screen max cos², max cd²)."""
    max_mse = cfg.max_fit_rmse * cfg.max_fit_rmse
    limits = np.empty(4)
    limits[0] = max_mse
    limits[1] = cfg.max_point_distance * cfg.max_point_distance
    limits[2] = math.cos(math.radians(cfg.min_angle_deg))
    limits[3] = math.cos(math.radians(cfg.max_angle_deg))
    # an opening angle in [min, max] has |cos| <= max(|cos min|, |cos max|); the margin
    # keeps the screen never stricter than the exact test
    max_abs_cos = max(abs(limits[2]), abs(limits[3]))
    max_cos2 = max_abs_cos * max_abs_cos * (1.0 + 1e-9)
    max_cd2 = cfg.max_centroid_distance * cfg.max_centroid_distance
    return limits, max_mse * (1.0 + 1e-9), max_cos2, max_cd2


@nb.njit(cache=True, nogil=True, error_model="numpy")
def candidates(
    x: NDArray[np.float64],
    y: NDArray[np.float64],
    packed: NDArray[np.float64],
    cand: NDArray[np.float64],
    table: NDArray[np.float64],
) -> None:
    """Fill ``cand`` (N, NC) with each point's candidate keypoint (column C_NSC 0: none).

    ``x``, ``y`` are the scan points in beam order, NaN for gaps. When ``table`` has shape
    (N, K, 3) it also receives, per point and scale, the intersection x, y and 1.0/0.0 for
    pass/fail (NaN where no intersection was computed).
    """
    cfg = unpack(packed)
    n = x.shape[0]
    scales, n_scales = cfg.scales, cfg.scales.shape[0]
    want_table = table.shape[0] == n
    valid, ox, oy, ps = prepare(x, y)
    r2 = scales * scales
    px, py = padded(x, y, valid)
    dense, box, lk = _walk_structures(x, y, valid, px, py, scales, cfg.max_gap_beams)
    limits, loose_mse, max_cos2, max_cd2 = _limits(cfg)
    start, stop, inv, screened, passed, res = _buffers(n, n_scales)
    m, top = cfg.min_consecutive_scales, n_scales - 1
    st, r2_a, r2_b, many, rm_a, rm_d, r2_sent, s_start, s_stop = _sentinels(r2, m, n)
    n_sent = r2_sent.shape[0]
    na = nd = -1  # step counts of the walks to the top sentinel (dense: unused)
    ahead, cur = False, (0, 0, 0, 0, 0, 0)
    mp, bridging, gap = cfg.min_points, cfg.max_gap_beams > 0, cfg.max_gap_beams
    gate = (mp, loose_mse, max_cos2, want_table)
    _clear(cand, table, want_table)
    for j in range(n):
        if not valid[j]:
            continue
        if dense:  # the sentinel scales only, for now
            walk(j, -1, x, y, valid, lk, box, r2_sent, gap, s_start)
            walk(j, 1, x, y, valid, lk, box, r2_sent, gap, s_stop)
            for i in range(n_sent):
                start[st - (n_sent - 1 - i) * m] = s_start[i]
                stop[st - (n_sent - 1 - i) * m] = s_stop[i]
        else:
            if many:  # store the running maxima, for within()
                na, na_a, na_b = reach(j, -1, px, py, (r2[st], r2_a, r2_b), rm_a, True)
                nd, nd_a, nd_b = reach(j, 1, px, py, (r2[st], r2_a, r2_b), rm_d, True)
            else:  # the walks of p_j+1 now, overlapping the screens of p_j
                if not ahead:
                    cur = _walks(j, px, py, r2[st], r2_a, r2_b)
                na, na_a, na_b, nd, nd_a, nd_b = cur
                ahead = j + 1 < n and valid[j + 1]
                if ahead:
                    cur = _walks(j + 1, px, py, r2[st], r2_a, r2_b)
            for k, ca, cd in ((st, na, nd), (st - m, na_b, nd_b), (st - 2 * m, na_a, nd_a)):
                if k >= 0:
                    start[k] = j - ca
                    stop[k] = j + cd
        # every run of m consecutive scales holds one of the sentinels; a run lies between
        # two failing sentinels, so only scales within m-1 of a passing one can be in one
        hit = want_table
        for k in range(st, -1, -m):
            if not dense and k < st - 2 * m:
                start[k] = j - within(rm_a, na, r2[k])
                stop[k] = j + within(rm_d, nd, r2[k])
            screened[k] = screen(ps, inv, j, start[k], stop[k], mp, loose_mse, max_cos2, bridging)
            hit |= screened[k]
        if not hit:
            continue
        if dense:  # again, every scale
            walk(j, -1, x, y, valid, lk, box, r2, gap, start)
            walk(j, 1, x, y, valid, lk, box, r2, gap, stop)
        # the other scales' bounds (the modes of _screen_rest)
        mode = 0 if dense else (1 if many else 2)
        if mode == 1 and st < top:  # again, to the largest scale, storing the running maxima
            na = reach(j, -1, px, py, (r2[top], -1.0, -1.0), rm_a, True)[0]
            nd = reach(j, 1, px, py, (r2[top], -1.0, -1.0), rm_d, True)[0]
        rm = (rm_a, rm_d, na, nd, px, py, mode)
        _screen_rest(ps, inv, j, start, stop, screened, r2, m, st, gate, rm)
        if not want_table and not keep_runs(screened, m):
            continue
        _test_scales(x, y, ps, ox, oy, j, start, stop, screened, cfg, limits, passed, res, table)
        _store(cand, j, passed, res, cfg.min_consecutive_scales, max_cd2)


@nb.njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _walk_structures(x, y, valid, px, py, scales, max_gap_beams: int) -> tuple:
    """Which neighbourhood walk a scan gets, and its structures: (dense, boxes, links).

    Dense scans (many points within the largest scale) and gap bridging take the
    block-skipping :func:`~laser_corners.kernel.neighbourhood.walk` (block boxes,
    :mod:`~laser_corners.kernel.boxes`; its links:
    next/previous valid point and the padded points ``px``, ``py``); the others the short
    branch-free walk, counted per scale on demand.
    """
    crowded = points_within(x, y, valid, scales[scales.shape[0] - 1]) > 48.0
    dense = max_gap_beams > 0 or crowded
    # boxes in the local wall direction when crowded (tight: kernel.boxes), else axis-aligned
    box = block_boxes(x, y, valid, max_gap_beams, crowded) if dense else np.empty((1, 1, 6))
    if dense:
        next_valid, prev_valid = links(valid)
    else:
        next_valid = prev_valid = np.empty(0, dtype=np.int64)
    return dense, box, (next_valid, prev_valid, px, py)


@nb.njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _sentinels(r2, m: int, n: int) -> tuple:
    """The sentinel scales st = K-m, st - m, st - 2m, ... >= 0 and their walk buffers.

    Returns (st, r2 of the second and third sentinel from the top (-1.0: none), whether
    there are more than three, the running-maxima buffers of both walks (empty unless
    more than three), the sentinels' squared radii ascending, their start/stop buffers).
    """
    top = r2.shape[0] - 1
    st = max(top - (m - 1), 0)
    # the walk counts the top three sentinels; with more it stores the running maxima
    r2_a = r2[st - 2 * m] if st - 2 * m >= 0 else -1.0
    r2_b = r2[st - m] if st - m >= 0 else -1.0
    many = st - 3 * m >= 0
    rm_a = np.empty(n + PAD if many else 0)
    rm_d = np.empty(n + PAD if many else 0)
    n_sent = st // m + 1
    r2_sent = r2[st - (n_sent - 1) * m :: m].copy()
    s_start = np.full(n_sent, -1, dtype=np.int64)  # also the guesses of the dense walk
    s_stop = np.full(n_sent, -1, dtype=np.int64)
    return st, r2_a, r2_b, many, rm_a, rm_d, r2_sent, s_start, s_stop


@nb.njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _buffers(n: int, n_scales: int) -> tuple:
    """Per-point work buffers: start, stop (bounds per scale), 1/count table, screened,
    passed, res (per scale: ix, iy, worst rmse, opening, bisector x, y)."""
    start = np.full(n_scales, -1, dtype=np.int64)  # also the guesses of the dense walk
    stop = np.full(n_scales, -1, dtype=np.int64)
    inv = 1.0 / np.arange(n + 2)  # 1/count, a table (inv[0] = inf is never used)
    screened = np.zeros(n_scales, dtype=np.bool_)
    passed = np.zeros(n_scales, dtype=np.bool_)
    res = np.empty((n_scales, 6))
    return start, stop, inv, screened, passed, res


@nb.njit(cache=True, nogil=True, error_model="numpy")
def _clear(cand, table, want_table: bool) -> None:
    """No candidate yet at any point; with the table, no intersection (NaN) and no pass."""
    cand[:, C_NSC] = 0.0
    if want_table:
        table[:, :, 0:2] = math.nan
        table[:, :, 2] = 0.0


@nb.njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _walks(j: int, px, py, r2_max: float, r2_a: float, r2_b: float) -> tuple:
    """Both :func:`~laser_corners.kernel.neighbourhood.counts` walks of p_j: arrival, departure."""
    na, na_a, na_b = counts(j, -1, px, py, r2_max, r2_a, r2_b)
    nd, nd_a, nd_b = counts(j, 1, px, py, r2_max, r2_a, r2_b)
    return na, na_a, na_b, nd, nd_a, nd_b


@nb.njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _screen_rest(
    ps,
    inv,
    j: int,
    start,
    stop,
    screened,
    r2,
    m: int,
    st: int,
    gate: tuple,
    rm: tuple,
) -> None:
    """Screen the scales of p_j other than the sentinels (already in ``screened``).

    Every run of m consecutive scales holds a sentinel and lies between two failing ones,
    so only scales next to a passing sentinel (within m-1) can be in a run; the others are
    not screened (unless ``want_all``). ``gate`` holds min_points, loose_mse, max_cos2 and
    want_all. ``rm`` holds the running maxima (mode 1) and step
    counts of both walks, the padded coordinates and the mode: 0, the bounds are already in
    ``start``, ``stop``; 1, from the running maxima
    (:func:`~laser_corners.kernel.neighbourhood.within`); 2, from the bounds of the sentinels next
    to the scale (:func:`~laser_corners.kernel.neighbourhood.extend`).
    """
    rm_a, rm_d, na, nd, px, py, mode = rm
    min_points, loose_mse, max_cos2, want_all = gate
    top = r2.shape[0] - 1
    far = px.shape[0]  # more steps than any walk takes (it stops at the padding)
    r = st % m  # (st - k) % m, counted down with k (no division per scale)
    for k in range(top + 1):
        # the nearest sentinels above (none above st) and below k
        above = k + r if k < st else -1
        below = above - m if k < st else st
        sentinel = k <= st and r == 0
        r = r - 1 if r > 0 else m - 1
        if sentinel:
            continue
        near = want_all or (above >= 0 and screened[above]) or (below >= 0 and screened[below])
        screened[k] = False
        if not near:
            continue
        if mode == 1:
            start[k] = j - within(rm_a, na, r2[k])
            stop[k] = j + within(rm_d, nd, r2[k])
        elif mode == 2:  # between the counts of the sentinels below (or 0) and above (or none)
            lo_a = j - start[below] if below >= 0 else 0
            lo_d = stop[below] - j if below >= 0 else 0
            hi_a = j - start[above] if above >= 0 else far
            hi_d = stop[above] - j if above >= 0 else far
            start[k] = j - extend(j, -1, px, py, lo_a, hi_a, r2[k])
            stop[k] = j + extend(j, 1, px, py, lo_d, hi_d, r2[k])
        screened[k] = screen(
            ps, inv, j, start[k], stop[k], min_points, loose_mse, max_cos2, mode == 0
        )


@nb.njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _test_scales(
    x, y, ps, ox, oy, j: int, start, stop, screened, cfg: KernelConfig, limits, passed, res, table
) -> None:
    """The exact test (:func:`~laser_corners.kernel.scale_tests.full_test`) of the screened scales
    of p_j: ``passed[k]`` and ``res[k]`` (ix, iy, worst rmse, opening, bisector x, y)."""
    want_table = table.shape[0] == x.shape[0]
    for k in range(screened.shape[0]):
        passed[k] = False
        res[k, 0] = math.nan
        res[k, 1] = math.nan
        if not screened[k]:
            continue
        s = start[k]
        e = stop[k]
        if cfg.min_extent_ratio > 0.0:  # option, not in the paper: both runs must reach out
            reach2 = (cfg.min_extent_ratio * cfg.scales[k]) ** 2
            if (x[s] - x[j]) ** 2 + (y[s] - y[j]) ** 2 < reach2 or (
                (x[e] - x[j]) ** 2 + (y[e] - y[j]) ** 2 < reach2
            ):
                continue
        state, ix, iy, worst, opening, bx, by = full_test(x, y, ps, ox, oy, j, s, e, limits)
        if state == 0:
            continue
        res[k, 0] = ix
        res[k, 1] = iy
        if want_table:
            table[j, k, 0] = ix
            table[j, k, 1] = iy
        if state == 2:
            passed[k] = True
            res[k, 2] = worst
            res[k, 3] = opening
            res[k, 4] = bx
            res[k, 5] = by
            if want_table:
                table[j, k, 2] = 1.0


@nb.njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _store(cand, j, passed, res, min_consecutive, max_cd2) -> None:
    """The winning run of p_j (if any) into its candidate row."""
    k0, length, cx, cy = best_run(passed, res, min_consecutive, max_cd2)
    if length == 0:
        return
    w = 0.0
    o = 0.0
    sbx = 0.0
    sby = 0.0
    for kk in range(k0, k0 + length):
        w = max(w, res[kk, 2])
        o += res[kk, 3]
        sbx += res[kk, 4]
        sby += res[kk, 5]
    cand[j, C_X] = cx
    cand[j, C_Y] = cy
    cand[j, C_NSC] = length
    cand[j, C_K0] = k0
    cand[j, C_RMSE] = w
    cand[j, C_OPEN] = o / length
    cand[j, C_ORIENT] = math.atan2(sby, sbx)
