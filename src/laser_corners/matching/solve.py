"""numba kernels: weighted least-squares SE(2) and the whole pairwise registration.

:func:`register_pair` is the per-pair pipeline (candidate matches -> verification -> WLS ->
final inliers); :func:`register_batch` runs it for one query against many candidates in one
call, in parallel over the candidates (``numba.prange``).
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np
from numpy.typing import NDArray

from laser_corners.matching.core import (
    VERIFY_CLIQUE,
    _wrap,
    candidate_matches,
    max_clique,
    ransac,
)

# status codes of register_pair (the Python layer turns them into reason strings)
OK = 0
FEW_KEYPOINTS = 1
FEW_CANDIDATES = 2
FEW_INLIERS = 3


@nb.njit(cache=True, nogil=True)
def _weight(
    cov_a: NDArray[np.float64], cov_b: NDArray[np.float64], i: int, j: int,
    c: float, s: float, default_var: float,
) -> tuple[float, float, float]:  # fmt: skip
    """Inverse of C_a + R C_b Rᵀ as (w00, w01, w11); unknown (NaN) covariances -> default."""
    a00 = cov_a[i, 0, 0]
    a01 = cov_a[i, 0, 1]
    a11 = cov_a[i, 1, 1]
    if not (math.isfinite(a00) and math.isfinite(a01) and math.isfinite(a11)):
        a00, a01, a11 = default_var, 0.0, default_var
    b00 = cov_b[j, 0, 0]
    b01 = cov_b[j, 0, 1]
    b11 = cov_b[j, 1, 1]
    if not (math.isfinite(b00) and math.isfinite(b01) and math.isfinite(b11)):
        b00, b01, b11 = default_var, 0.0, default_var
    # R B Rᵀ
    r00 = c * c * b00 - 2 * c * s * b01 + s * s * b11
    r01 = c * s * (b00 - b11) + (c * c - s * s) * b01
    r11 = s * s * b00 + 2 * c * s * b01 + c * c * b11
    s00 = a00 + r00
    s01 = a01 + r01
    s11 = a11 + r11
    det = s00 * s11 - s01 * s01
    return s11 / det, -s01 / det, s00 / det


@nb.njit(cache=True, nogil=True)
def wls_pose(
    xa: NDArray[np.float64], xb: NDArray[np.float64],
    cov_a: NDArray[np.float64], cov_b: NDArray[np.float64],
    m: NDArray[np.int64], sel: NDArray[np.int64], n_sel: int,
    tx: float, ty: float, th: float, default_var: float, pose_cov: NDArray[np.float64],
) -> tuple[float, float, float]:  # fmt: skip
    """Gauss-Newton on the Mahalanobis residuals r = a - (R b + t), weights (C_a + R C_b Rᵀ)⁻¹.

    Starts from (tx, ty, θ); ``pose_cov`` (3x3) receives (JᵀWJ)⁻¹ at the solution.
    """
    h = np.zeros((3, 3))
    g = np.zeros(3)
    for _ in range(6):
        h[:, :] = 0.0
        g[:] = 0.0
        c = math.cos(th)
        s = math.sin(th)
        for q in range(n_sel):
            i = m[sel[q], 0]
            j = m[sel[q], 1]
            bx = xb[j, 0]
            by = xb[j, 1]
            rx = xa[i, 0] - (c * bx - s * by + tx)
            ry = xa[i, 1] - (s * bx + c * by + ty)
            w00, w01, w11 = _weight(cov_a, cov_b, i, j, c, s, default_var)
            # J = d r / d(tx, ty, θ) = -[[1, 0, -(s bx + c by)], [0, 1, c bx - s by]]
            j0x, j0y = -1.0, 0.0
            j1x, j1y = 0.0, -1.0
            j2x = s * bx + c * by
            j2y = -(c * bx - s * by)
            jx = (j0x, j1x, j2x)
            jy = (j0y, j1y, j2y)
            for u in range(3):
                wu_x = w00 * jx[u] + w01 * jy[u]
                wu_y = w01 * jx[u] + w11 * jy[u]
                g[u] += wu_x * rx + wu_y * ry
                for v in range(3):
                    h[u, v] += wu_x * jx[v] + wu_y * jy[v]
        if not abs(np.linalg.det(h)) > 1e-300:  # degenerate geometry: keep the start
            pose_cov[:, :] = math.inf
            return tx, ty, th
        step = np.linalg.solve(h, g)
        tx -= step[0]
        ty -= step[1]
        th -= step[2]
        if abs(step[0]) + abs(step[1]) + abs(step[2]) < 1e-10:
            break
    pose_cov[:, :] = np.linalg.inv(h)
    th = math.atan2(math.sin(th), math.cos(th))
    return tx, ty, th


@nb.njit(cache=True, nogil=True)
def _final_inliers(
    xa: NDArray[np.float64], xb: NDArray[np.float64], m: NDArray[np.int64], n: int,
    tx: float, ty: float, th: float, tol: float, sel: NDArray[np.int64],
    oa: NDArray[np.float64], ob: NDArray[np.float64], angle_tol: float,
) -> int:  # fmt: skip
    """Matches within ``tol`` of the pose, one per keypoint of A and of B (smallest residual)."""
    c = math.cos(th)
    s = math.sin(th)
    res = np.empty(n)
    for q in range(n):
        bx = xb[m[q, 1], 0]
        by = xb[m[q, 1], 1]
        res[q] = math.hypot(xa[m[q, 0], 0] - (c * bx - s * by + tx),
                            xa[m[q, 0], 1] - (s * bx + c * by + ty))  # fmt: skip
        if abs(_wrap(oa[m[q, 0]] - ob[m[q, 1]] - th)) > angle_tol:
            res[q] = math.inf
    order = np.argsort(res, kind="mergesort")
    used_a = np.zeros(xa.shape[0], dtype=np.bool_)
    used_b = np.zeros(xb.shape[0], dtype=np.bool_)
    k = 0
    for q in order:
        if not res[q] <= tol:  # NaN too (keypoints without a position)
            break
        if used_a[m[q, 0]] or used_b[m[q, 1]]:
            continue
        used_a[m[q, 0]] = True
        used_b[m[q, 1]] = True
        sel[k] = q
        k += 1
    return k


@nb.njit(cache=True, nogil=True)
def _rotation_support(
    oa: NDArray[np.float64], ob: NDArray[np.float64], m: NDArray[np.int64], n: int,
    angle_tol: float,
) -> int:  # fmt: skip
    """Largest number of matches whose implied rotations lie within ``angle_tol`` of one's."""
    rot = np.empty(n)
    for q in range(n):
        rot[q] = oa[m[q, 0]] - ob[m[q, 1]]
    best = 0
    for p in range(n):
        cnt = 0
        for q in range(n):
            if abs(_wrap(rot[p] - rot[q])) <= angle_tol:
                cnt += 1
        best = max(best, cnt)
    return best


