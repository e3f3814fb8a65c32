"""The detector's numba kernel, phase by phase: points -> per-point candidate keypoints.

Phases (each a small ``@njit`` function; numba inlines them into :func:`candidates`):

1. :func:`polar_to_xy` and :func:`prepare`: gaps become NaN, coordinates are shifted by the
   scan's centroid (smaller sums, less cancellation), prefix sums of x, y, x², y², xy and of
   the valid-point count (so every fit costs O(1)), next/previous valid index, and bounding
   boxes of aligned blocks of 8, 64, 512 and 4096 beams;
2. :func:`walk`: the neighbourhood bounds of one point for every scale in one outward walk
   per side. A block whose bounding box lies inside the current radius is skipped whole (the
   farthest box corner bounds every point's distance, in floating point too: rounding is
   monotone), so the walk costs O(blocks + points near the radii), not O(points within R);
3. :func:`screen`: a division-free necessary condition of the RMSE tests (eqs. 8-9) and of
   the angle test on the undirected lines; scales that fail it fail the full test;
4. :func:`full_test`: the exact per-scale test (eqs. 2-13, distance to p_j, opening angle);
5. :func:`best_run`: the runs of consecutive passing scales, the centroid test, the winner.

A point needs ``min_consecutive_scales`` consecutive passing scales (m), so every such run
contains one of the *sentinel* scales K-1, K-1-m, K-1-2m, ... (the larger scales: their
fits are the least noisy, so the screen rejects most wall points there). The sentinels are
screened first, and a point where all of them fail is done (most points of a room lie on
straight walls); only the others get every scale screened.

The parameters reach the kernel as one :class:`KernelConfig` made by :func:`kernel_config`.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numba as nb
import numpy as np
from numpy.typing import NDArray

from laser_corners.linefit import centred_moments, intersect, line_direction, select_from_sums
from laser_corners.params import DetectorParams

__all__ = ["KernelConfig", "candidates", "kernel_config", "polar_to_xy", "unpack"]

# columns of the per-point candidate table (float64, shape (N, NC))
C_X, C_Y, C_NSC, C_K0, C_RMSE, C_OPEN, C_ORIENT = range(7)
NC = 7
_LEVELS = 4  # block sizes 8, 64, 512, 4096 beams
_SHIFT = 3  # log2 of the block size ratio
PAD = 4  # +inf entries before and after the padded coordinates of :func:`reach`


class KernelConfig(NamedTuple):
    """The detector parameters as the kernel sees them (built by :func:`unpack`)."""

    scales: NDArray[np.float64]
    min_points: int
    min_angle_deg: float
    max_angle_deg: float
    max_fit_rmse: float
    max_point_distance: float
    max_centroid_distance: float
    min_consecutive: int
    min_extent: float
    max_gap: int
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
) -> None:
    """Polar -> Cartesian in beam order; gaps (NaN, inf, <= range_min, >= range_max) -> NaN."""
    for i in range(ranges.shape[0]):
        r = ranges[i]
        if math.isfinite(r) and r > range_min and r < range_max:
            x[i] = r * cos_a[i]
            y[i] = r * sin_a[i]
        else:
            x[i] = math.nan
            y[i] = math.nan


@nb.njit(cache=True, nogil=True, error_model="numpy")
def prepare(x: NDArray[np.float64], y: NDArray[np.float64]) -> tuple:
    """Validity, centroid, prefix sums (N+1, 6: x, y, x², y², xy, count), next/previous valid
    index (N if none / -1 if none)."""
    n = x.shape[0]
    valid = np.empty(n, dtype=np.bool_)
    ox = 0.0
    oy = 0.0
    n_valid = 0
    for i in range(n):
        ok = math.isfinite(x[i]) and math.isfinite(y[i])
        valid[i] = ok
        if ok:
            ox += x[i]
            oy += y[i]
            n_valid += 1
    if n_valid > 0:
        ox /= n_valid
        oy /= n_valid
    ps = np.zeros((n + 1, 6))  # one row per index: a neighbourhood's sums in one cache line
    for i in range(n):
        if valid[i]:
            xi = x[i] - ox
            yi = y[i] - oy
            ps[i + 1, 0] = ps[i, 0] + xi
            ps[i + 1, 1] = ps[i, 1] + yi
            ps[i + 1, 2] = ps[i, 2] + xi * xi
            ps[i + 1, 3] = ps[i, 3] + yi * yi
            ps[i + 1, 4] = ps[i, 4] + xi * yi
            ps[i + 1, 5] = ps[i, 5] + 1.0
        else:
            for c in range(6):
                ps[i + 1, c] = ps[i, c]
    next_valid = np.empty(n + 1, dtype=np.int64)
    prev_valid = np.empty(n, dtype=np.int64)
    next_valid[n] = n
    for i in range(n - 1, -1, -1):
        next_valid[i] = i if valid[i] else next_valid[i + 1]
    last = -1
    for i in range(n):
        if valid[i]:
            last = i
        prev_valid[i] = last
    return valid, ox, oy, ps, next_valid, prev_valid


@nb.njit(cache=True, nogil=True, error_model="numpy")
def block_boxes(
    x: NDArray[np.float64], y: NDArray[np.float64], valid: NDArray[np.bool_]
) -> NDArray[np.float64]:
    """Bounding boxes (xmin, xmax, ymin, ymax) of the aligned full blocks of 8**(l+1) beams,
    shape (levels, N // 8, 4); a block holding a gap gets an infinite box (never skipped)."""
    n = x.shape[0]
    nb0 = n >> _SHIFT
    box = np.empty((_LEVELS, max(nb0, 1), 4))
    for b in range(nb0):
        x0 = math.inf
        x1 = -math.inf
        y0 = math.inf
        y1 = -math.inf
        for i in range(b << _SHIFT, (b + 1) << _SHIFT):
            if not valid[i]:
                x0 = -math.inf
                x1 = math.inf
                y0 = -math.inf
                y1 = math.inf
                break
            x0 = min(x0, x[i])
            x1 = max(x1, x[i])
            y0 = min(y0, y[i])
            y1 = max(y1, y[i])
        box[0, b, 0] = x0
        box[0, b, 1] = x1
        box[0, b, 2] = y0
        box[0, b, 3] = y1
    for lev in range(1, _LEVELS):
        for b in range(n >> (_SHIFT * (lev + 1))):
            c0 = b << _SHIFT
            box[lev, b, 0] = box[lev - 1, c0, 0]
            box[lev, b, 1] = box[lev - 1, c0, 1]
            box[lev, b, 2] = box[lev - 1, c0, 2]
            box[lev, b, 3] = box[lev - 1, c0, 3]
            for c in range(c0 + 1, c0 + (1 << _SHIFT)):
                box[lev, b, 0] = min(box[lev, b, 0], box[lev - 1, c, 0])
                box[lev, b, 1] = max(box[lev, b, 1], box[lev - 1, c, 1])
                box[lev, b, 2] = min(box[lev, b, 2], box[lev - 1, c, 2])
                box[lev, b, 3] = max(box[lev, b, 3], box[lev - 1, c, 3])
    return box


@nb.njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _box_d2(box: NDArray[np.float64], lev: int, b: int, xj: float, yj: float) -> float:
    """Squared distance from (xj, yj) to the farthest corner of a block's box: an upper
    bound of the kernel's d2 of every point in the block (monotone rounding)."""
    dx = max(abs(box[lev, b, 0] - xj), abs(box[lev, b, 1] - xj))
    dy = max(abs(box[lev, b, 2] - yj), abs(box[lev, b, 3] - yj))
    return dx * dx + dy * dy


@nb.njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _skip(box: NDArray[np.float64], i: int, step: int, n: int, xj: float, yj: float,
          r2: float) -> int:  # fmt: skip
    """Size of the largest aligned block starting at ``i`` (towards ``step``) that lies
    within ``r2`` of (xj, yj), or 0."""
    edge = i if step > 0 else i + 1  # aligned block boundary at the walk's near side
    for lev in range(_LEVELS - 1, -1, -1):
        size = 1 << (_SHIFT * (lev + 1))
        if edge & (size - 1) != 0:
            continue
        b = (edge >> (_SHIFT * (lev + 1))) - (0 if step > 0 else 1)
        if b < 0 or (b + 1) * size > n:
            continue
        if _box_d2(box, lev, b, xj, yj) <= r2:
            return size
    return 0


@nb.njit(cache=True, nogil=True, error_model="numpy")
def walk(
    j: int,
    step: int,
    x: NDArray[np.float64],
    y: NDArray[np.float64],
    valid: NDArray[np.bool_],
    next_valid: NDArray[np.int64],
    prev_valid: NDArray[np.int64],
    box: NDArray[np.float64],
    r2: NDArray[np.float64],
    max_gap: int,
    bound: NDArray[np.int64],
) -> None:
    """Farthest valid index of the neighbourhood of p_j for every scale, one side.

    Walks from ``j`` towards ``step`` (-1 arrival, +1 departure) up to the first point
    farther than R_k from p_j, the first run of more than ``max_gap`` invalid beams, or the
    scan's end; ``bound[k]`` is the last valid index before that point.
    """
    n = x.shape[0]
    n_scales = r2.shape[0]
    xj = x[j]
    yj = y[j]
    k = 0
    last = j
    i = j + step
    while k < n_scales and 0 <= i < n:
        if not valid[i]:  # a run of gaps: bridge it if short and a point follows
            g = next_valid[i] if step > 0 else prev_valid[i]
            if g < 0 or g >= n or abs(g - i) >= max_gap + 1:
                break
            i = g
            continue
        size = _skip(box, i, step, n, xj, yj, r2[k])
        if size > 0:  # a whole block within R_k (and every larger scale)
            i += step * size
            last = i - step
            continue
        d2 = (x[i] - xj) ** 2 + (y[i] - yj) ** 2
        while k < n_scales and d2 > r2[k]:
            bound[k] = last
            k += 1
        last = i
        i += step
    while k < n_scales:
        bound[k] = last
        k += 1


@nb.njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _sums(ps: NDArray[np.float64], a: int, b: int) -> tuple:
    """Count and sums of x, y, x², y², xy over the valid points of indices [a, b]."""
    return (
        ps[b + 1, 5] - ps[a, 5],
        ps[b + 1, 0] - ps[a, 0],
        ps[b + 1, 1] - ps[a, 1],
        ps[b + 1, 2] - ps[a, 2],
        ps[b + 1, 3] - ps[a, 3],
        ps[b + 1, 4] - ps[a, 4],
    )


@nb.njit(cache=True, nogil=True, error_model="numpy", inline="always")
def screen(ps: NDArray[np.float64], inv: NDArray[np.float64], j: int, s: int, e: int,
           min_points: int, loose_mse: float, max_cos2: float) -> bool:  # fmt: skip
    """Necessary condition for a scale to pass, without divisions (a hair permissive).

    The RMSE tests of eqs. 8-9 as D <= max_rmse² · n · spread (D = Sxx·Syy - Sxy², spread =
    the kept model's Sxx or Syy) and |cos| of the angle between the undirected lines, whose
    directions are (Sxx, Sxy) for y|x and (Sxy, Syy) for x|y, at most ``max_cos2``.
    ``inv[c]`` is 1/c (a table: no division per call).
    """
    na, sx, sy, sxx, syy, sxy = _sums(ps, s, j)
    nd, tx, ty, txx, tyy, txy = _sums(ps, j, e)
    if na < min_points or nd < min_points:
        return False
    axx, ayy, axy = centred_moments(inv[int(na)], sx, sy, sxx, syy, sxy)
    dxx, dyy, dxy = centred_moments(inv[int(nd)], tx, ty, txx, tyy, txy)
    a_yx = axx >= ayy
    d_yx = dxx >= dyy
    a_spread = axx if a_yx else ayy
    d_spread = dxx if d_yx else dyy
    va_x = axx if a_yx else axy
    va_y = axy if a_yx else ayy
    vd_x = dxx if d_yx else dxy
    vd_y = dxy if d_yx else dyy
    dot = va_x * vd_x + va_y * vd_y
    return (
        (axx * ayy - axy * axy <= loose_mse * na * a_spread)
        & (dxx * dyy - dxy * dxy <= loose_mse * nd * d_spread)
        & (dot * dot <= max_cos2 * (va_x * va_x + va_y * va_y) * (vd_x * vd_x + vd_y * vd_y))
    )


@nb.njit(cache=True, nogil=True, error_model="numpy")
def full_test(
    x: NDArray[np.float64],
    y: NDArray[np.float64],
    ps: NDArray[np.float64],
    ox: float,
    oy: float,
    j: int,
    s: int,
    e: int,
    limits: NDArray[np.float64],
) -> tuple:
    """The exact test of one scale: ``(state, ix, iy, worst_rmse, opening_deg, bx, by)``.

    ``state`` is 0 without an intersection, 1 when the lines intersect at (ix, iy) but a test
    fails, 2 when the scale passes; (bx, by) is the unit bisector of the opening.
    ``limits``: max squared RMSE, max squared point distance, cos of the min and max angle.
    """
    fail = (0, math.nan, math.nan, 0.0, 0.0, 0.0, 0.0)
    max_mse = limits[0]
    # arrival neighbourhood [s, j], departure [j, e]: sums from prefix sums
    ma, a0, a1, mse_a = select_from_sums(*_sums(ps, s, j))
    md, d0, d1, mse_d = select_from_sums(*_sums(ps, j, e))
    if mse_a > max_mse or mse_d > max_mse:  # eqs. 8-9, exact
        return fail
    ix, iy, ok = intersect(ma, a0, a1, md, d0, d1)  # eqs. 10-13
    if not ok:
        return fail
    ix += ox
    iy += oy
    xj = x[j]
    yj = y[j]
    if (ix - xj) ** 2 + (iy - yj) ** 2 > limits[1]:
        return (1, ix, iy, 0.0, 0.0, 0.0, 0.0)
    # opening angle between the lines, each directed from the corner towards the far end of
    # its neighbourhood
    ua_x, ua_y = line_direction(ma, a1)
    ud_x, ud_y = line_direction(md, d1)
    if ua_x * (x[s] - ix) + ua_y * (y[s] - iy) < 0.0:
        ua_x = -ua_x
        ua_y = -ua_y
    if ud_x * (x[e] - ix) + ud_y * (y[e] - iy) < 0.0:
        ud_x = -ud_x
        ud_y = -ud_y
    cos_open = min(1.0, max(-1.0, ua_x * ud_x + ua_y * ud_y))
    # angle in [min, max] <=> cos in [cos max, cos min] (cos decreases on [0, 180])
    if cos_open > limits[2] or cos_open < limits[3]:
        return (1, ix, iy, 0.0, 0.0, 0.0, 0.0)
    bx = ua_x + ud_x
    by = ua_y + ud_y
    norm = math.sqrt(bx * bx + by * by)
    bx = bx / norm if norm > 0.0 else 0.0
    by = by / norm if norm > 0.0 else 0.0
    worst = math.sqrt(max(mse_a, mse_d))
    return (2, ix, iy, worst, math.degrees(math.acos(cos_open)), bx, by)


@nb.njit(cache=True, nogil=True, error_model="numpy")
def best_run(passed: NDArray[np.bool_], q: NDArray[np.float64], min_consecutive: int,
             max_cd2: float) -> tuple:  # fmt: skip
    """The winning run of consecutive passing scales: ``(k0, length, cx, cy)``.

    The longest run of at least ``min_consecutive`` scales whose intersections ``q[k, :2]``
    all lie within sqrt(``max_cd2``) of their centroid; ties go to the run of smaller scales.
    ``length`` is 0 when there is none.
    """
    n_scales = passed.shape[0]
    best_len = 0
    best_k0 = -1
    best_cx = 0.0
    best_cy = 0.0
    k = 0
    while k < n_scales:
        if not passed[k]:
            k += 1
            continue
        k0 = k
        while k < n_scales and passed[k]:
            k += 1
        run = k - k0
        if run < min_consecutive or run <= best_len:
            continue
        cx = 0.0
        cy = 0.0
        for kk in range(k0, k):
            cx += q[kk, 0]
            cy += q[kk, 1]
        cx /= run
        cy /= run
        compact = True
        for kk in range(k0, k):
            if (q[kk, 0] - cx) ** 2 + (q[kk, 1] - cy) ** 2 > max_cd2:
                compact = False
                break
        if compact:
            best_len = run
            best_k0 = k0
            best_cx = cx
            best_cy = cy
    return best_k0, best_len, best_cx, best_cy


@nb.njit(cache=True, nogil=True, error_model="numpy")
def padded(x: NDArray[np.float64], valid: NDArray[np.bool_]) -> NDArray[np.float64]:
    """``x`` with gaps and :data:`PAD` entries before and after set to +inf (far from all)."""
    n = x.shape[0]
    out = np.full(n + 2 * PAD, math.inf)
    for i in range(n):
        if valid[i]:
            out[i + PAD] = x[i]
    return out


@nb.njit(cache=True, nogil=True, error_model="numpy")
def reach(j: int, step: int, px: NDArray[np.float64], py: NDArray[np.float64],
          r2_max: float, running_max: NDArray[np.float64], r2_a: float, r2_b: float,
          r2_c: float) -> tuple:  # fmt: skip
    """Walk from p_j towards ``step`` up to the largest scale, point by point.

    Stores the running maximum of the squared distance to p_j per step (a gap, or the scan's
    end, is infinitely far: ``px``, ``py`` from :func:`padded`) until it exceeds ``r2_max``
    and returns the number of steps within, and the numbers of leading steps within
    sqrt(``r2_a``), sqrt(``r2_b``), sqrt(``r2_c``) (three sentinel scales, counted on the way).
    Four steps per iteration, whose running maxima are all computed from the previous one (a
    short dependency chain, no branch per point). For dense scans :func:`walk` (block
    skipping) is used instead.
    """
    c = j + PAD
    xj = px[c]
    yj = py[c]
    i = c + step
    m = 0.0
    steps = 0
    ca = 0
    cb = 0
    cc = 0
    while True:
        d0 = (px[i] - xj) ** 2 + (py[i] - yj) ** 2
        d1 = (px[i + step] - xj) ** 2 + (py[i + step] - yj) ** 2
        d2 = (px[i + 2 * step] - xj) ** 2 + (py[i + 2 * step] - yj) ** 2
        d3 = (px[i + 3 * step] - xj) ** 2 + (py[i + 3 * step] - yj) ** 2
        d01 = max(d0, d1)
        d012 = max(d01, d2)
        m0 = max(m, d0)
        m1 = max(m, d01)
        m2 = max(m, d012)
        m3 = max(m, max(d012, d3))
        running_max[steps] = m0
        running_max[steps + 1] = m1
        running_max[steps + 2] = m2
        running_max[steps + 3] = m3
        ca += int(m0 <= r2_a) + int(m1 <= r2_a) + int(m2 <= r2_a) + int(m3 <= r2_a)
        cb += int(m0 <= r2_b) + int(m1 <= r2_b) + int(m2 <= r2_b) + int(m3 <= r2_b)
        cc += int(m0 <= r2_c) + int(m1 <= r2_c) + int(m2 <= r2_c) + int(m3 <= r2_c)
        if m3 > r2_max:
            last = int(m0 <= r2_max) + int(m1 <= r2_max) + int(m2 <= r2_max)
            return steps + last, ca, cb, cc
        m = m3
        steps += 4
        i += 4 * step


@nb.njit(cache=True, nogil=True, error_model="numpy", inline="always")
def within(running_max: NDArray[np.float64], steps: int, r2: float) -> int:
    """Number of leading steps of a :func:`reach` walk within sqrt(``r2``): a branch-free
    binary search (the running maximum is non-decreasing)."""
    lo = 0
    size = steps
    while size > 0:
        half = size >> 1
        ok = int(running_max[lo + half] <= r2)  # arithmetic, not a branch
        lo += (half + 1) * ok
        size = half - (2 * half + 1 - size) * ok
    return lo


@nb.njit(cache=True, nogil=True, error_model="numpy")
def keep_runs(screened: NDArray[np.bool_], m: int) -> bool:
    """Clear screened scales outside a screened run of at least ``m``; True if any is left."""
    n_scales = screened.shape[0]
    k = 0
    any_run = False
    while k < n_scales:
        k0 = k
        while k < n_scales and screened[k]:
            k += 1
        if 0 < k - k0 < m:
            screened[k0:k] = False
        any_run |= k - k0 >= m
        k += 1
    return any_run


@nb.njit(cache=True, nogil=True, error_model="numpy")
def _points_within(x, y, valid, radius: float) -> float:
    """Estimated number of points within ``radius`` along the scan: radius / mean step."""
    total = 0.0
    count = 0
    for i in range(x.shape[0] - 1):
        if valid[i] and valid[i + 1]:
            total += abs(x[i + 1] - x[i]) + abs(y[i + 1] - y[i])  # L1: a rough estimate
            count += 1
    return radius * count / total if total > 0.0 else 0.0


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
    scales = cfg.scales
    n_scales = scales.shape[0]
    want_table = table.shape[0] == n
    valid, ox, oy, ps, next_valid, prev_valid = prepare(x, y)
    r2 = scales * scales
    # dense scans (many points within the largest scale) and gap bridging: block-skipping
    # walk; otherwise the short branch-free walk, counted per scale on demand
    dense = cfg.max_gap > 0 or _points_within(x, y, valid, scales[n_scales - 1]) > 48.0
    box = block_boxes(x, y, valid) if dense else np.empty((_LEVELS, 1, 4))
    limits, loose_mse, max_cos2, max_cd2 = _limits(cfg)
    start = np.empty(n_scales, dtype=np.int64)
    stop = np.empty(n_scales, dtype=np.int64)
    inv = np.empty(n + 2)
    inv[0] = 0.0
    for c in range(1, n + 2):
        inv[c] = 1.0 / c
    px = padded(x, valid)
    py = padded(y, valid)
    rm_a = np.empty(n + PAD)
    rm_d = np.empty(n + PAD)
    screened = np.zeros(n_scales, dtype=np.bool_)
    passed = np.zeros(n_scales, dtype=np.bool_)
    res = np.empty((n_scales, 6))  # per scale: ix, iy, worst rmse, opening, bx, by
    m = cfg.min_consecutive
    first = (n_scales - 1) % m  # sentinels: first, first + m, ..., n_scales - 1
    sa = r2[first]  # the first three sentinels' squared radii (-1: no such scale, count 0)
    sb = r2[first + m] if first + m < n_scales else -1.0
    sc = r2[first + 2 * m] if first + 2 * m < n_scales else -1.0
    for j in range(n):
        cand[j, C_NSC] = 0.0
        if want_table:
            table[j, :, 0:2] = math.nan
            table[j, :, 2] = 0.0
        if not valid[j]:
            continue
        if dense:
            walk(j, -1, x, y, valid, next_valid, prev_valid, box, r2, cfg.max_gap, start)
            walk(j, 1, x, y, valid, next_valid, prev_valid, box, r2, cfg.max_gap, stop)
        else:  # counting the first three sentinels on the way
            steps_a, a0, a1, a2 = reach(j, -1, px, py, r2[n_scales - 1], rm_a, sa, sb, sc)
            steps_d, d0, d1, d2 = reach(j, 1, px, py, r2[n_scales - 1], rm_d, sa, sb, sc)
            start[first] = j - a0
            stop[first] = j + d0
            if first + m < n_scales:
                start[first + m] = j - a1
                stop[first + m] = j + d1
            if first + 2 * m < n_scales:
                start[first + 2 * m] = j - a2
                stop[first + 2 * m] = j + d2
        # every run of m consecutive scales holds one of the sentinels
        hit = want_table
        for k in range(first, n_scales, m):
            if hit:
                break
            if not dense and k > first + 2 * m:
                start[k] = j - within(rm_a, steps_a, r2[k])
                stop[k] = j + within(rm_d, steps_d, r2[k])
            hit = screen(ps, inv, j, start[k], stop[k], cfg.min_points, loose_mse, max_cos2)
        if not hit:
            continue
        for k in range(n_scales):
            if not dense:
                start[k] = j - within(rm_a, steps_a, r2[k])
                stop[k] = j + within(rm_d, steps_d, r2[k])
            screened[k] = screen(ps, inv, j, start[k], stop[k], cfg.min_points, loose_mse, max_cos2)
        if not want_table and not keep_runs(screened, m):
            continue
        for k in range(n_scales):
            passed[k] = False
            res[k, 0] = math.nan
            res[k, 1] = math.nan
            if not screened[k]:
                continue
            s = start[k]
            e = stop[k]
            if cfg.min_extent > 0.0:  # option, not in the paper: both runs must reach out
                reach2 = (cfg.min_extent * scales[k]) ** 2
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
        _store(cand, j, passed, res, cfg.min_consecutive, max_cd2)


@nb.njit(cache=True, nogil=True, error_model="numpy")
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
