"""Descriptors and a batch matcher for the place-recognition evaluation (one query, many scans).

Every method of :mod:`laser_corners.eval.loops` goes through the same descriptor and matcher,
so the comparison is about the keypoints. The work is split so that each scan is described
once and the pair loop is one numba call per query:

1. :func:`~laser_corners.eval.loop_descriptors.build_bank` describes every keypoint of every
   scan once (a shape-context histogram aligned with the keypoint's orientation).
2. :func:`score_query` registers one query against many candidate scans (``numba.prange``
   over the candidates). Per pair: each query keypoint keeps its ``k_best`` nearest candidate
   keypoints in descriptor space (L1 distance below ``max_descriptor_distance``, opening angles
   within ``max_opening_difference_deg``); every two tentative matches whose inter-keypoint
   distances agree give an SE(2) hypothesis (two-point alignment); a match is an inlier of a
   hypothesis when the moved query keypoint lies within ``inlier_distance`` of its candidate
   keypoint and the orientations agree within ``max_orientation_difference_deg``. The best
   hypothesis (most inliers, then smallest residual) is refined by least squares on its
   inliers and its inliers recounted. Exhaustive over hypotheses, hence deterministic.

The pose returned is the query's sensor pose in the candidate's sensor frame (``b = R a + t``
for a query point ``a`` and its candidate point ``b``), the convention of
:func:`laser_corners.eval.poses.relative_pose` (candidate pose ⊖ ... ⊕ query pose).

This is the smallest self-contained matcher the evaluation needs; it is meant to be swapped
for :mod:`laser_corners.matching`'s batch call when that exists (one function,
:func:`score_query`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba as nb
import numpy as np
from numpy.typing import NDArray

from laser_corners.eval.loop_descriptors import KeypointBank

__all__ = ["MatchOptions", "score_pairs", "score_query"]


@dataclass(frozen=True)
class MatchOptions:
    """Matcher settings of :func:`score_query` (see the module docstring).

    Attributes
    ----------
    k_best : int
        Tentative matches kept per query keypoint.
    max_descriptor_distance : float
        Largest L1 distance between two descriptors (histograms sum to 1, so at most 2).
    max_opening_difference_deg : float
        Largest difference of the opening angles of two matched keypoints, degrees.
    inlier_distance : float
        A moved query keypoint within this of its candidate keypoint is an inlier, metres.
    max_orientation_difference_deg : float
        Largest orientation difference of an inlier after the rotation, degrees.
    min_pair_distance : float
        Two keypoints closer than this do not make a hypothesis (ill-conditioned), metres.
    """

    k_best: int = 2
    max_descriptor_distance: float = 0.7
    max_opening_difference_deg: float = 20.0
    inlier_distance: float = 0.08
    max_orientation_difference_deg: float = 15.0
    min_pair_distance: float = 0.3

    def as_array(self) -> NDArray[np.float64]:
        """The settings as the float vector the numba kernel takes."""
        return np.array(
            [
                self.k_best,
                self.max_descriptor_distance,
                self.max_opening_difference_deg,
                self.inlier_distance,
                math.radians(self.max_orientation_difference_deg),
                self.min_pair_distance,
            ],
            dtype=np.float64,
        )


@nb.njit(cache=True, nogil=True)
def _wrap(a: float) -> float:
    return a - 2.0 * math.pi * math.floor((a + math.pi) / (2.0 * math.pi))


@nb.njit(cache=True, nogil=True)
def _tentative(
    qlo: int, qhi: int, clo: int, chi: int, opening: NDArray[np.float64],
    desc: NDArray[np.float64], opt: NDArray[np.float64],
    out_i: NDArray[np.int64], out_j: NDArray[np.int64],
) -> int:  # fmt: skip
    """The ``k_best`` nearest candidate keypoints of each query keypoint (global indices)."""
    k_best = int(opt[0])
    d_max = opt[1]
    best_d = np.empty(k_best)
    best_j = np.empty(k_best, dtype=np.int64)
    n = 0
    n_dim = desc.shape[1]
    for i in range(qlo, qhi):
        for k in range(k_best):
            best_d[k] = d_max
            best_j[k] = -1
        for j in range(clo, chi):
            if abs(opening[i] - opening[j]) > opt[2]:
                continue
            bound = best_d[k_best - 1]
            d = 0.0
            for b in range(n_dim):
                d += abs(desc[i, b] - desc[j, b])
                if d >= bound:
                    break
            if d >= bound:
                continue
            k = k_best - 1  # insertion into the sorted k-best list
            while k > 0 and best_d[k - 1] > d:
                best_d[k] = best_d[k - 1]
                best_j[k] = best_j[k - 1]
                k -= 1
            best_d[k] = d
            best_j[k] = j
        for k in range(k_best):
            if best_j[k] >= 0:
                out_i[n] = i
                out_j[n] = best_j[k]
                n += 1
    return n


@nb.njit(cache=True, nogil=True)
def _count(
    th: float, tx: float, ty: float, mi: NDArray[np.int64], mj: NDArray[np.int64], n: int,
    xy: NDArray[np.float64], ori: NDArray[np.float64], opt: NDArray[np.float64],
    used_q: NDArray[np.int64], used_c: NDArray[np.int64], qlo: int, clo: int, stamp: int,
    flags: NDArray[np.bool_],
) -> tuple[int, float]:  # fmt: skip
    """Inliers of the hypothesis (each keypoint used once) and their summed squared error."""
    c, s = math.cos(th), math.sin(th)
    eps2 = opt[3] * opt[3]
    count = 0
    sse = 0.0
    for m in range(n):
        flags[m] = False
        i, j = mi[m], mj[m]
        if used_q[i - qlo] == stamp or used_c[j - clo] == stamp:
            continue
        dx = c * xy[i, 0] - s * xy[i, 1] + tx - xy[j, 0]
        dy = s * xy[i, 0] + c * xy[i, 1] + ty - xy[j, 1]
        e2 = dx * dx + dy * dy
        if e2 > eps2 or abs(_wrap(ori[j] - ori[i] - th)) > opt[4]:
            continue
        used_q[i - qlo] = stamp
        used_c[j - clo] = stamp
        flags[m] = True
        count += 1
        sse += e2
    return count, sse


@nb.njit(cache=True, nogil=True)
def _fit(
    mi: NDArray[np.int64], mj: NDArray[np.int64], flags: NDArray[np.bool_], n: int,
    xy: NDArray[np.float64],
) -> tuple[float, float, float]:  # fmt: skip
    """Least-squares SE(2) ``b = R a + t`` over the flagged matches (closed form)."""
    ax = ay = bx = by = 0.0
    w = 0
    for m in range(n):
        if flags[m]:
            ax += xy[mi[m], 0]
            ay += xy[mi[m], 1]
            bx += xy[mj[m], 0]
            by += xy[mj[m], 1]
            w += 1
    ax /= w
    ay /= w
    bx /= w
    by /= w
    sxx = sxy = 0.0
    for m in range(n):
        if flags[m]:
            px, py = xy[mi[m], 0] - ax, xy[mi[m], 1] - ay
            qx, qy = xy[mj[m], 0] - bx, xy[mj[m], 1] - by
            sxx += px * qx + py * qy
            sxy += px * qy - py * qx
    th = math.atan2(sxy, sxx)
    c, s = math.cos(th), math.sin(th)
    return th, bx - (c * ax - s * ay), by - (s * ax + c * ay)


@nb.njit(cache=True, nogil=True)
def _register_pair(
    q: int, c: int, offsets: NDArray[np.int64], xy: NDArray[np.float64],
    ori: NDArray[np.float64], opening: NDArray[np.float64], desc: NDArray[np.float64],
    opt: NDArray[np.float64], pose: NDArray[np.float64],
) -> tuple[int, float]:  # fmt: skip
    """Register scan ``q`` (query) on scan ``c``: inliers, RMS error; ``pose`` gets (x, y, th)."""
    qlo, qhi = offsets[q], offsets[q + 1]
    clo, chi = offsets[c], offsets[c + 1]
    if qhi - qlo < 2 or chi - clo < 2:
        return 0, 0.0
    size = (qhi - qlo) * int(opt[0])
    mi = np.empty(size, dtype=np.int64)
    mj = np.empty(size, dtype=np.int64)
    n = _tentative(qlo, qhi, clo, chi, opening, desc, opt, mi, mj)
    if n < 2:
        return 0, 0.0
    used_q = np.full(qhi - qlo, -1, dtype=np.int64)
    used_c = np.full(chi - clo, -1, dtype=np.int64)
    flags = np.zeros(n, dtype=np.bool_)
    best_n, best_sse, best = 0, 0.0, (0.0, 0.0, 0.0)
    stamp = 0
    eps, tol_ori, min_d = opt[3], opt[4], opt[5]
    for m1 in range(n):
        i1, j1 = mi[m1], mj[m1]
        for m2 in range(m1 + 1, n):
            i2, j2 = mi[m2], mj[m2]
            if i1 == i2 or j1 == j2:
                continue
            vax, vay = xy[i2, 0] - xy[i1, 0], xy[i2, 1] - xy[i1, 1]
            vbx, vby = xy[j2, 0] - xy[j1, 0], xy[j2, 1] - xy[j1, 1]
            da = math.sqrt(vax * vax + vay * vay)
            if da < min_d or abs(da - math.sqrt(vbx * vbx + vby * vby)) > eps:
                continue
            th = _wrap(math.atan2(vby, vbx) - math.atan2(vay, vax))
            if abs(_wrap(ori[j1] - ori[i1] - th)) > tol_ori:
                continue
            cs, sn = math.cos(th), math.sin(th)
            mx, my = 0.5 * (xy[i1, 0] + xy[i2, 0]), 0.5 * (xy[i1, 1] + xy[i2, 1])
            tx = 0.5 * (xy[j1, 0] + xy[j2, 0]) - (cs * mx - sn * my)
            ty = 0.5 * (xy[j1, 1] + xy[j2, 1]) - (sn * mx + cs * my)
            stamp += 1
            k, sse = _count(th, tx, ty, mi, mj, n, xy, ori, opt, used_q, used_c, qlo, clo,
                            stamp, flags)  # fmt: skip
            if k > best_n or (k == best_n and k > 0 and sse < best_sse):
                best_n, best_sse, best = k, sse, (th, tx, ty)
    if best_n < 2:
        return 0, 0.0
    stamp += 1
    _count(best[0], best[1], best[2], mi, mj, n, xy, ori, opt, used_q, used_c, qlo, clo,
           stamp, flags)  # fmt: skip
    th, tx, ty = _fit(mi, mj, flags, n, xy)
    stamp += 1
    k, sse = _count(th, tx, ty, mi, mj, n, xy, ori, opt, used_q, used_c, qlo, clo, stamp, flags)
    if k >= best_n:
        best_n, best_sse, best = k, sse, (th, tx, ty)
    pose[0], pose[1], pose[2] = best[1], best[2], best[0]
    return best_n, math.sqrt(best_sse / best_n)


@nb.njit(cache=True, nogil=True, parallel=True)
def _score_pairs(
    queries: NDArray[np.int64], candidates: NDArray[np.int64], offsets: NDArray[np.int64],
    xy: NDArray[np.float64], ori: NDArray[np.float64], opening: NDArray[np.float64],
    desc: NDArray[np.float64], opt: NDArray[np.float64],
    inliers: NDArray[np.int64], poses: NDArray[np.float64], rms: NDArray[np.float64],
) -> None:  # fmt: skip
    for k in nb.prange(candidates.shape[0]):
        n, e = _register_pair(queries[k], candidates[k], offsets, xy, ori, opening, desc, opt,
                              poses[k])  # fmt: skip
        inliers[k] = n
        rms[k] = e


def score_pairs(
    bank: KeypointBank,
    queries: NDArray[np.int64],
    candidates: NDArray[np.int64],
    options: MatchOptions | None = None,
) -> tuple[NDArray[np.int64], NDArray[np.float64], NDArray[np.float64]]:
    """Register scan ``queries[k]`` against scan ``candidates[k]`` for every k, in one numba
    call over all cores (several queries per call amortise the threads' start-up).

    Parameters
    ----------
    bank : KeypointBank
        Keypoints and descriptors of all scans
        (:func:`~laser_corners.eval.loop_descriptors.build_bank`).
    queries, candidates : ndarray of int, shape (P,)
        Scan indices of each pair.
    options : MatchOptions, optional
        Matcher settings.

    Returns
    -------
    inliers : ndarray of int, shape (P,)
        Inliers of the best hypothesis per pair (0: no hypothesis).
    poses : ndarray, shape (P, 3)
        The query's sensor pose ``(x, y, theta)`` in the candidate's sensor frame (zeros
        where ``inliers`` is 0).
    rms : ndarray, shape (P,)
        RMS distance of the inliers, metres.
    """
    opt = (options or MatchOptions()).as_array()
    q = np.ascontiguousarray(queries, dtype=np.int64)
    c = np.ascontiguousarray(candidates, dtype=np.int64)
    if q.shape != c.shape:
        raise ValueError(f"{q.shape[0]} queries but {c.shape[0]} candidates")
    inliers = np.zeros(c.shape[0], dtype=np.int64)
    poses = np.zeros((c.shape[0], 3))
    rms = np.zeros(c.shape[0])
    _score_pairs(q, c, bank.offsets, bank.xy, bank.orientation, bank.opening_deg,
                 bank.descriptors, opt, inliers, poses, rms)  # fmt: skip
    return inliers, poses, rms


def score_query(
    bank: KeypointBank,
    query: int,
    candidates: NDArray[np.int64],
    options: MatchOptions | None = None,
) -> tuple[NDArray[np.int64], NDArray[np.float64], NDArray[np.float64]]:
    """Register scan ``query`` against each of ``candidates`` (:func:`score_pairs`)."""
    cand = np.ascontiguousarray(candidates, dtype=np.int64)
    return score_pairs(bank, np.full(cand.shape[0], int(query), dtype=np.int64), cand, options)
