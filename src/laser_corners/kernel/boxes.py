"""Block boxes of the dense neighbourhood walk: a sparse table of oriented bounding boxes.

:func:`~laser_corners.kernel.neighbourhood.walk` skips a run of beams when every point of it
lies within R_k of p_j, which it learns from a box that holds the run's points: the distance
from p_j to the box's farthest corner bounds every point's (:func:`box_d2`). With an
axis-aligned box that bound is loose by about the range noise on an oblique wall (the largest
x and the largest y come from different points), so the walk had to check point by point every
beam whose distance lies within the noise of R_k, a band that widens with the beam density
(about 200 beams at 1,000,000 beams, σ 0.001 m). Here a box is a rectangle in the frame of the
local wall direction u (the direction between the centroids of the two halves of a window of
:data:`WINDOW` beams around the block, from running sums): seen from a point on the same wall,
the farthest point of a run is the one farthest along u, which is the rectangle's far side, so
the bound is tight up to the rectangle's width squared over 2R (micrometres): the walk stops
within a block or two of the first point beyond R_k at any density.

Entry (l, b) of the table bounds the valid beams 8b to 8(b + 2**l) - 1; an entry of two
children takes the orientation of the block at its middle and the children's corners
projected on it (the orientation varies slowly along a wall, so little is lost). Scans with few
points within the largest scale (bridging on a sparse scan) get axis-aligned boxes (u = (1, 0),
children merged by min/max).
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np
from numpy.typing import NDArray

__all__ = ["SHIFT", "SPAN", "WINDOW", "block_boxes", "box_d2"]

SHIFT = 3  # log2 of the block size (8 beams) and of the ratio of aligned block sizes
SPAN = 10  # levels of the sparse table: runs of 1 to 512 blocks
WINDOW = 4096  # beams of the window whose halves' centroids give a block's direction
NCOL = 6  # per entry: ux, uy, along-u min and max, across-u min and max


@nb.njit(cache=True, nogil=True, error_model="numpy")
def _long_gaps(valid: NDArray[np.bool_], max_gap: int) -> NDArray[np.bool_]:
    """Whether each beam is invalid and in a run of more than ``max_gap`` invalid beams (one
    that ends a neighbourhood), in one pass."""
    n = valid.shape[0]
    ends = np.zeros(n, dtype=np.bool_)
    i = 0
    while i < n:
        if valid[i]:
            i += 1
            continue
        run_end = i
        while run_end < n and not valid[run_end]:
            run_end += 1
        if run_end - i > max_gap:
            ends[i:run_end] = True
        i = run_end
    return ends


@nb.njit(cache=True, nogil=True, error_model="numpy")
def _directions(x, y, valid, n_blocks: int, oriented: bool) -> NDArray[np.float64]:
    """Unit direction of every block of 8 beams: (1, 0) unless ``oriented``; else from the
    centroid of the first half to that of the second half of the :data:`WINDOW` beams around
    it (running sums of the valid points; (1, 0) when a half is empty or both coincide)."""
    n = x.shape[0]
    u = np.empty((max(n_blocks, 1), 2))
    u[:, 0] = 1.0
    u[:, 1] = 0.0
    if not oriented:
        return u
    cx = np.zeros(n + 1)
    cy = np.zeros(n + 1)
    cn = np.zeros(n + 1)
    for i in range(n):
        ok = valid[i]
        cx[i + 1] = cx[i] + (x[i] if ok else 0.0)
        cy[i + 1] = cy[i] + (y[i] if ok else 0.0)
        cn[i + 1] = cn[i] + (1.0 if ok else 0.0)
    half = WINDOW // 2
    for b in range(n_blocks):
        m = (b << SHIFT) + 4
        lo = max(m - half, 0)
        hi = min(m + half, n)
        mid = (lo + hi) >> 1
        n1 = cn[mid] - cn[lo]
        n2 = cn[hi] - cn[mid]
        if n1 > 0.0 and n2 > 0.0:
            ux = (cx[hi] - cx[mid]) / n2 - (cx[mid] - cx[lo]) / n1
            uy = (cy[hi] - cy[mid]) / n2 - (cy[mid] - cy[lo]) / n1
            norm = math.sqrt(ux * ux + uy * uy)
            if norm > 0.0:
                u[b, 0] = ux / norm
                u[b, 1] = uy / norm
    return u


@nb.njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _set(box, lev: int, b: int, ux: float, uy: float, a0, a1, c0, c1) -> None:
    box[lev, b, 0] = ux
    box[lev, b, 1] = uy
    box[lev, b, 2] = a0
    box[lev, b, 3] = a1
    box[lev, b, 4] = c0
    box[lev, b, 5] = c1


@nb.njit(cache=True, nogil=True, error_model="numpy")
def block_boxes(
    x: NDArray[np.float64],
    y: NDArray[np.float64],
    valid: NDArray[np.bool_],
    max_gap: int,
    oriented: bool = True,
) -> NDArray[np.float64]:
    """Oriented boxes of runs of 2**l consecutive blocks of 8 beams, a sparse table of shape
    (:data:`SPAN`, N // 8, 6): entry (l, b) = (ux, uy, a0, a1, c0, c1), the rectangle
    a0 <= p·u <= a1, c0 <= p·v <= c1 (v = (-uy, ux)) holding the valid beams 8b to
    8(b + 2**l) - 1 (filled for b + 2**l <= N // 8). A run holding a beam of a run of more than
    ``max_gap`` invalid beams (which ends a neighbourhood; every gap when ``max_gap`` is 0) gets
    an infinite box (never skipped); shorter gaps, bridged by the walk, are left out (a block of
    such gaps only: an empty box, +inf to -inf, never skipped either). ``oriented``: boxes in
    the local wall direction (dense scans), else axis-aligned."""
    n = x.shape[0]
    nb0 = n >> SHIFT
    box = np.empty((SPAN, max(nb0, 1), NCOL))
    ends = _long_gaps(valid, max_gap)
    u = _directions(x, y, valid, nb0, oriented)
    for b in range(nb0):
        ux, uy = u[b, 0], u[b, 1]
        a0, a1, c0, c1 = math.inf, -math.inf, math.inf, -math.inf
        for i in range(b << SHIFT, (b + 1) << SHIFT):
            if ends[i]:
                a0, a1, c0, c1 = -math.inf, math.inf, -math.inf, math.inf
                break
            if valid[i]:
                a = x[i] * ux + y[i] * uy
                c = y[i] * ux - x[i] * uy
                a0, a1, c0, c1 = min(a0, a), max(a1, a), min(c0, c), max(c1, c)
        _set(box, 0, b, ux, uy, a0, a1, c0, c1)
    for lev in range(1, SPAN):
        half = 1 << (lev - 1)
        for b in range(nb0 - (1 << lev) + 1):
            o = b + half  # the orientation of the block at the middle
            _merge(box, lev, b, b + half, u[o, 0], u[o, 1], oriented)
    return box


@nb.njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _merge(box, lev: int, p: int, q: int, ux: float, uy: float, oriented: bool) -> None:
    """Entry (lev, p) from its children (lev - 1, p) and (lev - 1, q), in direction u: the
    children's corners projected on u and v (min/max of the children when axis-aligned). An
    infinite child makes it infinite; an empty one is left out."""
    c = lev - 1
    if not oriented or box[c, p, 3] == math.inf or box[c, q, 3] == math.inf:
        a0, a1 = min(box[c, p, 2], box[c, q, 2]), max(box[c, p, 3], box[c, q, 3])
        c0, c1 = min(box[c, p, 4], box[c, q, 4]), max(box[c, p, 5], box[c, q, 5])
        _set(box, lev, p, ux, uy, a0, a1, c0, c1)
        return
    a0, a1, c0, c1 = math.inf, -math.inf, math.inf, -math.inf
    for s in (p, q):
        if box[c, s, 2] > box[c, s, 3]:  # empty
            continue
        sx, sy = box[c, s, 0], box[c, s, 1]
        uu = sx * ux + sy * uy  # the child's u and v in this frame
        uv = sy * ux - sx * uy
        vu = sx * uy - sy * ux
        vv = sx * ux + sy * uy
        for ca in (box[c, s, 2], box[c, s, 3]):
            for cc in (box[c, s, 4], box[c, s, 5]):
                a = ca * uu + cc * vu
                v = ca * uv + cc * vv
                a0, a1, c0, c1 = min(a0, a), max(a1, a), min(c0, v), max(c1, v)
    _set(box, lev, p, ux, uy, a0, a1, c0, c1)


@nb.njit(cache=True, nogil=True, error_model="numpy", inline="always")
def box_d2(box: NDArray[np.float64], lev: int, b: int, xj: float, yj: float) -> float:
    """An upper bound of the kernel's squared distance from (xj, yj) to every point of entry
    (lev, b): the squared distance to the rectangle's farthest corner, each side lengthened
    by 1e-9·(1 + |xj| + |yj|) m, far more than the rounding of the projections (~1e-15
    relative per operation, a few dozen operations deep), so the bound also holds for the
    kernel's rounded d2 of each point."""
    ux = box[lev, b, 0]
    uy = box[lev, b, 1]
    ca = xj * ux + yj * uy
    cc = yj * ux - xj * uy
    eps = 1e-9 * (1.0 + abs(xj) + abs(yj))
    da = max(abs(box[lev, b, 2] - ca), abs(box[lev, b, 3] - ca)) + eps
    dc = max(abs(box[lev, b, 4] - cc), abs(box[lev, b, 5] - cc)) + eps
    return da * da + dc * dc
