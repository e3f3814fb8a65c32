"""numba kernels of the matcher: descriptor nearest neighbours, RANSAC, maximum clique, WLS.

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
# exact maximum clique up to this many candidate matches (bitsets of one uint64 word)
CLIQUE_EXACT_MAX = 64
# node expansions of the exact clique search before it returns its best clique so far
CLIQUE_BUDGET = 20000


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
) -> int:
    """Candidate matches by nearest neighbours in descriptor space; returns their count.

    For each keypoint of A its ``k_nearest`` nearest keypoints of B with a distance at most
    ``max_distance``; with ``ratio < 1`` the nearest is kept only when d1 <= ratio·d2
    (Lowe's test; then only the nearest), with ``mutual`` only when A's keypoint is also the
    nearest of B's. ``out`` (at least M_a·k_nearest rows, 2 columns) receives the pairs.
    """
    na = max(bits_a.shape[0], vals_a.shape[0])
    nb_ = max(bits_b.shape[0], vals_b.shape[0])
    if na == 0 or nb_ == 0:
        return 0
    # distances above `bound` are never kept, never decide a ratio test (the second nearest
    # is then beyond d1/ratio) and never win a column of the mutual check against a kept
    # match, so their computation may stop early: the result is that of exact distances
    bound = max_distance / min(ratio, 1.0) if ratio > 0.0 else math.inf
    dist = np.empty((na, nb_))
    for i in range(na):
        for j in range(nb_):
            dist[i, j] = _distance(kind, bits_a, vals_a, i, bits_b, vals_b, j, inv_bits, bound)
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
def ransac(
    xa: NDArray[np.float64], xb: NDArray[np.float64], m: NDArray[np.int64], n: int,
    tol: float, min_sep: float, iterations: int, seed: int,
    oa: NDArray[np.float64], ob: NDArray[np.float64], angle_tol: float,
) -> tuple[float, float, float, int]:  # fmt: skip
    """Best two-point SE(2) hypothesis (most inliers within ``tol``; ties: lower cost).

    All pairs of matches are tried when there are at most ``iterations`` of them, else
    ``iterations`` pairs drawn by a xorshift generator seeded with ``seed`` (deterministic).
    Returns ``(tx, ty, θ, n_inliers)``; n_inliers 0 when no hypothesis was valid.
    """
    best = (0.0, 0.0, 0.0)
    best_n = 0
    best_cost = math.inf
    tol2 = tol * tol
    da, db, rot = _prepare(xa, xb, m, n, oa, ob)
    cos_tol = math.cos(angle_tol) if angle_tol < math.pi else -2.0
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
        if cnt > best_n or (cnt == best_n and cost < best_cost):
            best_n = cnt
            best_cost = cost
            best = (tx, ty, th)
    return best[0], best[1], best[2], best_n


@nb.njit(cache=True, nogil=True)
def max_clique(
    xa: NDArray[np.float64], xb: NDArray[np.float64], m: NDArray[np.int64], n: int,
    tol: float, min_sep: float, members: NDArray[np.int64],
    oa: NDArray[np.float64], ob: NDArray[np.float64], angle_tol: float,
) -> int:  # fmt: skip
    """Largest set of pairwise-consistent matches (FALKO's CCDA); returns its size.

    Exact branch and bound on bitsets when n <= 64 (stopping after ``CLIQUE_BUDGET`` node
    expansions with the best clique so far), greedy by degree otherwise. ``members``
    receives the indices of the clique's matches.
    """
    if n == 0:
        return 0
    da, db, rot = _prepare(xa, xb, m, n, oa, ob)
    cos_tol = math.cos(angle_tol) if angle_tol < math.pi else -2.0
    if n > CLIQUE_EXACT_MAX:
        adj_ok = np.zeros((n, n), dtype=np.bool_)
        deg = np.zeros(n, dtype=np.int64)
        for p in range(n):
            for q in range(p + 1, n):
                if _pair_fast(da, db, rot, m, p, q, tol, 0.0, cos_tol):
                    adj_ok[p, q] = adj_ok[q, p] = True
                    deg[p] += 1
                    deg[q] += 1
        order = np.argsort(-deg, kind="mergesort")
        size = 0
        for v in order:
            ok = True
            for r in range(size):
                if not adj_ok[v, members[r]]:
                    ok = False
                    break
            if ok:
                members[size] = v
                size += 1
        return size
    adj = np.zeros(n, dtype=np.uint64)
    one = np.uint64(1)
    for p in range(n):
        for q in range(p + 1, n):
            if _pair_fast(da, db, rot, m, p, q, tol, 0.0, cos_tol):
                adj[p] |= one << np.uint64(q)
                adj[q] |= one << np.uint64(p)
    full = np.uint64(0xFFFFFFFFFFFFFFFF) if n == 64 else (one << np.uint64(n)) - one
    stack_p = np.empty(n + 2, dtype=np.uint64)
    stack_r = np.empty(n + 2, dtype=np.uint64)
    stack_s = np.empty(n + 2, dtype=np.int64)
    # depth-first: each frame holds a candidate set P, the clique R and its size
    top = 0
    stack_p[0] = full
    stack_r[0] = np.uint64(0)
    stack_s[0] = 0
    best_r = np.uint64(0)
    best_s = 0
    budget = CLIQUE_BUDGET
    while top >= 0 and budget > 0:
        budget -= 1
        pset = stack_p[top]
        r = stack_r[top]
        s = stack_s[top]
        if pset == np.uint64(0) or s + _popcount(pset) <= best_s:
            if s > best_s:
                best_s = s
                best_r = r
            top -= 1
            continue
        # lowest vertex v of P: replace the frame by "v excluded", push "v included"
        low = pset & (~pset + one)
        v = _popcount(low - one)
        stack_p[top] = pset & ~low
        top += 1
        stack_p[top] = pset & adj[v]
        stack_r[top] = r | low
        stack_s[top] = s + 1
    size = 0
    for v in range(n):
        if (best_r >> np.uint64(v)) & one:
            members[size] = v
            size += 1
    return size