@nb.njit(cache=True, nogil=True)
def register_pair(
    kind: int, inv_bits: float,
    xa: NDArray[np.float64], cov_a: NDArray[np.float64], oa: NDArray[np.float64],
    bits_a: NDArray[np.uint64], vals_a: NDArray[np.float64],
    xb: NDArray[np.float64], cov_b: NDArray[np.float64], ob: NDArray[np.float64],
    bits_b: NDArray[np.uint64], vals_b: NDArray[np.float64],
    k_nearest: int, ratio: float, mutual: bool, max_distance: float,
    verify: int, tol: float, min_sep: float, iterations: int, seed: int,
    min_inliers: int, default_var: float, angle_tol: float,
    pose: NDArray[np.float64], pose_cov: NDArray[np.float64], inliers: NDArray[np.int64],
) -> tuple[int, int, int]:  # fmt: skip
    """Register B to A; returns ``(status, n_inliers, n_candidates)``.

    ``pose`` (3) receives (tx, ty, θ) of B in A, ``pose_cov`` (3, 3) its covariance,
    ``inliers`` (at least min(M_a, M_b) rows, 2 columns) the inlier pairs. Cheap rejects
    first: fewer than max(2, min_inliers) keypoints on either side, then fewer candidate
    matches than that.
    """
    need = max(2, min_inliers)
    na = xa.shape[0]
    nb_ = xb.shape[0]
    if na < need or nb_ < need:
        return 1, 0, 0
    m = np.empty((na * max(k_nearest, 1), 2), dtype=np.int64)
    n = candidate_matches(
        kind, bits_a, vals_a, bits_b, vals_b, inv_bits, k_nearest, ratio, mutual,
        max_distance, m,
    )  # fmt: skip
    if n < need:
        return 2, 0, n
    # cheap reject: inliers imply one rotation, so at least `need` matches must agree on the
    # rotation given by their keypoint orientations (bisectors) within angle_tol
    if angle_tol < math.pi and _rotation_support(oa, ob, m, n, angle_tol) < need:
        return 3, 0, n
    sel = np.empty(n, dtype=np.int64)
    if verify == VERIFY_CLIQUE:
        n_sel = max_clique(xa, xb, m, n, tol, min_sep, sel, oa, ob, angle_tol)
        if n_sel < need:
            return 3, n_sel, n
        # initial pose from the clique's two farthest-apart matches
        p0 = sel[0]
        q0 = sel[1]
        best = -1.0
        for u in range(n_sel):
            for v in range(u + 1, n_sel):
                d = math.hypot(xa[m[sel[u], 0], 0] - xa[m[sel[v], 0], 0],
                               xa[m[sel[u], 0], 1] - xa[m[sel[v], 0], 1])  # fmt: skip
                if d > best:
                    best = d
                    p0 = sel[u]
                    q0 = sel[v]
        th = math.atan2(xa[m[q0, 0], 1] - xa[m[p0, 0], 1], xa[m[q0, 0], 0] - xa[m[p0, 0], 0])
        th -= math.atan2(xb[m[q0, 1], 1] - xb[m[p0, 1], 1], xb[m[q0, 1], 0] - xb[m[p0, 1], 0])
        tx, ty, th = wls_pose(xa, xb, cov_a, cov_b, m, sel, n_sel,
                              0.0, 0.0, th, default_var, pose_cov)  # fmt: skip
    else:
        tx, ty, th, cnt = ransac(xa, xb, m, n, tol, min_sep, iterations, seed, oa, ob, angle_tol)
        if cnt < need:
            return 3, cnt, n
    # final inliers and two WLS rounds (the second on the inliers of the first)
    for _ in range(2):
        n_sel = _final_inliers(xa, xb, m, n, tx, ty, th, tol, sel, oa, ob, angle_tol)
        if n_sel < need:
            return 3, n_sel, n
        tx, ty, th = wls_pose(
            xa, xb, cov_a, cov_b, m, sel, n_sel, tx, ty, th, default_var, pose_cov
        )
    n_sel = _final_inliers(xa, xb, m, n, tx, ty, th, tol, sel, oa, ob, angle_tol)
    if n_sel < need:
        return 3, n_sel, n
    pose[0] = tx
    pose[1] = ty
    pose[2] = th
    for q in range(n_sel):
        inliers[q, 0] = m[sel[q], 0]
        inliers[q, 1] = m[sel[q], 1]
    return 0, n_sel, n


