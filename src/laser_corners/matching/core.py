"""numba kernels of the matcher: pose hypotheses (single matches, RANSAC pairs).

All kernels work on plain arrays so that one call can register a query against many
candidate scans (:func:`laser_corners.matching.solve.register_batch`, parallel over pairs).
Candidate matches come from :mod:`laser_corners.matching.nearest`. Conventions: A is the
reference (query) scan, B the other; a match is a pair (index in A, index in B); the pose
(tx, ty, θ) maps B's sensor frame into A's: p_A = R(θ)·p_B + t.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np
from numpy.typing import NDArray

from laser_corners.matching.kernel_args import KernelOptions, Side
from laser_corners.pose import wrap_angle

# verification modes
VERIFY_RANSAC = 0
VERIFY_CLIQUE = 1


@nb.njit(cache=True, nogil=True)
def _pose_two(
    a1x: float,
    a1y: float,
    a2x: float,
    a2y: float,
    b1x: float,
    b1y: float,
    b2x: float,
    b2y: float,
) -> tuple[float, float, float]:
    """SE(2) mapping b1, b2 onto a1, a2 (rotation of the segment, centroids aligned)."""
    th = math.atan2(a2y - a1y, a2x - a1x) - math.atan2(b2y - b1y, b2x - b1x)
    c = math.cos(th)
    s = math.sin(th)
    mbx = 0.5 * (b1x + b2x)
    mby = 0.5 * (b1y + b2y)
    tx = 0.5 * (a1x + a2x) - (c * mbx - s * mby)
    ty = 0.5 * (a1y + a2y) - (s * mbx + c * mby)
    return tx, ty, th


@nb.njit(cache=True, nogil=True)
def _count_inliers(
    xa: NDArray[np.float64],
    xb: NDArray[np.float64],
    m: NDArray[np.int64],
    n: int,
    tx: float,
    ty: float,
    th: float,
    tol2: float,
    rot: NDArray[np.float64],
    cos_tol: float,
) -> tuple[int, float]:
    c = math.cos(th)
    s = math.sin(th)
    cnt = 0
    cost = 0.0
    for q in range(n):
        if rot[q, 0] * c + rot[q, 1] * s < cos_tol:  # the match's own rotation disagrees
            continue
        bx = xb[m[q, 1], 0]
        by = xb[m[q, 1], 1]
        dx = xa[m[q, 0], 0] - (c * bx - s * by + tx)
        dy = xa[m[q, 0], 1] - (s * bx + c * by + ty)
        d2 = dx * dx + dy * dy
        if d2 <= tol2:
            cnt += 1
            cost += d2
    return cnt, cost


@nb.njit(cache=True, nogil=True, inline="always")
def cos_tolerance(angle_tolerance: float) -> float:
    """The cosine of ``angle_tolerance`` for the rotation tests (-2: off at pi or more)."""
    return math.cos(angle_tolerance) if angle_tolerance < math.pi else -2.0


@nb.njit(cache=True, nogil=True)
def _prepare(
    xa: NDArray[np.float64],
    xb: NDArray[np.float64],
    m: NDArray[np.int64],
    n: int,
    oa: NDArray[np.float64],
    ob: NDArray[np.float64],
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Inter-keypoint distances of A and of B, and each match's implied rotation as a unit
    vector (cos, sin), so that the pairwise tests need no square root or angle wrapping."""
    na = xa.shape[0]
    nb_ = xb.shape[0]
    da = np.empty((na, na))
    for i in range(na):
        for j in range(na):
            da[i, j] = math.hypot(xa[i, 0] - xa[j, 0], xa[i, 1] - xa[j, 1])
    db = np.empty((nb_, nb_))
    for i in range(nb_):
        for j in range(nb_):
            db[i, j] = math.hypot(xb[i, 0] - xb[j, 0], xb[i, 1] - xb[j, 1])
    rot = np.empty((n, 2))
    for q in range(n):
        r = oa[m[q, 0]] - ob[m[q, 1]]
        rot[q, 0] = math.cos(r)
        rot[q, 1] = math.sin(r)
    return da, db, rot


@nb.njit(cache=True, nogil=True, inline="always")
def _pair_fast(
    da: NDArray[np.float64],
    db: NDArray[np.float64],
    rot: NDArray[np.float64],
    m: NDArray[np.int64],
    p: int,
    q: int,
    tol: float,
    min_sep: float,
    cos_tol: float,
) -> bool:
    """Pairwise consistency of matches p and q (FALKO's CCDA): distinct keypoints, equal
    inter-keypoint distances in A and B within ``tol`` (and at least ``min_sep``), and (ours)
    the same rotation implied by both matches' keypoint orientations, within the angle whose
    cosine is ``cos_tol``."""
    ia = m[p, 0]
    ja = m[q, 0]
    ib = m[p, 1]
    jb = m[q, 1]
    if ia == ja or ib == jb:
        return False
    if rot[p, 0] * rot[q, 0] + rot[p, 1] * rot[q, 1] < cos_tol:
        return False
    d = da[ia, ja]
    return abs(d - db[ib, jb]) <= tol and d >= min_sep


@nb.njit(cache=True, nogil=True)
def _better(cnt: int, cost: float, cnt2: int, cost2: float) -> bool:
    return cnt > cnt2 or (cnt == cnt2 and cost < cost2)


