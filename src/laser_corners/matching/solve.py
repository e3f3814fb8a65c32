"""numba kernels: weighted least-squares SE(2) and the whole pairwise registration.

:func:`register_pair` is the per-pair pipeline (candidate matches -> hypotheses -> WLS ->
final inliers -> scan verification); :func:`register_batch` runs it for any list of
(query, candidate) pairs of two keypoint banks in one call, in parallel over the pairs
(``numba.prange``).

A *side* (one scan, :class:`~laser_corners.matching.kernel_args.Side`), a *bank* (many scans,
:class:`~laser_corners.matching.kernel_args.Bank`) and the options
(:class:`~laser_corners.matching.kernel_args.KernelOptions`, the fields of
:class:`~laser_corners.matching.MatchOptions` under the same names) are named tuples.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np
from numpy.typing import NDArray

from laser_corners.matching.clique import max_clique
from laser_corners.matching.core import VERIFY_CLIQUE, ransac
from laser_corners.matching.kernel_args import KernelOptions, Offsets, Side, side_scan
from laser_corners.matching.nearest import candidate_matches
from laser_corners.matching.verify import precheck, verify_pose
from laser_corners.pose import wrap_angle

# status codes of register_pair (the Python layer turns them into reason strings)
OK = 0
FEW_KEYPOINTS = 1
FEW_CANDIDATES = 2
FEW_INLIERS = 3
SCAN_DISAGREES = 4


@nb.njit(cache=True, nogil=True)
def _weight(
    cov_a: NDArray[np.float64],
    cov_b: NDArray[np.float64],
    i: int,
    j: int,
    c: float,
    s: float,
    default_var: float,
) -> tuple[float, float, float]:
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
    xa: NDArray[np.float64],
    xb: NDArray[np.float64],
    cov_a: NDArray[np.float64],
    cov_b: NDArray[np.float64],
    m: NDArray[np.int64],
    sel: NDArray[np.int64],
    n_sel: int,
    tx: float,
    ty: float,
    th: float,
    default_var: float,
    pose_cov: NDArray[np.float64],
) -> tuple[float, float, float]:
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
    a: Side,
    b: Side,
    m: NDArray[np.int64],
    n: int,
    tx: float,
    ty: float,
    th: float,
    tol: float,
    angle_tol: float,
    sel: NDArray[np.int64],
) -> int:
    """Matches within ``tol`` of the pose whose keypoint orientations agree with its rotation
    within ``angle_tol``, one per keypoint of A and of B (smallest residual), into ``sel``."""
    xa, xb, oa, ob = a.xy, b.xy, a.orientation, b.orientation
    c = math.cos(th)
    s = math.sin(th)
    res = np.empty(n)
    for q in range(n):
        bx = xb[m[q, 1], 0]
        by = xb[m[q, 1], 1]
        res[q] = math.hypot(
            xa[m[q, 0], 0] - (c * bx - s * by + tx), xa[m[q, 0], 1] - (s * bx + c * by + ty)
        )
        if abs(wrap_angle(oa[m[q, 0]] - ob[m[q, 1]] - th)) > angle_tol:
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
    oa: NDArray[np.float64],
    ob: NDArray[np.float64],
    m: NDArray[np.int64],
    n: int,
    angle_tol: float,
) -> int:
    """Largest number of matches whose implied rotations lie within ``angle_tol`` of one's."""
    rot = np.empty(n)
    for q in range(n):
        rot[q] = oa[m[q, 0]] - ob[m[q, 1]]
    best = 0
    for p in range(n):
        cnt = 0
        for q in range(n):
            if abs(wrap_angle(rot[p] - rot[q])) <= angle_tol:
                cnt += 1
        best = max(best, cnt)
    return best


