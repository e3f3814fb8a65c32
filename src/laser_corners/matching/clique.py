"""numba kernel of the matcher's other verification: FALKO's CCDA, a maximum clique of
pairwise-consistent matches (conventions as :mod:`laser_corners.matching.core`)."""

from __future__ import annotations

import numba as nb
import numpy as np
from numpy.typing import NDArray

from laser_corners.matching.core import _pair_fast, _prepare, cos_tolerance
from laser_corners.matching.kernel_args import KernelOptions, Side
from laser_corners.matching.nearest import _popcount

# exact maximum clique up to this many candidate matches (bitsets of one uint64 word)
CLIQUE_EXACT_MAX = 64
# node expansions of the exact clique search before it returns its best clique so far
CLIQUE_BUDGET = 20000


@nb.njit(cache=True, nogil=True)
def max_clique(
    a: Side,
    b: Side,
    m: NDArray[np.int64],
    n: int,
    members: NDArray[np.int64],
    options: KernelOptions,
) -> int:
    """Largest set of pairwise-consistent matches (FALKO's CCDA); returns its size.

    Exact branch and bound on bitsets when n <= 64 (stopping after ``CLIQUE_BUDGET`` node
    expansions with the best clique so far), greedy by degree otherwise. ``members``
    receives the indices of the clique's matches.
    """
    if n == 0:
        return 0
    da, db, rot = _prepare(a.xy, b.xy, m, n, a.orientation, b.orientation)
    tol = options.tolerance
    cos_tol = cos_tolerance(options.angle_tolerance)
    if n > CLIQUE_EXACT_MAX:
        return _greedy_clique(da, db, rot, m, n, tol, cos_tol, members)
    return _exact_clique(da, db, rot, m, n, tol, cos_tol, members)


@nb.njit(cache=True, nogil=True)
def _greedy_clique(da, db, rot, m, n: int, tol: float, cos_tol: float, members) -> int:
    """Greedy clique by degree (many matches): the consistency graph as a boolean matrix,
    vertices taken in decreasing degree when consistent with all taken so far."""
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


@nb.njit(cache=True, nogil=True)
def _exact_clique(da, db, rot, m, n: int, tol: float, cos_tol: float, members) -> int:
    """Exact branch and bound on 64-bit sets (n <= 64), depth first, stopping after
    ``CLIQUE_BUDGET`` node expansions with the best clique so far."""
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
