"""numba kernels of the matcher: descriptor nearest neighbours and RANSAC hypotheses.

All kernels work on plain arrays so that one call can register a query against many
candidate scans (:func:`register_batch`, parallel over candidates). Conventions: A is the
reference (query) scan, B the other; a match is a pair (index in A, index in B); the pose
(tx, ty, θ) maps B's sensor frame into A's: p_A = R(θ)·p_B + t.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np
from numpy.typing import NDArray

# verification modes
VERIFY_RANSAC = 0
VERIFY_CLIQUE = 1


@nb.njit(cache=True, nogil=True, inline="always")
def _popcount(v: np.uint64) -> int:
    v = v - ((v >> np.uint64(1)) & np.uint64(0x5555555555555555))
    v = (v & np.uint64(0x3333333333333333)) + ((v >> np.uint64(2)) & np.uint64(0x3333333333333333))
    v = (v + (v >> np.uint64(4))) & np.uint64(0x0F0F0F0F0F0F0F0F)
    return int((v * np.uint64(0x0101010101010101)) >> np.uint64(56))


@nb.njit(cache=True, nogil=True)
def _distance(
    kind: int,
    bits_a: NDArray[np.uint64],
    vals_a: NDArray[np.float64],
    i: int,
    bits_b: NDArray[np.uint64],
    vals_b: NDArray[np.float64],
    j: int,
    inv_bits: float,
    bound: float = math.inf,
) -> float:
    """Normalised descriptor distance: Hamming / n_bits (bsc) or L1 (csc).

    csc stops early once the partial sum exceeds ``bound`` and returns that partial sum
    (a value above ``bound``, below the true distance).
    """
    if kind == 0:
        h = 0
        for w in range(bits_a.shape[1]):
            h += _popcount(bits_a[i, w] ^ bits_b[j, w])
        return h * inv_bits
    s = 0.0
    d = vals_a.shape[1]
    c = 0
    while c < d:
        top = min(c + 8, d)
        for cc in range(c, top):
            s += abs(vals_a[i, cc] - vals_b[j, cc])
        if s > bound:
            return s
        c = top
    return s


@nb.njit(cache=True, nogil=True, inline="always")
def _opening_ok(open_a: NDArray[np.float64], i: int, open_b: NDArray[np.float64], j: int,
                max_open: float) -> bool:  # fmt: skip
    """Opening angles within ``max_open`` degrees (unknown, NaN, openings always pass)."""
    d = abs(open_a[i] - open_b[j])
    return not d > max_open


@nb.njit(cache=True, nogil=True)
def _nearest_stream(
    kind: int, bits_a: NDArray[np.uint64], vals_a: NDArray[np.float64],
    bits_b: NDArray[np.uint64], vals_b: NDArray[np.float64], inv_bits: float,
    open_a: NDArray[np.float64], open_b: NDArray[np.float64], max_open: float,
    k: int, max_distance: float, na: int, nb_: int, out: NDArray[np.int64],
) -> int:  # fmt: skip
    """k nearest within ``max_distance`` without a distance matrix: each distance stops as
    soon as it exceeds the current k-th best (the result is that of exact distances)."""
    idx = np.empty(k, dtype=np.int64)
    dd = np.empty(k)
    n = 0
    for i in range(na):
        cnt = 0
        for j in range(nb_):
            if not _opening_ok(open_a, i, open_b, j, max_open):
                continue
            bound = dd[k - 1] if cnt == k else max_distance
            d = _distance(kind, bits_a, vals_a, i, bits_b, vals_b, j, inv_bits, bound)
            if d > bound or (cnt == k and d >= bound):
                continue
            if cnt < k:
                p = cnt
                cnt += 1
            else:
                p = k - 1
            while p > 0 and dd[p - 1] > d:
                dd[p] = dd[p - 1]
                idx[p] = idx[p - 1]
                p -= 1
            dd[p] = d
            idx[p] = j
        for q in range(cnt):
            out[n, 0] = i
            out[n, 1] = idx[q]
            n += 1
    return n


@nb.njit(cache=True, nogil=True)
def candidate_matches(
    kind: int,
    bits_a: NDArray[np.uint64],
    vals_a: NDArray[np.float64],
    bits_b: NDArray[np.uint64],
    vals_b: NDArray[np.float64],
    inv_bits: float,
    k_nearest: int,
    ratio: float,
    mutual: bool,
    max_distance: float,
    out: NDArray[np.int64],
    open_a: NDArray[np.float64],
    open_b: NDArray[np.float64],
    max_open: float,
) -> int:
    """Candidate matches by nearest neighbours in descriptor space; returns their count.

    For each keypoint of A its ``k_nearest`` nearest keypoints of B with a distance at most
    ``max_distance`` and an opening angle within ``max_open`` degrees (``open_a``,
    ``open_b``); with ``ratio < 1`` the nearest is kept only when d1 <= ratio·d2
    (Lowe's test; then only the nearest), with ``mutual`` only when A's keypoint is also the
    nearest of B's. ``out`` (at least M_a·k_nearest rows, 2 columns) receives the pairs.
    """
    na = max(bits_a.shape[0], vals_a.shape[0])
    nb_ = max(bits_b.shape[0], vals_b.shape[0])
    if na == 0 or nb_ == 0:
        return 0
    if ratio >= 1.0 and not mutual:
        k = min(k_nearest, nb_)
        return _nearest_stream(kind, bits_a, vals_a, bits_b, vals_b, inv_bits, open_a, open_b,
                               max_open, k, max_distance, na, nb_, out)  # fmt: skip
    # distances above `bound` are never kept, never decide a ratio test (the second nearest
    # is then beyond d1/ratio) and never win a column of the mutual check against a kept
    # match, so their computation may stop early: the result is that of exact distances
    bound = max_distance / min(ratio, 1.0) if ratio > 0.0 else math.inf
    dist = np.empty((na, nb_))
    for i in range(na):
        for j in range(nb_):
            if _opening_ok(open_a, i, open_b, j, max_open):
                dist[i, j] = _distance(kind, bits_a, vals_a, i, bits_b, vals_b, j, inv_bits,
                                       bound)  # fmt: skip
            else:
                dist[i, j] = math.inf
    best_a = np.empty(nb_, dtype=np.int64)  # nearest keypoint of A for each of B
    if mutual:
        for j in range(nb_):
            bi = 0
            for i in range(1, na):
                if dist[i, j] < dist[bi, j]:
                    bi = i
            best_a[j] = bi
    k = min(k_nearest, nb_) if ratio >= 1.0 else 1
    idx = np.empty(k + 1, dtype=np.int64)
    dd = np.empty(k + 1)
    n = 0
    for i in range(na):
        # insertion of the k+1 smallest distances
        cnt = 0
        for j in range(nb_):
            d = dist[i, j]
            if cnt < k + 1:
                p = cnt
                cnt += 1
            elif d < dd[k]:
                p = k
            else:
                continue
            while p > 0 and dd[p - 1] > d:
                dd[p] = dd[p - 1]
                idx[p] = idx[p - 1]
                p -= 1
            dd[p] = d
            idx[p] = j
        for q in range(min(k, cnt)):
            if dd[q] > max_distance:
                break
            if ratio < 1.0 and cnt > 1 and dd[0] > ratio * dd[1]:
                break
            if mutual and best_a[idx[q]] != i:
                continue
            out[n, 0] = i
            out[n, 1] = idx[q]
            n += 1
    return n


@nb.njit(cache=True, nogil=True)
def _pose_two(
    a1x: float, a1y: float, a2x: float, a2y: float,
    b1x: float, b1y: float, b2x: float, b2y: float,
) -> tuple[float, float, float]:  # fmt: skip
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
    xa: NDArray[np.float64], xb: NDArray[np.float64], m: NDArray[np.int64], n: int,
    tx: float, ty: float, th: float, tol2: float,
    rot: NDArray[np.float64], cos_tol: float,
) -> tuple[int, float]:  # fmt: skip
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


@nb.njit(cache=True, nogil=True)
def _wrap(a: float) -> float:
    return (a + math.pi) % (2.0 * math.pi) - math.pi


@nb.njit(cache=True, nogil=True)
def _prepare(
    xa: NDArray[np.float64], xb: NDArray[np.float64], m: NDArray[np.int64], n: int,
    oa: NDArray[np.float64], ob: NDArray[np.float64],
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:  # fmt: skip
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
    da: NDArray[np.float64], db: NDArray[np.float64], rot: NDArray[np.float64],
    m: NDArray[np.int64], p: int, q: int, tol: float, min_sep: float, cos_tol: float,
) -> bool:  # fmt: skip
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
    poses: NDArray[np.float64], counts: NDArray[np.int64], costs: NDArray[np.float64],
    nk: int, tx: float, ty: float, th: float, cnt: int, cost: float, tol: float,
) -> int:  # fmt: skip
    """Insert a hypothesis into the list of the best ones (most inliers, then lowest cost),
    at most ``len(counts)`` of them; returns the new length. Hypotheses of one pose (within
    ``2·tol`` in translation and ``tol/2`` rad, e.g. the pairs and single matches of one
    inlier set) are kept once, the better one."""
    for h in range(nk):
        if (abs(poses[h, 0] - tx) <= 2.0 * tol and abs(poses[h, 1] - ty) <= 2.0 * tol
                and abs(_wrap(poses[h, 2] - th)) <= 0.5 * tol):  # fmt: skip
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
def ransac(
    xa: NDArray[np.float64], xb: NDArray[np.float64], m: NDArray[np.int64], n: int,
    tol: float, min_sep: float, iterations: int, seed: int,
    oa: NDArray[np.float64], ob: NDArray[np.float64], angle_tol: float, single: bool,
    poses: NDArray[np.float64], counts: NDArray[np.int64],
) -> int:  # fmt: skip
    """The best SE(2) hypotheses (most inliers within ``tol``; ties: lower cost).

    Hypotheses: with ``single``, each match alone (rotation = difference of the two keypoint
    orientations, translation from the keypoints); then pairs of matches (two-point
    alignment): all pairs when there are at most ``iterations`` of them, else ``iterations``
    pairs drawn by a xorshift generator seeded with ``seed`` (deterministic). ``poses`` (K, 3)
    and ``counts`` (K) receive the K best distinct ones, best first; returns how many.
    """
    costs = np.empty(counts.shape[0])
    nk = 0
    tol2 = tol * tol
    da, db, rot = _prepare(xa, xb, m, n, oa, ob)
    cos_tol = math.cos(angle_tol) if angle_tol < math.pi else -2.0
    if single:
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
    n_pairs = n * (n - 1) // 2
    exhaustive = n_pairs <= iterations
    state = np.uint64(88172645463325252) ^ (np.uint64(seed) * np.uint64(2654435761))
    p = np.int64(0)
    q = np.int64(1)
    total = n_pairs if exhaustive else iterations
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
        if not _pair_fast(da, db, rot, m, p, q, tol, min_sep, cos_tol):
            continue
        tx, ty, th = _pose_two(
            xa[m[p, 0], 0], xa[m[p, 0], 1], xa[m[q, 0], 0], xa[m[q, 0], 1],
            xb[m[p, 1], 0], xb[m[p, 1], 1], xb[m[q, 1], 0], xb[m[q, 1], 1],
        )  # fmt: skip
        cnt, cost = _count_inliers(xa, xb, m, n, tx, ty, th, tol2, rot, cos_tol)
        if cnt > 0:
            nk = _keep(poses, counts, costs, nk, tx, ty, th, cnt, cost, tol)
    return nk