@nb.njit(cache=True, nogil=True)
def _clique_pose(
    xa: NDArray[np.float64],
    xb: NDArray[np.float64],
    cov_a: NDArray[np.float64],
    cov_b: NDArray[np.float64],
    oa: NDArray[np.float64],
    ob: NDArray[np.float64],
    m: NDArray[np.int64],
    sel: NDArray[np.int64],
    n_sel: int,
    default_var: float,
    pose_cov: NDArray[np.float64],
) -> tuple[float, float, float]:
    """Pose of a clique: WLS from the rotation of its two farthest-apart matches (one match:
    the rotation of its keypoint orientations)."""
    p0 = sel[0]
    if n_sel < 2:
        th = oa[m[p0, 0]] - ob[m[p0, 1]]
        c = math.cos(th)
        s = math.sin(th)
        bx = xb[m[p0, 1], 0]
        by = xb[m[p0, 1], 1]
        return xa[m[p0, 0], 0] - (c * bx - s * by), xa[m[p0, 0], 1] - (s * bx + c * by), th
    q0 = sel[1]
    best = -1.0
    for u in range(n_sel):
        for v in range(u + 1, n_sel):
            d = math.hypot(
                xa[m[sel[u], 0], 0] - xa[m[sel[v], 0], 0], xa[m[sel[u], 0], 1] - xa[m[sel[v], 0], 1]
            )
            if d > best:
                best = d
                p0 = sel[u]
                q0 = sel[v]
    th = math.atan2(xa[m[q0, 0], 1] - xa[m[p0, 0], 1], xa[m[q0, 0], 0] - xa[m[p0, 0], 0])
    th -= math.atan2(xb[m[q0, 1], 1] - xb[m[p0, 1], 1], xb[m[q0, 1], 0] - xb[m[p0, 1], 0])
    return wls_pose(xa, xb, cov_a, cov_b, m, sel, n_sel, 0.0, 0.0, th, default_var, pose_cov)


@nb.njit(cache=True, nogil=True)
def _refine(
    a: Side,
    b: Side,
    m: NDArray[np.int64],
    n: int,
    hyp: NDArray[np.float64],
    options: KernelOptions,
    need: int,
    sel: NDArray[np.int64],
    pose_cov: NDArray[np.float64],
) -> tuple[int, float, float, float]:
    """Final inliers and two WLS rounds (the second on the inliers of the first), from the
    hypothesis ``hyp`` (tx, ty, θ); returns ``(n_inliers, tx, ty, θ)`` (``sel`` holds the
    inliers). With one inlier the WLS cannot fix the rotation: the pose stays, ``pose_cov``
    is infinite."""
    xa, xb, cov_a, cov_b = a.xy, b.xy, a.cov, b.cov
    tol, angle_tol = options.tolerance, options.angle_tolerance
    default_var = options.default_sigma**2
    tx, ty, th = hyp[0], hyp[1], hyp[2]
    for _ in range(2):
        n_sel = _final_inliers(a, b, m, n, tx, ty, th, tol, angle_tol, sel)
        if n_sel < need:
            return n_sel, tx, ty, th
        tx, ty, th = wls_pose(
            xa, xb, cov_a, cov_b, m, sel, n_sel, tx, ty, th, default_var, pose_cov
        )
    n_sel = _final_inliers(a, b, m, n, tx, ty, th, tol, angle_tol, sel)
    return n_sel, tx, ty, th


@nb.njit(cache=True, nogil=True)
def _hypotheses(
    a: Side,
    b: Side,
    m: NDArray[np.int64],
    n: int,
    options: KernelOptions,
    sel: NDArray[np.int64],
    hyp: NDArray[np.float64],
    counts: NDArray[np.int64],
    pose_cov: NDArray[np.float64],
) -> int:
    """The verification's pose hypotheses, best first (RANSAC: up to ``max_hypotheses``;
    clique: one); returns how many."""
    if options.verification == VERIFY_CLIQUE:
        n_sel = max_clique(a, b, m, n, sel, options)
        if n_sel == 0:
            return 0
        tx, ty, th = _clique_pose(
            a.xy,
            b.xy,
            a.cov,
            b.cov,
            a.orientation,
            b.orientation,
            m,
            sel,
            n_sel,
            options.default_sigma**2,
            pose_cov,
        )
        hyp[0, 0], hyp[0, 1], hyp[0, 2] = tx, ty, th
        counts[0] = n_sel
        return 1
    return ransac(a, b, m, n, options, hyp, counts)


@nb.njit(cache=True, nogil=True)
def _candidates(
    kind: int, inv_bits: float, a: Side, b: Side, options: KernelOptions
) -> tuple[NDArray[np.int64], int]:
    """The candidate matches (descriptor neighbours of A's keypoints among B's): ``m`` and
    how many of its rows are filled."""
    m = np.empty((a.xy.shape[0] * max(options.k_nearest, 1), 2), dtype=np.int64)
    n = candidate_matches(kind, inv_bits, a, b, options, m)
    return m, n


