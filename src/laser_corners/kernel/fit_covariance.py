"""Covariance of the closed-form line fits (eqs. 2-9) and of their intersection (eqs. 10-13).

The building blocks of :mod:`laser_corners.kernel.covariance` (steps 1-2 of its docstring): for one
neighbourhood, the residual variance of the kept model gives the covariance of the line
parameters; through the Jacobian of the intersection, the covariance of a scale's keypoint.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np
from numpy.typing import NDArray

from laser_corners.noise import second_difference_sigma

__all__ = [
    "centred_sums",
    "fit_terms",
    "line_fit_covariance",
    "noise_floor",
    "pair_covariance",
    "scale_covariance",
    "scan_range_noise",
]


@nb.njit(cache=True, nogil=True, error_model="numpy")
def fit_terms(
    n: float, sx: float, sy: float, sxx: float, syy: float, sxy: float
) -> tuple[bool, float, float, float, float, float, float]:
    """Kept model of a neighbourhood (as ``select_from_sums``) with its variance terms.

    Returns ``(y_on_x, c0, c1, s2, v_mean, s_vv, n)``: intercept and slope of the kept
    model u = c0 + c1·v, residual variance s² = SSE/(n-2) (eqs. 8-9), mean and centred
    spread of the independent variable v.
    """
    inv = 1.0 / n
    dxx = sxx - sx * sx * inv
    dyy = syy - sy * sy * inv
    dxy = sxy - sx * sy * inv
    det = max(dxx * dyy - dxy * dxy, 0.0)
    y_on_x = dxx >= dyy
    spread = dxx if y_on_x else dyy
    slope = dxy / spread  # eq. 3 / eq. 6
    if y_on_x:
        c0 = (sy - slope * sx) * inv  # eq. 4
        v_mean = sx * inv
    else:
        c0 = (sx - slope * sy) * inv  # eq. 7
        v_mean = sy * inv
    sse = det / spread  # eq. 8 / eq. 9 times n
    s2 = sse / (n - 2.0) if n > 2.0 else 0.0
    return y_on_x, c0, slope, s2, v_mean, spread, n


@nb.njit(cache=True, nogil=True, error_model="numpy")
def line_fit_covariance(
    n: float, v_mean: float, s_vv: float, s2: float
) -> tuple[float, float, float]:
    """Covariance of (c0, c1) of a least-squares line u = c0 + c1·v.

    Returns ``(var_c0, cov_c0_c1, var_c1)`` for ``n`` points with mean ``v_mean`` and centred
    spread ``s_vv`` of v and residual variance ``s2``.
    """
    return s2 * (1.0 / n + v_mean * v_mean / s_vv), -s2 * v_mean / s_vv, s2 / s_vv


@nb.njit(cache=True, nogil=True, error_model="numpy")
def centred_sums(
    x: NDArray[np.float64], y: NDArray[np.float64], lo: int, hi: int, cx: float, cy: float
) -> tuple[float, float, float, float, float, float]:
    """n, Σx, Σy, Σx², Σy², Σxy of the valid points lo..hi (inclusive; dropped beams, NaN,
    are skipped) relative to (cx, cy)."""
    n = 0.0
    sx = sy = sxx = syy = sxy = 0.0
    for i in range(lo, hi + 1):
        dx = x[i] - cx
        dy = y[i] - cy
        if not math.isfinite(dx):
            continue
        n += 1.0
        sx += dx
        sy += dy
        sxx += dx * dx
        syy += dy * dy
        sxy += dx * dy
    return n, sx, sy, sxx, syy, sxy


@nb.njit(cache=True, nogil=True, error_model="numpy")
def scale_covariance(
    x: NDArray[np.float64],
    y: NDArray[np.float64],
    s: int,
    j: int,
    e: int,
    cx: float,
    cy: float,
    sigma2: float,
    out: NDArray[np.float64],
) -> bool:
    """Covariance of the intersection of the fits of [s, j] and [j, e] (step 2); adds to out."""
    sa = centred_sums(x, y, s, j, cx, cy)
    sd = centred_sums(x, y, j, e, cx, cy)
    return pair_covariance(sa, sd, x[s], y[s], x[e], y[e], sigma2, out)


@nb.njit(cache=True, nogil=True, error_model="numpy")
def pair_covariance(
    sa: tuple[float, float, float, float, float, float],
    sd: tuple[float, float, float, float, float, float],
    pax: float,
    pay: float,
    pdx: float,
    pdy: float,
    sigma2: float,
    out: NDArray[np.float64],
) -> bool:
    """Step 2 for two neighbourhoods given by their sums (relative to the keypoint) and one
    point of each (for the incidence angle of the noise floor); adds to ``out``."""
    ya, a0, a1, s2a, va, sva, na = fit_terms(sa[0], sa[1], sa[2], sa[3], sa[4], sa[5])
    yd, d0, d1, s2d, vd, svd, nd = fit_terms(sd[0], sd[1], sd[2], sd[3], sd[4], sd[5])
    if not (sva > 0.0 and svd > 0.0):
        return False
    s2a = max(s2a, noise_floor(pax, pay, ya, a1, sigma2))
    s2d = max(s2d, noise_floor(pdx, pdy, yd, d1, sigma2))
    # gradients of f = u - c0 - c1 v with respect to q = (x, y)
    fa_x, fa_y = (-a1, 1.0) if ya else (1.0, -a1)
    fd_x, fd_y = (-d1, 1.0) if yd else (1.0, -d1)
    det = fa_x * fd_y - fa_y * fd_x
    if det == 0.0:
        return False
    # intersection (eqs. 10-13, in the frame centred on the keypoint)
    ra = a0  # f_a(q) = 0  <=>  fa · q = c0 (up to sign conventions below)
    rd = d0
    qx = (fd_y * ra - fa_y * rd) / det
    qy = (-fd_x * ra + fa_x * rd) / det
    # columns of F^-1
    g_ax, g_ay = fd_y / det, -fd_x / det
    g_dx, g_dy = -fa_y / det, fa_x / det
    v_a = qx if ya else qy
    v_d = qx if yd else qy
    var_a = s2a * (1.0 / na + (v_a - va) ** 2 / sva)
    var_d = s2d * (1.0 / nd + (v_d - vd) ** 2 / svd)
    out[0] += var_a * g_ax * g_ax + var_d * g_dx * g_dx
    out[1] += var_a * g_ax * g_ay + var_d * g_dx * g_dy
    out[2] += var_a * g_ay * g_ay + var_d * g_dy * g_dy
    return True


@nb.njit(cache=True, nogil=True, error_model="numpy")
def noise_floor(px: float, py: float, y_on_x: bool, c1: float, sigma2: float) -> float:
    """Residual variance (in u) that range noise sigma2 alone causes on this line.

    Range noise moves a point along its beam; its component along the line's normal is
    σ·cos ψ (ψ = incidence angle), which is σ·cos ψ·√(1 + c1²) along u.
    """
    nx, ny = (-c1, 1.0) if y_on_x else (1.0, -c1)
    norm2 = nx * nx + ny * ny
    b2 = px * px + py * py
    if b2 == 0.0:
        return 0.0
    cos2 = (nx * px + ny * py) ** 2 / (norm2 * b2)
    return sigma2 * cos2 * norm2


@nb.njit(cache=True, nogil=True, error_model="numpy")
def scan_range_noise(x: NDArray[np.float64], y: NDArray[np.float64], max_jump: float) -> float:
    """Range-noise sigma of a scan given as points (NaN: a gap): the estimator of
    :func:`laser_corners.noise.estimate_range_noise` on the points' ranges."""
    return second_difference_sigma(np.sqrt(x * x + y * y), max_jump)