@nb.njit(cache=True, parallel=True)
def register_batch(
    kind: int, inv_bits: float,
    xa: NDArray[np.float64], cov_a: NDArray[np.float64], oa: NDArray[np.float64],
    bits_a: NDArray[np.uint64], vals_a: NDArray[np.float64],
    xb: NDArray[np.float64], cov_b: NDArray[np.float64], ob: NDArray[np.float64],
    bits_b: NDArray[np.uint64], vals_b: NDArray[np.float64],
    offsets: NDArray[np.int64], which: NDArray[np.int64],
    k_nearest: int, ratio: float, mutual: bool, max_distance: float,
    verify: int, tol: float, min_sep: float, iterations: int, seed: int,
    min_inliers: int, default_var: float, angle_tol: float,
    status: NDArray[np.int64], n_inliers: NDArray[np.int64], poses: NDArray[np.float64],
    pose_covs: NDArray[np.float64],
) -> None:  # fmt: skip
    """:func:`register_pair` of A against the candidates ``which`` of a bank.

    The bank's keypoints of candidate c are rows ``offsets[c]:offsets[c+1]`` of ``xb``,
    ``cov_b``, ``bits_b``, ``vals_b``. Outputs are indexed like ``which``.
    """
    for t in nb.prange(which.shape[0]):
        c = which[t]
        lo = offsets[c]
        hi = offsets[c + 1]
        inl = np.empty((max(min(xa.shape[0], hi - lo), 1), 2), dtype=np.int64)
        bb = bits_b[lo:hi]
        vb = vals_b[lo:hi]
        st, k, _ = register_pair(
            kind, inv_bits, xa, cov_a, oa, bits_a, vals_a, xb[lo:hi], cov_b[lo:hi], ob[lo:hi],
            bb, vb, k_nearest, ratio, mutual, max_distance, verify, tol, min_sep, iterations,
            seed, min_inliers, default_var, angle_tol, poses[t], pose_covs[t], inl,
        )  # fmt: skip
        status[t] = st
        n_inliers[t] = k
