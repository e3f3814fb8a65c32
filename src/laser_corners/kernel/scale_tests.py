"""The tests of one point at one scale: a division-free screen and the exact test.

:func:`screen` is a necessary condition of the RMSE tests (eqs. 8-9) and of the angle test,
a hair permissive; :func:`full_test` is the paper's test exactly: both line fits from the
prefix sums (eqs. 2-9), their intersection (eqs. 10-13), its distance to p_j and the
directed opening angle. :func:`best_run` picks a point's run of consecutive passing scales
and :func:`keep_runs` tells whether the screened scales can still hold one.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np
from numpy.typing import NDArray

from laser_corners.kernel.linefit import (
    centred_moments,
    intersect,
    line_direction,
    select_from_sums,
)
from laser_corners.kernel.neighbourhood import ROW

__all__ = ["best_run", "full_test", "keep_runs", "screen"]


@nb.njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _sums(ps: NDArray[np.float64], a: int, b: int) -> tuple:
    """Count and sums of x, y, x², y², xy over the valid points of indices [a, b]."""
    lo = ROW * a  # the flat layout of neighbourhood.prepare
    hi = ROW * (b + 1)
    return (  # unsigned indices: no wrap-around code per access (a >= 0)
        ps[np.uint64(hi + 5)] - ps[np.uint64(lo + 5)],
        ps[np.uint64(hi)] - ps[np.uint64(lo)],
        ps[np.uint64(hi + 1)] - ps[np.uint64(lo + 1)],
        ps[np.uint64(hi + 2)] - ps[np.uint64(lo + 2)],
        ps[np.uint64(hi + 3)] - ps[np.uint64(lo + 3)],
        ps[np.uint64(hi + 4)] - ps[np.uint64(lo + 4)],
    )


@nb.njit(cache=True, nogil=True, error_model="numpy", inline="always")
def screen(
    ps: NDArray[np.float64],
    inv: NDArray[np.float64],
    j: int,
    s: int,
    e: int,
    min_points: int,
    loose_mse: float,
    max_cos2: float,
    bridged: bool,
) -> bool:
    """Necessary condition for a scale to pass, without divisions (a hair permissive).

    The RMSE tests of eqs. 8-9 as D <= max_rmse² · n · spread (D = Sxx·Syy - Sxy², spread =
    the kept model's Sxx or Syy) and |cos| of the angle between the undirected lines, whose
    directions are (Sxx, Sxy) for y|x and (Sxy, Syy) for x|y, at most ``max_cos2``.
    ``inv[c]`` is 1/c (a table: no division per call). Without gap bridging (``bridged``
    False) a neighbourhood holds no gap, so its point count is its index span (no loads,
    no conversion); with it, the count comes from the prefix sums.
    """
    if bridged:
        na = int(_sums(ps, s, j)[0])
        nd = int(_sums(ps, j, e)[0])
    else:
        na = j - s + 1
        nd = e - j + 1
    if na < min_points or nd < min_points:
        return False
    _, sx, sy, sxx, syy, sxy = _sums(ps, s, j)
    _, tx, ty, txx, tyy, txy = _sums(ps, j, e)
    axx, ayy, axy = centred_moments(inv[na], sx, sy, sxx, syy, sxy)
    dxx, dyy, dxy = centred_moments(inv[nd], tx, ty, txx, tyy, txy)
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


@nb.njit(cache=True, nogil=True, error_model="numpy", inline="always")
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
def best_run(
    passed: NDArray[np.bool_], q: NDArray[np.float64], min_consecutive: int, max_cd2: float
) -> tuple:
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
