"""numba kernels: candidate matches by nearest neighbours in descriptor space.

Distances: Hamming / number of bits for ``bsc`` (XOR + popcount on uint64 words), L1 for
``csc`` (abandoned early once above a bound). Conventions as
:mod:`laser_corners.matching.core` (A the query, B the other scan; a match is a pair of
indices).
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np
from numpy.typing import NDArray

from laser_corners.matching.kernel_args import KernelOptions, Side


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
def _opening_ok(
    open_a: NDArray[np.float64], i: int, open_b: NDArray[np.float64], j: int, max_open: float
) -> bool:
    """Opening angles within ``max_open`` degrees (unknown, NaN, openings always pass)."""
    d = abs(open_a[i] - open_b[j])
    return not d > max_open


@nb.njit(cache=True, nogil=True, inline="always")
def _insert(dd: NDArray[np.float64], idx: NDArray[np.int64], p: int, d: float, j: int) -> None:
    """Put distance ``d`` of keypoint ``j`` into the ascending list ``dd``/``idx`` at free slot
    ``p`` or below it (insertion sort: the larger entries above it move up one)."""
    while p > 0 and dd[p - 1] > d:
        dd[p] = dd[p - 1]
        idx[p] = idx[p - 1]
        p -= 1
    dd[p] = d
    idx[p] = j


@nb.njit(cache=True, nogil=True)
def _nearest_stream(
    kind: int, inv_bits: float, a: Side, b: Side, options: KernelOptions, out: NDArray[np.int64]
) -> int:
    """k nearest within ``max_distance`` without a distance matrix: each distance stops as
    soon as it exceeds the current k-th best (the result is that of exact distances)."""
    bits_a, vals_a, open_a = a.bits, a.values, a.opening
    bits_b, vals_b, open_b = b.bits, b.values, b.opening
    max_open, max_distance = options.max_opening_difference, options.max_distance
    na, nb_ = _count(a), _count(b)
    k = min(options.k_nearest, nb_)
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
            _insert(dd, idx, p, d, j)
        for q in range(cnt):
            out[n, 0] = i
            out[n, 1] = idx[q]
            n += 1
    return n


@nb.njit(cache=True, nogil=True)
def _nearest_matrix(
    kind: int, inv_bits: float, a: Side, b: Side, options: KernelOptions, out: NDArray[np.int64]
) -> int:
    """Candidate matches with Lowe's ratio test and/or the mutual check (distance matrix)."""
    # distances above `bound` are never kept, never decide a ratio test (the second nearest
    # is then beyond d1/ratio) and never win a column of the mutual check against a kept
    # match, so their computation may stop early: the result is that of exact distances
    bits_a, vals_a, open_a = a.bits, a.values, a.opening
    bits_b, vals_b, open_b = b.bits, b.values, b.opening
    max_open, max_distance = options.max_opening_difference, options.max_distance
    ratio, mutual = options.ratio, options.mutual
    na, nb_ = _count(a), _count(b)
    bound = max_distance / min(ratio, 1.0) if ratio > 0.0 else math.inf
    dist = np.empty((na, nb_))
    for i in range(na):
        for j in range(nb_):
            if _opening_ok(open_a, i, open_b, j, max_open):
                dist[i, j] = _distance(kind, bits_a, vals_a, i, bits_b, vals_b, j, inv_bits, bound)
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
    k = min(options.k_nearest, nb_) if ratio >= 1.0 else 1
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
            _insert(dd, idx, p, d, j)
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


@nb.njit(cache=True, nogil=True, inline="always")
def _count(side: Side) -> int:
    """Keypoints of a side (its descriptors: bits for bsc, values for csc)."""
    return max(side.bits.shape[0], side.values.shape[0])


@nb.njit(cache=True, nogil=True)
def candidate_matches(
    kind: int, inv_bits: float, a: Side, b: Side, options: KernelOptions, out: NDArray[np.int64]
) -> int:
    """Candidate matches by nearest neighbours in descriptor space; returns their count.

    For each keypoint of A its ``options.k_nearest`` nearest keypoints of B with a distance
    at most ``options.max_distance`` and an opening angle within
    ``options.max_opening_difference`` degrees; with ``options.ratio < 1`` the nearest is
    kept only when d1 <= ratio·d2 (Lowe's test; then only the nearest), with
    ``options.mutual`` only when A's keypoint is also the nearest of B's. ``kind`` (0: bsc,
    1: csc) and ``inv_bits`` (1 / number of bits) as :func:`_distance`. ``out`` (at least
    M_a·k_nearest rows, 2 columns) receives the pairs.
    """
    if _count(a) == 0 or _count(b) == 0:
        return 0
    if options.ratio >= 1.0 and not options.mutual:
        return _nearest_stream(kind, inv_bits, a, b, options, out)
    return _nearest_matrix(kind, inv_bits, a, b, options, out)