@nb.njit(cache=True, nogil=True)
def _keep(
    poses: NDArray[np.float64],
    counts: NDArray[np.int64],
    costs: NDArray[np.float64],
    nk: int,
    tx: float,
    ty: float,
    th: float,
    cnt: int,
    cost: float,
    tol: float,
) -> int:
    """Insert a hypothesis into the list of the best ones (most inliers, then lowest cost),
    at most ``len(counts)`` of them; returns the new length. Hypotheses of one pose (within
    ``2·tol`` in translation and ``tol/2`` rad, e.g. the pairs and single matches of one
    inlier set) are kept once, the better one."""
    for h in range(nk):
        if (
            abs(poses[h, 0] - tx) <= 2.0 * tol
            and abs(poses[h, 1] - ty) <= 2.0 * tol
            and abs(wrap_angle(poses[h, 2] - th)) <= 0.5 * tol
        ):
            if not _better(cnt, cost, counts[h], costs[h]):
                return nk
            for g in range(h, nk - 1):  # drop the worse copy
                poses[g] = poses[g + 1]
                counts[g] = counts[g + 1]
                costs[g] = costs[g + 1]
            nk -= 1
            break
    k_max = counts.shape[0]
    if nk == k_max and not _better(cnt, cost, counts[nk - 1], costs[nk - 1]):
        return nk
    p = nk if nk < k_max else k_max - 1
    nk = min(nk + 1, k_max)
    while p > 0 and _better(cnt, cost, counts[p - 1], costs[p - 1]):
        poses[p] = poses[p - 1]
        counts[p] = counts[p - 1]
        costs[p] = costs[p - 1]
        p -= 1
    poses[p, 0] = tx
    poses[p, 1] = ty
    poses[p, 2] = th
    counts[p] = cnt
    costs[p] = cost
    return nk


@nb.njit(cache=True, nogil=True)
def _single_point_hypotheses(xa, xb, m, n: int, rot, tol: float, cos_tol: float, kept) -> int:
    """One hypothesis per match (rotation: the difference of the two keypoint orientations,
    translation from the keypoints) into the ``kept`` (poses, counts, costs); returns how
    many are kept."""
    poses, counts, costs = kept
    tol2 = tol * tol
    nk = 0
    for q in range(n):
        th = math.atan2(rot[q, 1], rot[q, 0])
        if th != th:
            continue
        c = math.cos(th)
        s = math.sin(th)
        bx = xb[m[q, 1], 0]
        by = xb[m[q, 1], 1]
        tx = xa[m[q, 0], 0] - (c * bx - s * by)
        ty = xa[m[q, 0], 1] - (s * bx + c * by)
        cnt, cost = _count_inliers(xa, xb, m, n, tx, ty, th, tol2, rot, cos_tol)
        if cnt > 0:
            nk = _keep(poses, counts, costs, nk, tx, ty, th, cnt, cost, tol)
    return nk


@nb.njit(cache=True, nogil=True)
def ransac(
    a: Side,
    b: Side,
    m: NDArray[np.int64],
    n: int,
    options: KernelOptions,
    poses: NDArray[np.float64],
    counts: NDArray[np.int64],
) -> int:
    """The best SE(2) hypotheses (most inliers within ``options.tolerance``; ties: lower
    cost).

    Hypotheses: with ``options.single_point``, each match alone (rotation = difference of the
    two keypoint orientations, translation from the keypoints); then pairs of matches
    (two-point alignment): all pairs when there are at most ``options.iterations`` of them,
    else that many pairs drawn by a xorshift generator seeded with ``options.seed``
    (deterministic). ``poses`` (K, 3) and ``counts`` (K) receive the K best distinct ones,
    best first; returns how many. ``a`` and ``b``: the two sides (keypoint positions and
    orientations), ``m``: the candidate matches, ``n`` of them.
    """
    xa, xb = a.xy, b.xy
    tol = options.tolerance
    costs = np.empty(counts.shape[0])
    nk = 0
    tol2 = tol * tol
    da, db, rot = _prepare(xa, xb, m, n, a.orientation, b.orientation)
    cos_tol = cos_tolerance(options.angle_tolerance)
    if options.single_point:
        kept = (poses, counts, costs)
        nk = _single_point_hypotheses(xa, xb, m, n, rot, tol, cos_tol, kept)
    n_pairs = n * (n - 1) // 2
    exhaustive = n_pairs <= options.iterations
    state = np.uint64(88172645463325252) ^ (np.uint64(options.seed) * np.uint64(2654435761))
    p = np.int64(0)
    q = np.int64(1)
    total = n_pairs if exhaustive else options.iterations
    for it in range(total):
        if exhaustive:
            if it > 0:
                q += 1
                if q >= n:
                    p += 1
                    q = p + 1
        else:
            state ^= state << np.uint64(13)
            state ^= state >> np.uint64(7)
            state ^= state << np.uint64(17)
            p = np.int64(state % np.uint64(n))
            state ^= state << np.uint64(13)
            state ^= state >> np.uint64(7)
            state ^= state << np.uint64(17)
            q = np.int64(state % np.uint64(n))
            if p == q:
                continue
        if not _pair_fast(da, db, rot, m, p, q, tol, options.min_separation, cos_tol):
            continue
        tx, ty, th = _pose_two(
            xa[m[p, 0], 0],
            xa[m[p, 0], 1],
            xa[m[q, 0], 0],
            xa[m[q, 0], 1],
            xb[m[p, 1], 0],
            xb[m[p, 1], 1],
            xb[m[q, 1], 0],
            xb[m[q, 1], 1],
        )
        cnt, cost = _count_inliers(xa, xb, m, n, tx, ty, th, tol2, rot, cos_tol)
        if cnt > 0:
            nk = _keep(poses, counts, costs, nk, tx, ty, th, cnt, cost, tol)
    return nk
