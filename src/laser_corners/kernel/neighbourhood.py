"""Neighbourhood bounds: how far the arrival and departure neighbourhoods of p_j reach.

For every scale R_k the arrival (departure) neighbourhood of p_j is the run of points before
(after) p_j up to the first point farther than R_k from p_j, a gap (or, with the option
``max_gap_beams``, a run of more than that many gaps) or the scan's end. Two walks compute it
exactly, for all scales in one pass per side:

* :func:`counts`, for scans with a few dozen points within the largest scale and at most
  three sentinel scales: the distances of :data:`~laser_corners.kernel.simd.W` points at a time,
  three bit masks of the points farther than each radius
  (:func:`~laser_corners.kernel.simd.far_masks`), the count from the first set bit;
* :func:`reach`, with more sentinels: point by point, four steps per iteration,
  branch-free; it stores the running maximum of the squared distance, counted per scale
  afterwards (:func:`within`);
* :func:`walk`, for dense scans and gap bridging: jumps to near the previous point's bound
  when the boxes of the blocks on the way lie within the radius (a sparse table of block
  boxes, :func:`block_boxes`), skips aligned blocks of 64, 512 or 4096 beams whose box
  lies within it, and checks the other beams 16 at a time (up to 64 per step), so it costs
  O(blocks + points near the radii) instead of O(points within R).

:func:`prepare` makes the per-scan tables (validity, prefix sums), :func:`links` the
next/previous valid index (dense scans and gap bridging only).
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np
from numba.cpython.unsafe.numbers import leading_zeros, trailing_zeros
from numpy.typing import NDArray

from laser_corners.kernel.boxes import SHIFT as _SHIFT
from laser_corners.kernel.boxes import SPAN as _SPAN
from laser_corners.kernel.boxes import block_boxes
from laser_corners.kernel.boxes import box_d2 as _box_d2
from laser_corners.kernel.simd import W, far_masks

__all__ = [
    "PAD",
    "block_boxes",
    "counts",
    "extend",
    "links",
    "padded",
    "points_within",
    "prepare",
    "reach",
    "walk",
    "within",
]

_LEVELS = 4  # aligned block sizes of the sparse table: 8, 64, 512, 4096 beams (_SPAN = 3·3 + 1)
# the smallest level :func:`_skip` tries: 64 beams. Blocks of 8 are checked beam by beam
# instead, W at a time, up to _CHUNKS · W beams per step (:func:`_leading_within`): near the
# bound (the range noise's band, wider in beams the denser the scan) a box of 8 fails as
# often as it passes, and one far_masks costs about one box_d2 for twice the beams
_FINE = 1
_CHUNKS = 4
_BACKOFF = 24  # tries of :func:`_jump`: 0, 1, 3, 7, ... blocks short of the guess
ROW = 6  # values per index in the flat prefix sums of :func:`prepare`
PAD = W  # +inf entries before and after the padded coordinates of :func:`reach`, :func:`counts`


@nb.njit(cache=True, nogil=True, error_model="numpy")
def prepare(x: NDArray[np.float64], y: NDArray[np.float64]) -> tuple:
    """Validity, centroid, prefix sums of x, y, x², y², xy and the valid-point count: a flat
    array, :data:`ROW` values per index i = 0..N (the sums over indices < i), at ROW·i."""
    n = x.shape[0]
    valid = np.empty(n, dtype=np.bool_)
    ox = 0.0
    oy = 0.0
    n_valid = 0
    for i in range(n):
        ok = math.isfinite(x[i]) and math.isfinite(y[i])
        valid[i] = ok
        if ok:
            ox += x[i]
            oy += y[i]
            n_valid += 1
    if n_valid > 0:
        ox /= n_valid
        oy /= n_valid
    ps = np.empty((n + 1) * ROW)  # flat, ROW values per index (a row at ROW * i)
    ps[:ROW] = 0.0
    for i in range(n):
        r = ROW * i
        if valid[i]:
            xi = x[i] - ox
            yi = y[i] - oy
            ps[r + ROW + 0] = ps[r + 0] + xi
            ps[r + ROW + 1] = ps[r + 1] + yi
            ps[r + ROW + 2] = ps[r + 2] + xi * xi
            ps[r + ROW + 3] = ps[r + 3] + yi * yi
            ps[r + ROW + 4] = ps[r + 4] + xi * yi
            ps[r + ROW + 5] = ps[r + 5] + 1.0
        else:
            for c in range(6):
                ps[r + ROW + c] = ps[r + c]
    return valid, ox, oy, ps


@nb.njit(cache=True, nogil=True, error_model="numpy")
def links(valid: NDArray[np.bool_]) -> tuple:
    """Next/previous valid index of every index (N if none / -1 if none), for :func:`walk`."""
    n = valid.shape[0]
    next_valid = np.empty(n + 1, dtype=np.int64)
    prev_valid = np.empty(n, dtype=np.int64)
    next_valid[n] = n
    for i in range(n - 1, -1, -1):
        next_valid[i] = i if valid[i] else next_valid[i + 1]
    last = -1
    for i in range(n):
        if valid[i]:
            last = i
        prev_valid[i] = last
    return next_valid, prev_valid


@nb.njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _skip(
    box: NDArray[np.float64], i: int, step: int, n: int, xj: float, yj: float, r2: float
) -> int:
    """Size of the largest aligned block of 8**(a+1) beams (a >= :data:`_FINE`) starting at
    ``i`` (towards ``step``) that lies within ``r2`` of (xj, yj), or 0."""
    edge = i if step > 0 else i + 1  # aligned block boundary at the walk's near side
    for lev in range(_LEVELS - 1, _FINE - 1, -1):
        shift = _SHIFT * (lev + 1)
        size = 1 << shift
        if edge & (size - 1) != 0:
            continue
        b = (edge >> shift) - (0 if step > 0 else 1)
        if b < 0 or (b + 1) * size > n:
            continue
        if _box_d2(box, _SHIFT * lev, b << (_SHIFT * lev), xj, yj) <= r2:
            return size
    return 0


@nb.njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _run_within(
    box: NDArray[np.float64], b0: int, b1: int, xj: float, yj: float, r2: float
) -> bool:
    """Whether blocks ``b0`` to ``b1 - 1`` (of 8 beams) all lie within ``r2`` of (xj, yj), by
    their boxes: two overlapping sparse-table entries per 2**:data:`_SPAN` - 1 blocks."""
    while b0 < b1:  # from the far end, where a point beyond the radius would be
        length = min(b1 - b0, (1 << _SPAN) - 1)
        lev = 63 - leading_zeros(length)  # floor(log2(length))
        if _box_d2(box, lev, b1 - (1 << lev), xj, yj) > r2:
            return False
        if _box_d2(box, lev, b1 - length, xj, yj) > r2:
            return False
        b1 -= length
    return True


@nb.njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _jump(
    box: NDArray[np.float64], i: int, step: int, n: int, xj: float, yj: float, r2: float, g: int
) -> int:
    """Where a walk at block boundary ``i`` can go on, its whole way to near ``g`` (a guess
    of the bound, the previous point's) lying within ``r2``: the first of the block
    boundaries 0, 1, 3, 7, ..., 2**t - 1 blocks short of ``g`` (t < :data:`_BACKOFF`) whose
    run from ``i`` passes :func:`_run_within`; ``i`` if none does. (In a dense noisy scan the
    bound moves by hundreds of beams from one point to the next: the range noise along a
    wall spans that many beams.)"""
    if step > 0:
        b0 = i >> _SHIFT
        end = min((g + 1) >> _SHIFT, n >> _SHIFT)  # blocks wholly at or before g
        for t in range(_BACKOFF):
            e = end - ((1 << t) - 1)
            if e <= b0:
                return i
            if _run_within(box, b0, e, xj, yj, r2):
                return e << _SHIFT
        return i
    b1 = (i + 1) >> _SHIFT
    first = (max(g, 0) + 7) >> _SHIFT  # blocks wholly at or after g
    for t in range(_BACKOFF):
        s = first + ((1 << t) - 1)
        if s >= b1:
            return i
        if _run_within(box, s, b1, xj, yj, r2):
            return (s << _SHIFT) - 1
    return i


@nb.njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _leading_within(
    px: NDArray[np.float64],
    py: NDArray[np.float64],
    i: int,
    step: int,
    xj: float,
    yj: float,
    r2: float,
) -> int:
    """Number of leading beams from ``i`` towards ``step`` within ``r2`` of (xj, yj): up to
    the next block boundary when ``i`` is not on one, else up to :data:`_CHUNKS` · :data:`W`
    beams, :data:`W` at a time, up to the first beyond it; one
    :func:`~laser_corners.kernel.simd.far_masks` per :data:`W` beams on the padded coordinates
    (a gap is +inf: a chunk with a set bit ends the count, so the padding is never passed)."""
    if step > 0:
        room = (8 - (i & 7)) & 7
        if room > 0:
            mask = far_masks(px, py, i + PAD, xj, yj, r2, r2, r2)[0] | (1 << room)
            return trailing_zeros(mask)
        done = 0
        for _ in range(_CHUNKS):
            mask = far_masks(px, py, i + PAD + done, xj, yj, r2, r2, r2)[0]
            if mask != 0:
                return done + trailing_zeros(mask)
            done += W
        return done
    room = (i + 1) & 7
    if room > 0:
        mask = far_masks(px, py, i + PAD - (W - 1), xj, yj, r2, r2, r2)[0]
        mask |= 1 << (W - 1 - room)
        return leading_zeros(mask) - (64 - W)
    done = 0
    for _ in range(_CHUNKS):
        mask = far_masks(px, py, i + PAD - (W - 1) - done, xj, yj, r2, r2, r2)[0]
        if mask != 0:
            return done + leading_zeros(mask) - (64 - W)
        done += W
    return done


@nb.njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _last_valid(i: int, step: int, valid, next_valid, prev_valid) -> int:
    """The last valid beam of a walk towards ``step`` that has passed beam ``i``: ``i``, or,
    when it is a bridged gap (a skipped block ending in one), the valid beam before it."""
    if valid[i]:
        return i
    return prev_valid[i] if step > 0 else next_valid[i]


@nb.njit(cache=True, nogil=True, error_model="numpy")
def walk(
    j: int,
    step: int,
    x: NDArray[np.float64],
    y: NDArray[np.float64],
    valid: NDArray[np.bool_],
    links: tuple,
    box: NDArray[np.float64],
    r2: NDArray[np.float64],
    max_gap: int,
    bound: NDArray[np.int64],
) -> None:
    """Farthest valid index of the neighbourhood of p_j for every scale, one side.

    Walks from ``j`` towards ``step`` (-1 arrival, +1 departure) up to the first point
    farther than R_k from p_j, the first run of more than ``max_gap`` invalid beams, or the
    scan's end; ``bound[k]`` is the last valid index before that point. ``links``: the
    next/previous valid index (:func:`links`) and the padded coordinates (:func:`padded`).

    On entry ``bound[k]`` is a guess (any integer; the previous point's bound is a good one):
    at the first block boundary within R_k the walk jumps to near it when every box on the
    way lies within R_k (:func:`_jump`). Whole blocks within R_k are skipped
    (:func:`_skip`), the other beams are checked :data:`W` at a time, up to
    :data:`_CHUNKS` · :data:`W` per step (:func:`_leading_within`), and only the first beam
    farther than R_k (or a gap) point by point. The result does not depend on the guess.
    """
    next_valid, prev_valid, px, py = links
    n = x.shape[0]
    n_scales = r2.shape[0]
    xj = x[j]
    yj = y[j]
    k = 0
    last = j
    i = j + step
    tried = -1  # the last scale whose guess was tried
    while k < n_scales and 0 <= i < n:
        if not valid[i]:  # a run of gaps: bridge it if short and a point follows
            g = next_valid[i] if step > 0 else prev_valid[i]
            if g < 0 or g >= n or abs(g - i) >= max_gap + 1:
                break
            i = g
            continue
        if tried < k and ((i if step > 0 else i + 1) & 7) == 0:
            tried = k
            to = _jump(box, i, step, n, xj, yj, r2[k], bound[k])
            if to != i:  # every beam up to ``to`` lies within R_k (and every larger scale)
                i = to
                last = _last_valid(i - step, step, valid, next_valid, prev_valid)
                continue
        size = _skip(box, i, step, n, xj, yj, r2[k])
        if size > 0:  # a whole block within R_k (and every larger scale)
            i += step * size
            last = _last_valid(i - step, step, valid, next_valid, prev_valid)
            continue
        ahead = _leading_within(px, py, i, step, xj, yj, r2[k])
        if ahead > 0:  # valid beams within R_k
            i += step * ahead
            last = i - step
            continue
        d2 = (x[i] - xj) ** 2 + (y[i] - yj) ** 2  # farther than R_k: which scales end here
        while k < n_scales and d2 > r2[k]:
            bound[k] = last
            k += 1
        last = i
        i += step
    while k < n_scales:
        bound[k] = last
        k += 1


@nb.njit(cache=True, nogil=True, error_model="numpy")
def padded(x: NDArray[np.float64], y: NDArray[np.float64], valid: NDArray[np.bool_]) -> tuple:
    """``x``, ``y`` with gaps and :data:`PAD` entries before and after set to +inf (far from
    all points), in one pass."""
    n = x.shape[0]
    px = np.empty(n + 2 * PAD)
    py = np.empty(n + 2 * PAD)
    px[:PAD] = math.inf
    py[:PAD] = math.inf
    px[n + PAD :] = math.inf
    py[n + PAD :] = math.inf
    for i in range(n):
        ok = valid[i]
        px[i + PAD] = x[i] if ok else math.inf
        py[i + PAD] = y[i] if ok else math.inf
    return px, py


@nb.njit(cache=True, nogil=True, error_model="numpy", inline="always")
def reach(
    j: int,
    step: int,
    px: NDArray[np.float64],
    py: NDArray[np.float64],
    radii: tuple,
    running_max: NDArray[np.float64],
    store: bool,
) -> tuple:
    """Walk from p_j towards ``step`` up to the largest scale, point by point.

    Follows the running maximum of the squared distance to p_j (a gap, or the scan's end, is
    infinitely far: ``px``, ``py`` from :func:`padded`) until it exceeds ``r2_max``; returns
    the number of steps within and the numbers of leading steps within sqrt(``r2_a``) and
    sqrt(``r2_b``) (two more sentinel scales, counted on the way); ``radii`` is
    (``r2_max``, ``r2_a``, ``r2_b``). With ``store`` the running
    maximum of every step goes to ``running_max`` (for :func:`within`). Four steps per
    iteration, whose running maxima are all computed from the previous one (a short
    dependency chain, no branch per point). For dense scans :func:`walk` is used instead.
    """
    r2_max, r2_a, r2_b = radii
    c = j + PAD
    xj = px[c]
    yj = py[c]
    i = c + step
    m = 0.0
    steps = 0
    ca = 0
    cb = 0
    while True:
        d0 = (px[i] - xj) ** 2 + (py[i] - yj) ** 2
        d1 = (px[i + step] - xj) ** 2 + (py[i + step] - yj) ** 2
        d2 = (px[i + 2 * step] - xj) ** 2 + (py[i + 2 * step] - yj) ** 2
        d3 = (px[i + 3 * step] - xj) ** 2 + (py[i + 3 * step] - yj) ** 2
        d01 = max(d0, d1)
        d012 = max(d01, d2)
        m0 = max(m, d0)
        m1 = max(m, d01)
        m2 = max(m, d012)
        m3 = max(m, max(d012, d3))
        if store:
            running_max[steps] = m0
            running_max[steps + 1] = m1
            running_max[steps + 2] = m2
            running_max[steps + 3] = m3
        ca += int(m0 <= r2_a) + int(m1 <= r2_a) + int(m2 <= r2_a) + int(m3 <= r2_a)
        cb += int(m0 <= r2_b) + int(m1 <= r2_b) + int(m2 <= r2_b) + int(m3 <= r2_b)
        if m3 > r2_max:
            last = int(m0 <= r2_max) + int(m1 <= r2_max) + int(m2 <= r2_max)
            return steps + last, ca, cb
        m = m3
        steps += 4
        i += 4 * step


@nb.njit(cache=True, nogil=True, error_model="numpy", inline="always")
def counts(
    j: int,
    step: int,
    px: NDArray[np.float64],
    py: NDArray[np.float64],
    r2_max: float,
    r2_a: float,
    r2_b: float,
) -> tuple:
    """What :func:`reach` returns without ``store``: the numbers of leading steps from p_j
    towards ``step`` within sqrt(``r2_max``), sqrt(``r2_a``) and sqrt(``r2_b``) (each at most
    ``r2_max``), :data:`W` points at a time.

    A count is the index of the first point farther than the radius (a gap or the scan's end
    is +inf in ``px``, ``py`` from :func:`padded`), which is where the running maximum of
    :func:`reach` first exceeds it: the lowest set bit of a mask (departure), the highest
    (arrival, whose chunk ends next to p_j). Same comparisons of the same squared distances,
    so the same counts; a chunk is loaded only while every point so far is within the
    largest radius (the padding, :data:`PAD` >= :data:`W`, stops it at the scan's ends).
    """
    c = j + PAD
    xj = px[c]
    yj = py[c]
    ca = -1
    cb = -1
    done = 0
    while True:
        base = c + 1 + done if step > 0 else c - W - done
        ma, mb, mc = far_masks(px, py, base, xj, yj, r2_a, r2_b, r2_max)
        if step > 0:
            za, zb, zc = trailing_zeros(ma), trailing_zeros(mb), trailing_zeros(mc)
        else:  # bit W-1 is the point next to p_j
            za = leading_zeros(ma) - (64 - W)
            zb = leading_zeros(mb) - (64 - W)
            zc = leading_zeros(mc) - (64 - W)
        if ca < 0 and ma != 0:
            ca = done + za
        if cb < 0 and mb != 0:
            cb = done + zb
        if mc != 0:
            return done + zc, ca, cb
        done += W


@nb.njit(cache=True, nogil=True, error_model="numpy", inline="always")
def within(running_max: NDArray[np.float64], steps: int, r2: float) -> int:
    """Number of leading steps of a :func:`reach` walk within sqrt(``r2``): a branch-free
    binary search (the running maximum is non-decreasing)."""
    lo = 0
    size = steps
    while size > 0:
        half = size >> 1
        ok = int(running_max[lo + half] <= r2)  # arithmetic, not a branch
        lo += (half + 1) * ok
        size = half - (2 * half + 1 - size) * ok
    return lo


@nb.njit(cache=True, nogil=True, error_model="numpy", inline="always")
def extend(
    j: int, step: int, px: NDArray[np.float64], py: NDArray[np.float64], lo: int, hi: int, r2: float
) -> int:
    """Number of leading steps of a :func:`reach` walk from p_j within sqrt(``r2``), given
    that the first ``lo`` steps are within it and at most ``hi`` are (the counts of a smaller
    and a larger scale): only the steps after ``lo`` are looked at, point by point.

    Equal to :func:`within` on the running maxima: the first ``lo`` distances are at most
    the smaller radius, so the running maximum at a later step is within sqrt(``r2``)
    exactly when every distance up to it is. :data:`~laser_corners.kernel.simd.W` points at a time
    with :func:`~laser_corners.kernel.simd.far_masks`, as :func:`counts` (the first ``lo`` steps
    are valid points, so the chunks stay within the padding).
    """
    c = j + PAD
    xj = px[c]
    yj = py[c]
    if lo >= hi:
        return lo
    done = lo
    while done < hi:  # W points at a time, as counts()
        base = c + 1 + done if step > 0 else c - W - done
        mask = far_masks(px, py, base, xj, yj, r2, r2, r2)[0]
        if mask != 0:
            z = trailing_zeros(mask) if step > 0 else leading_zeros(mask) - (64 - W)
            return min(done + z, hi)
        done += W
    return hi


@nb.njit(cache=True, nogil=True, error_model="numpy")
def points_within(x, y, valid, radius: float) -> float:
    """Estimated number of points within ``radius`` along the scan: radius / mean step."""
    total = 0.0
    count = 0
    for i in range(x.shape[0] - 1):
        if valid[i] and valid[i + 1]:
            total += abs(x[i + 1] - x[i]) + abs(y[i + 1] - y[i])  # L1: a rough estimate
            count += 1
    return radius * count / total if total > 0.0 else 0.0
