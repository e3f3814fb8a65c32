"""Keypoint covariance: residual variance of the line fits propagated through the intersection.

For a keypoint found at scan point p_j with the winning run of scales k0 .. k0+n-1 (see
:mod:`laser_corners.detector`), every scale's arrival and departure neighbourhoods are
re-fitted with the model the detector kept (eqs. 2-9) and intersected (eqs. 10-13):

1. **Line parameters.** For the kept model u = c0 + c1·v (u = y, v = x for y|x, eqs. 2-4;
   u = x, v = y for x|y, eqs. 5-7) with n points, centred spread S_vv = Σ(v - v̄)² and residual
   variance s² = SSE / (n - 2) (SSE from eqs. 8-9), ordinary least squares gives
   Var(c1) = s²/S_vv, Var(c0) = s²(1/n + v̄²/S_vv), Cov(c0, c1) = -s² v̄/S_vv.
2. **Intersection.** The keypoint q solves f_a(q) = f_b(q) = 0 with f = u - c0 - c1·v. Its
   Jacobian with respect to (c0, c1) of line l is the l-th column g_l of F⁻¹ (F = the 2x2
   matrix of the gradients ∂f/∂q of both lines) times (1, v_l(q)); this is the derivative of
   the closed forms of eqs. 10-13 for every combination of models. Since (1, v)·Cov(c0, c1)·
   (1, v)ᵀ = s²(1/n + (v - v̄)²/S_vv) is the variance of the fitted line at v, the covariance
   of one scale's intersection is Σ_l s_l²(1/n_l + (v_l(q) - v̄_l)²/S_vv,l) · g_l g_lᵀ (the
   two fits share only p_j and are treated as independent).
3. **Across scales.** The keypoint is the centroid of the run's intersections; they come from
   nested neighbourhoods that share most of their points, so they are strongly correlated. We
   take the *mean* of the per-scale covariances (the covariance of the centroid when the
   intersections are fully correlated), not the mean divided by the count, times
   :data:`SCALE_RUN_FACTOR`.
4. **Apex sampling.** Range noise does not explain everything: the apex lies between two
   beams, the point p_j sits on one wall or the other and the neighbourhoods next to it
   straddle the corner, which moves the intersection by a fraction of the beam spacing even
   without noise. We add an isotropic term ``apex_factor² · (ρ·Δθ)² / 12`` (ρ = the keypoint's
   range, Δθ the angular increment, ρ·Δθ the beam spacing at the corner: the variance of a
   uniform position over one spacing, scaled) plus ``floor²`` (default 1 mm), so that the
   covariance is never singular, also at zero noise.
5. **Refined keypoints** (option ``refine_radius``): the covariance of step 2 for the two wall
   runs the refinement fits (same runs and radius halving as ``detector._refine``) replaces
   steps 1-3; keypoints whose runs are too short fall back to the run of scales.

Range noise lower bound: the RMSE gates (eqs. 8-9) keep fits whose residuals are small, so
each fit's residual variance is floored at what the scan's range noise alone gives on that
line (:func:`scan_range_noise`, projected on the line's normal by the incidence angle).

Constants calibrated by ``benchmarks/covariance_study.py`` (Monte Carlo, ``docs/matching.md``).
Cost: O(M·K·n) for M keypoints, K scales and n points per neighbourhood (sums taken around the
keypoint, well conditioned); 2-5 µs per keypoint, 10-20 µs per 1081-beam scan
(``benchmarks/bench_detector.py``). The detector does not compute it in ``detect``: it
hands the keypoints a :class:`DeferredCovariances`, called on the first access of
``Keypoints.cov``.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np
from numpy.typing import NDArray

from laser_corners.kernel.candidates import polar_to_xy, unpack
from laser_corners.kernel.fit_covariance import (
    fit_terms,
    line_fit_covariance,
    pair_covariance,
    scale_covariance,
    scan_range_noise,
)
from laser_corners.kernel.merge import nearest, wall_sums

__all__ = [
    "APEX_FACTOR",
    "COV_FLOOR",
    "SCALE_RUN_FACTOR",
    "DeferredCovariances",
    "DeferredScanCovariances",
    "keypoint_covariances",
    "line_fit_covariance",
    "scan_range_noise",
]

APEX_FACTOR = 0.25
"""Scale of the apex-sampling standard deviation ρ·Δθ/√12 (step 4, calibrated)."""
COV_FLOOR = 0.001
"""Isotropic floor, standard deviation in metres, added to every keypoint covariance (step 4)."""
SCALE_RUN_FACTOR = 2.0
"""Inflation of the run-of-scales covariance (step 3; not for refined keypoints), calibrated:
the merge keeps the candidate with the lowest RMSE and the gates keep fits whose residuals
happen to be small, so the fits' own residual variance under-states the keypoint's error."""


@nb.njit(cache=True, nogil=True, error_model="numpy")
def _bound(
    x: NDArray[np.float64], y: NDArray[np.float64], j: int, step: int, r2: float, max_gap: int
) -> int:
    """Last index of the run of valid points from p_j within sqrt(r2) of it, stepping over at
    most ``max_gap`` dropped beams (the detector's neighbourhood rule)."""
    n = x.shape[0]
    xj, yj = x[j], y[j]
    last = j
    gaps = 0
    i = j + step
    while 0 <= i < n:
        if math.isfinite(x[i]):
            if (x[i] - xj) ** 2 + (y[i] - yj) ** 2 > r2:
                break
            last = i
            gaps = 0
        else:
            gaps += 1
            if gaps > max_gap:
                break
        i += step
    return last


@nb.njit(cache=True, nogil=True, error_model="numpy")
def _refined_covariance(
    x: NDArray[np.float64],
    y: NDArray[np.float64],
    cx: float,
    cy: float,
    beam: int,
    radius: float,
    exclude: float,
    min_points: int,
    max_rmse: float,
    sigma2: float,
    max_gap: int,
    out: NDArray[np.float64],
) -> bool:
    """Step 2 for a keypoint refined from longer wall runs (option ``refine_radius``): the
    runs of :func:`~laser_corners.kernel.merge.refine` around the keypoint, with its radius
    halving."""
    apex = nearest(x, y, beam, cx, cy, radius * radius, max_gap)
    rad = radius
    e2 = exclude * exclude
    sa = np.zeros(6)
    sd = np.zeros(6)
    while rad >= 4.0 * exclude:
        end_a = wall_sums(x, y, apex, -1, cx, cy, rad * rad, e2, max_gap, sa)
        end_d = wall_sums(x, y, apex, 1, cx, cy, rad * rad, e2, max_gap, sd)
        if sa[0] < max(min_points, 3) or sd[0] < max(min_points, 3):
            return False
        fa = fit_terms(sa[0], sa[1], sa[2], sa[3], sa[4], sa[5])
        fd = fit_terms(sd[0], sd[1], sd[2], sd[3], sd[4], sd[5])
        mse_a = fa[3] * (fa[6] - 2.0) / fa[6]  # eqs. 8-9: SSE / n
        mse_d = fd[3] * (fd[6] - 2.0) / fd[6]
        if mse_a > max_rmse * max_rmse or mse_d > max_rmse * max_rmse:
            rad *= 0.5
            continue
        return pair_covariance(sa, sd, x[end_a], y[end_a], x[end_d], y[end_d], sigma2, out)
    return False


def keypoint_covariances(
    x: NDArray[np.float64],
    y: NDArray[np.float64],
    xy: NDArray[np.float64],
    beam_index: NDArray[np.int64],
    scale_index: NDArray[np.int64],
    n_scales: NDArray[np.int64],
    angle_increment: float,
    config: NDArray[np.float64],
    apex_factor: float = APEX_FACTOR,
    floor: float = COV_FLOOR,
    run_factor: float = SCALE_RUN_FACTOR,
) -> NDArray[np.float64]:
    """Covariance (M, 2, 2) of every keypoint (module docstring, steps 1-4).

    Parameters
    ----------
    x, y : ndarray, shape (N,)
        Scan points in beam order, NaN for gaps (sensor frame).
    xy : ndarray, shape (M, 2)
        Keypoints.
    beam_index, scale_index, n_scales : ndarray, shape (M,)
        Supporting point p_j, first scale k0 and length of the winning run of each keypoint.
    angle_increment : float
        Beam spacing, radians.
    config : ndarray
        The detector's parameters from :func:`~laser_corners.kernel.candidates.kernel_config`: the
        radii R_k (``scales``), ``max_gap_beams`` (the wall runs step over that many dropped
        beams) and the refinement options: when ``refine_radius > 0`` a keypoint's
        covariance comes from the two wall runs the refinement fits (the keypoint is their
        intersection; ``refine_exclude``, ``min_points``, ``max_fit_rmse``), falling back to
        the run of scales when those runs are too short.
    apex_factor, floor, run_factor : float
        Apex-sampling scale, isotropic floor (metres) and run-of-scales inflation, see
        :data:`APEX_FACTOR`, :data:`COV_FLOOR`, :data:`SCALE_RUN_FACTOR`.
    """
    cfg = unpack.py_func(config)  # read in Python: unpacked inside numba it cost 10x more
    keypoints = (xy, beam_index, scale_index, n_scales)
    return _covariances(
        x,
        y,
        keypoints,
        cfg.scales,
        angle_increment,
        apex_factor,
        floor,
        run_factor,
        cfg.refine_radius,
        cfg.refine_exclude,
        cfg.min_points,
        cfg.max_fit_rmse,
        cfg.max_gap_beams,
    )


@nb.njit(cache=True, nogil=True, error_model="numpy")
def _covariances(
    x: NDArray[np.float64],
    y: NDArray[np.float64],
    keypoints: tuple,
    scales: NDArray[np.float64],
    angle_increment: float,
    apex_factor: float,
    floor: float,
    run_factor: float,
    refine_radius: float,
    refine_exclude: float,
    min_points: int,
    max_rmse: float,
    max_gap: int,
) -> NDArray[np.float64]:
    """:func:`keypoint_covariances` on the unpacked parameters; ``keypoints``: their xy,
    beam_index, scale_index and n_scales."""
    xy, beam_index, scale_index, n_scales = keypoints
    m = xy.shape[0]
    cov = np.zeros((m, 2, 2))
    acc = np.zeros(3)
    dth = abs(angle_increment)
    sigma = scan_range_noise(x, y, 0.2) if m > 0 else 0.0
    sigma2 = sigma * sigma
    for t in range(m):
        cx = xy[t, 0]
        cy = xy[t, 1]
        j = beam_index[t]
        acc[:] = 0.0
        used = 0
        scale_factor = 1.0
        if refine_radius > 0.0 and 0 <= j < x.shape[0] and math.isfinite(x[j]):
            used = int(
                _refined_covariance(
                    x,
                    y,
                    cx,
                    cy,
                    j,
                    refine_radius,
                    refine_exclude,
                    min_points,
                    max_rmse,
                    sigma2,
                    max_gap,
                    acc,
                )
            )
        if used == 0 and 0 <= j < x.shape[0] and math.isfinite(x[j]):
            scale_factor = run_factor
            k0 = max(scale_index[t], 0)
            for k in range(k0, min(k0 + max(n_scales[t], 1), scales.shape[0])):
                r2 = scales[k] * scales[k]
                s = _bound(x, y, j, -1, r2, max_gap)
                e = _bound(x, y, j, 1, r2, max_gap)
                if j - s + 1 >= 3 and e - j + 1 >= 3:
                    if scale_covariance(x, y, s, j, e, cx, cy, sigma2, acc):
                        used += 1
        if used > 0:
            for c in range(3):
                acc[c] *= scale_factor / used  # step 3: mean, not divided again by the count
        rho = math.sqrt(cx * cx + cy * cy)
        iso = (apex_factor * rho * dth) ** 2 / 12.0 + floor * floor  # step 4
        cov[t, 0, 0] = acc[0] + iso
        cov[t, 0, 1] = acc[1]
        cov[t, 1, 0] = acc[1]
        cov[t, 1, 1] = acc[2] + iso
    return cov


class DeferredCovariances:
    """A picklable, deferred call of :func:`keypoint_covariances` (lazy ``Keypoints.cov``).

    Holds the arguments (the scan's points, the keypoints' rows, the scales and the
    detector's options) and computes the covariances when called.
    """

    __slots__ = ("args",)

    def __init__(self, *args: object) -> None:
        self.args = args

    def __call__(self) -> NDArray[np.float64]:
        return keypoint_covariances(*self.args)

    def __reduce__(self) -> tuple[type, tuple[object, ...]]:
        return (DeferredCovariances, self.args)


class DeferredScanCovariances(DeferredCovariances):
    """:class:`DeferredCovariances` whose first two arguments are the scan's ranges and the
    detector's geometry array (cosines, sines, range_min, range_max) instead of its points:
    the points are made again when the covariances are computed, so the keypoints of a scan
    keep no copy of them (``ranges`` and the geometry are read-only and shared)."""

    __slots__ = ()

    def __call__(self) -> NDArray[np.float64]:
        ranges, geometry, *rest = self.args
        n = ranges.shape[0]
        x = np.empty(n)
        y = np.empty(n)
        limits = geometry[2 * n], geometry[2 * n + 1]
        polar_to_xy(ranges, geometry[:n], geometry[n : 2 * n], *limits, x, y)
        return keypoint_covariances(x, y, *rest)  # type: ignore[arg-type]

    def __reduce__(self) -> tuple[type, tuple[object, ...]]:
        return (DeferredScanCovariances, self.args)