@nb.njit(cache=True, nogil=True)
def register_pair(
    kind: int,
    inv_bits: float,
    a: Side,
    b: Side,
    options: KernelOptions,
    pose: NDArray[np.float64],
    pose_cov: NDArray[np.float64],
    inliers: NDArray[np.int64],
) -> tuple[int, int, int, float]:
    """Register side B to side A; returns ``(status, n_inliers, n_candidates, agreement)``.

    ``pose`` (3) receives (tx, ty, θ) of B in A, ``pose_cov`` (3, 3) its covariance,
    ``inliers`` (at least min(M_a, M_b) rows, 2 columns) the inlier pairs. Cheap rejects
    first: too few keypoints on either side, then too few candidate matches, then too few
    matches agreeing on a rotation. The hypotheses are then refined (WLS) and, with the scan
    check on, verified against the scans, best first; the first that passes is the result.
    """
    angle_tol = options.angle_tolerance
    need = max(1 if options.verify_scan else 2, options.min_inliers)
    na = a.xy.shape[0]
    nb_ = b.xy.shape[0]
    if na < need or nb_ < need:
        return FEW_KEYPOINTS, 0, 0, 0.0
    m, n = _candidates(kind, inv_bits, a, b, options)
    if n < need:
        return FEW_CANDIDATES, 0, n, 0.0
    # inliers imply one rotation, so at least `need` matches must agree on the rotation
    # given by their keypoint orientations (bisectors) within angle_tolerance
    if (
        angle_tol < math.pi
        and _rotation_support(a.orientation, b.orientation, m, n, angle_tol) < need
    ):
        return FEW_INLIERS, 0, n, 0.0
    sel = np.empty(n, dtype=np.int64)
    hyp = np.empty((max(options.max_hypotheses, 1), 3))
    counts = np.zeros(max(options.max_hypotheses, 1), dtype=np.int64)
    nk = _hypotheses(a, b, m, n, options, sel, hyp, counts, pose_cov)
    status = FEW_INLIERS
    best_n = 0
    for h in range(nk):
        if counts[h] < need:
            break
        if not precheck(side_scan(a), side_scan(b), (hyp[h, 0], hyp[h, 1], hyp[h, 2]), options):
            status = SCAN_DISAGREES  # the cheap look at the scans, before any refinement
            continue
        n_sel, tx, ty, th = _refine(a, b, m, n, hyp[h], options, need, sel, pose_cov)
        best_n = max(best_n, n_sel)
        if n_sel < need:
            continue
        agreement, (tx, ty, th) = verify_pose(side_scan(a), side_scan(b), (tx, ty, th), options)
        if agreement < 0.0:
            status = SCAN_DISAGREES
            continue
        pose[0], pose[1], pose[2] = tx, ty, th
        for q in range(n_sel):
            inliers[q, 0] = m[sel[q], 0]
            inliers[q, 1] = m[sel[q], 1]
        return OK, n_sel, n, agreement
    return status, best_n if status == FEW_INLIERS else 0, n, 0.0


@nb.njit(cache=True, nogil=True, inline="always")
def _side(rows: Side, offsets: Offsets, s: int) -> Side:
    """Scan ``s`` of a bank (its ``rows`` and ``offsets``) as a side."""
    lo, hi = offsets.keypoints[s], offsets.keypoints[s + 1]
    r0, r1 = offsets.ranges[s], offsets.ranges[s + 1]
    p0, p1 = offsets.points[s], offsets.points[s + 1]
    return Side(
        rows.xy[lo:hi],
        rows.cov[lo:hi],
        rows.orientation[lo:hi],
        rows.opening[lo:hi],
        rows.bits[lo:hi],
        rows.values[lo:hi],
        rows.ranges[r0:r1],
        rows.geometry[s],
        rows.points[p0:p1],
    )


@nb.njit(cache=True, parallel=True)
def register_batch(
    kind: int,
    inv_bits: float,
    rows_a: Side,
    offsets_a: Offsets,
    rows_b: Side,
    offsets_b: Offsets,
    qa: NDArray[np.int64],
    cb: NDArray[np.int64],
    options: KernelOptions,
    status: NDArray[np.int64],
    n_inliers: NDArray[np.int64],
    poses: NDArray[np.float64],
    pose_covs: NDArray[np.float64],
    agreement: NDArray[np.float64],
) -> None:
    """:func:`register_pair` of scan ``qa[t]`` of bank A and scan ``cb[t]`` of bank B for
    every t, in parallel; outputs are indexed by t. A bank comes as its
    :class:`~laser_corners.matching.kernel_args.Bank` ``rows`` and ``offsets`` (numba's
    parallel loops take flat tuples only)."""
    for t in nb.prange(qa.shape[0]):
        a = _side(rows_a, offsets_a, qa[t])
        b = _side(rows_b, offsets_b, cb[t])
        inl = np.empty((max(min(a.xy.shape[0], b.xy.shape[0]), 1), 2), dtype=np.int64)
        st, k, _, agr = register_pair(kind, inv_bits, a, b, options, poses[t], pose_covs[t], inl)
        status[t] = st
        n_inliers[t] = k
        agreement[t] = agr
