"""FROZEN copy of ``src/laser_corners/detector.py`` at main 91ca792; do not edit the code.

Kept on purpose, as the "old" reference: ``benchmarks/bench_detector.py`` times today's
kernel against it in the same process (its ``old ms`` and ``new/old`` columns, robust to the
load of a shared machine), and ``tests/test_detector_reference.py`` checks today's kernel
against it on 100,000-beam scans, too large for the pure-Python reference. Only the imports
of the modules it shares with the package (``laser_corners.kernel.linefit``) follow the
package's layout.

The corner-like keypoint detector of Sousa et al. (ICARA 2024), section III.

For every valid scan point p_j and every scale R_k the arrival neighbourhood (the run of
consecutive valid points before p_j, up to the first point farther than R_k from p_j or a gap)
and the departure neighbourhood (the same after p_j) are fitted with both closed-form line
models; the lower-RMSE model of each is kept (eqs. 2-9) and the two lines are intersected
(eqs. 10-13). Scale k *passes* when both neighbourhoods hold at least ``min_points`` points,
both RMSEs are at most ``max_fit_rmse``, the opening angle lies in
[``min_angle_deg``, ``max_angle_deg``] and the intersection lies within ``max_point_distance``
of p_j. A point is a corner-like feature when at least ``min_consecutive_scales`` consecutive
scales pass and all their intersections lie within ``max_centroid_distance`` of their
centroid, which is the point's keypoint.

Decisions the paper leaves open (see ``docs/method.md``):

* several runs of passing scales at one point: the longest run that also meets the centroid
  test wins; ties go to the run of smaller scales;
* several scan points that see one corner: per-point candidates whose keypoints lie within
  ``merge_radius`` of each other are merged by single linkage; the merged keypoint is the
  keypoint of the cluster's best candidate, the one with the lowest worst-fit RMSE (ties: more
  passing scales). Points beside the apex have a neighbourhood that straddles the corner, fit
  worse and intersect off the corner, so averaging them would bias the keypoint.

Options beyond the paper, off by default (the ``robust`` preset turns them on; see
``docs/simulation-and-accuracy.md``): ``min_extent_ratio`` (a scale passes only if both
neighbourhoods reach at least that fraction of R_k from p_j) and ``refine_radius`` (each
keypoint re-estimated from lines fitted to longer runs of each wall, ``_refine``).

The hot loop is one numba kernel (``cache=True``). The arrival/departure sums of x, y, x², y²
and xy come from prefix sums, so each fit is O(1) and a scan costs O(N·K) fits. Neighbourhood
bounds are found by walking outwards from p_j once for all scales (the run for R_k contains
the run for R_{k-1}).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from typing import Literal, overload

import numba as nb
import numpy as np
from numpy.typing import NDArray

from laser_corners.errors import InvalidScanError
from laser_corners.kernel.linefit import (
    centred_moments,
    intersect,
    line_direction,
    select_from_sums,
)
from laser_corners.keypoints import Keypoints
from laser_corners.params import DetectorParams
from laser_corners.scan import LaserScan

__all__ = ["CornerDetector", "ScaleTable"]

# indices into the per-point candidate table (float64, shape (N, _NC))
_C_X, _C_Y, _C_NSC, _C_K0, _C_RMSE, _C_OPEN, _C_ORIENT = range(7)
_NC = 7
# indices into the merged keypoint table (float64, shape (N, _NM))
_M_X, _M_Y, _M_BEAM, _M_OPEN, _M_ORIENT, _M_NSC, _M_RMSE, _M_NMERGED = range(8)
_NM = 8
# largest move of a keypoint by the refinement when merging is off (merge_radius = 0), metres
_REFINE_MAX_SHIFT = 0.05


@nb.njit(cache=True, nogil=True, error_model="numpy")
def _polar_to_xy(
    ranges: NDArray[np.float64],
    cos_a: NDArray[np.float64],
    sin_a: NDArray[np.float64],
    range_min: float,
    range_max: float,
    x: NDArray[np.float64],
    y: NDArray[np.float64],
) -> None:
    """Polar -> Cartesian in beam order; gaps (NaN, inf, <= range_min, >= range_max) -> NaN."""
    for i in range(ranges.shape[0]):
        r = ranges[i]
        if math.isfinite(r) and r > range_min and r < range_max:
            x[i] = r * cos_a[i]
            y[i] = r * sin_a[i]
        else:
            x[i] = math.nan
            y[i] = math.nan


@nb.njit(cache=True, nogil=True, error_model="numpy")
def _candidates(
    x: NDArray[np.float64],
    y: NDArray[np.float64],
    scales: NDArray[np.float64],
    min_points: int,
    min_angle_deg: float,
    max_angle_deg: float,
    max_fit_rmse: float,
    max_point_distance: float,
    max_centroid_distance: float,
    min_consecutive: int,
    min_extent: float,
    cand: NDArray[np.float64],
    table: NDArray[np.float64],
) -> None:
    """Fill ``cand`` (N, _NC) with each point's candidate keypoint (n_scales 0: none).

    ``x``, ``y`` are the scan points in beam order, NaN for gaps.

    When ``table`` has shape (N, K, 3) it also receives, per point and scale, the
    intersection x, y and 1.0/0.0 for pass/fail (NaN where no intersection was computed).
    """
    n = x.shape[0]
    n_scales = scales.shape[0]
    want_table = table.shape[0] == n
    # gaps are NaN points
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
    # work relative to the centroid of the scan: smaller prefix sums, less cancellation
    if n_valid > 0:
        ox /= n_valid
        oy /= n_valid
    # --- prefix sums of x, y, x², y², xy (gaps contribute nothing); one row per index keeps
    # the five sums of a neighbourhood end in one cache line
    ps = np.zeros((n + 1, 5))
    for i in range(n):
        if valid[i]:
            xi = x[i] - ox
            yi = y[i] - oy
            ps[i + 1, 0] = ps[i, 0] + xi
            ps[i + 1, 1] = ps[i, 1] + yi
            ps[i + 1, 2] = ps[i, 2] + xi * xi
            ps[i + 1, 3] = ps[i, 3] + yi * yi
            ps[i + 1, 4] = ps[i, 4] + xi * yi
        else:
            for c in range(5):
                ps[i + 1, c] = ps[i, c]

    r2 = scales * scales
    max_mse = max_fit_rmse * max_fit_rmse
    # necessary condition on the undirected lines, checked before intersecting them:
    # an opening angle in [min, max] has |cos| <= max(|cos min|, |cos max|)
    max_abs_cos = max(
        abs(math.cos(math.radians(min_angle_deg))), abs(math.cos(math.radians(max_angle_deg)))
    )
    max_cos2 = max_abs_cos * max_abs_cos * (1.0 + 1e-9)  # margin: never stricter than exact
    cos_min_angle = math.cos(math.radians(min_angle_deg))
    cos_max_angle = math.cos(math.radians(max_angle_deg))
    max_pd2 = max_point_distance * max_point_distance
    max_cd2 = max_centroid_distance * max_centroid_distance
    # --- 1. neighbourhood bounds of every point and scale. One walk outwards per side serves
    # all scales: it records the running maximum of the squared distance to p_j (a gap counts
    # as infinitely far) until that exceeds the largest R_k; the run for R_k is then the
    # number of leading steps whose running maximum is <= R_k², counted without branches.
    start = np.empty((n_scales, n), dtype=np.int64)  # first index of the arrival neighbourhood
    stop = np.empty((n_scales, n), dtype=np.int64)  # last index of the departure neighbourhood
    r2_max = r2[n_scales - 1]
    running_max = np.empty(n)
    for j in range(n):
        if not valid[j]:
            for k in range(n_scales):
                start[k, j] = j
                stop[k, j] = j
            continue
        xj = x[j]
        yj = y[j]
        for side in range(2):
            step = -1 if side == 0 else 1
            i = j + step
            m = 0.0
            steps = 0
            while 0 <= i < n:
                d2 = (x[i] - xj) ** 2 + (y[i] - yj) ** 2 if valid[i] else math.inf
                m = max(m, d2)
                if m > r2_max:
                    break
                running_max[steps] = m
                steps += 1
                i += step
            for k in range(n_scales):
                within = 0
                for q in range(steps):
                    within += running_max[q] <= r2[k]
                if side == 0:
                    start[k, j] = j - within
                else:
                    stop[k, j] = j + within

    # --- 2. branch-free screen of every (scale, point), without divisions: the centred
    # moments of both neighbourhoods from the prefix sums (O(1)), the RMSE tests of eqs. 8-9
    # as D <= max_rmse² · n · spread (D = Sxx·Syy - Sxy², spread = the kept model's Sxx or
    # Syy), and a necessary condition on the angle between the undirected lines, whose
    # directions are (Sxx, Sxy) for y|x and (Sxy, Syy) for x|y. Most points lie on straight
    # walls and stop here. The screen is a little permissive; phase 3 applies the exact tests.
    inv_count = np.empty(n + 1)
    inv_count[0] = 0.0
    for c in range(1, n + 1):
        inv_count[c] = 1.0 / c
    loose_mse = max_mse * (1.0 + 1e-9)
    screened = np.empty((n_scales, n), dtype=np.bool_)
    for k in range(n_scales):
        for j in range(n):
            s = start[k, j]
            e = stop[k, j]
            na = j - s + 1
            nd = e - j + 1
            if na < min_points or nd < min_points:
                # too few points (near the sensor's reach, at small scales): consecutive
                # points at one scale mostly agree, so this branch predicts well
                screened[k, j] = False
                continue
            axx, ayy, axy = centred_moments(
                inv_count[na],
                ps[j + 1, 0] - ps[s, 0],
                ps[j + 1, 1] - ps[s, 1],
                ps[j + 1, 2] - ps[s, 2],
                ps[j + 1, 3] - ps[s, 3],
                ps[j + 1, 4] - ps[s, 4],
            )
            dxx, dyy, dxy = centred_moments(
                inv_count[nd],
                ps[e + 1, 0] - ps[j, 0],
                ps[e + 1, 1] - ps[j, 1],
                ps[e + 1, 2] - ps[j, 2],
                ps[e + 1, 3] - ps[j, 3],
                ps[e + 1, 4] - ps[j, 4],
            )
            a_yx = axx >= ayy
            d_yx = dxx >= dyy
            a_spread = axx if a_yx else ayy
            d_spread = dxx if d_yx else dyy
            va_x = axx if a_yx else axy
            va_y = axy if a_yx else ayy
            vd_x = dxx if d_yx else dxy
            vd_y = dxy if d_yx else dyy
            dot = va_x * vd_x + va_y * vd_y
            screened[k, j] = (
                (axx * ayy - axy * axy <= loose_mse * na * a_spread)
                & (dxx * dyy - dxy * dxy <= loose_mse * nd * d_spread)
                & (
                    dot * dot
                    <= max_cos2 * (va_x * va_x + va_y * va_y) * (vd_x * vd_x + vd_y * vd_y)
                )
            )

    # --- 3. the full test of the screened scales, then the runs of passing scales per point
    passed = np.zeros(n_scales, dtype=np.bool_)
    qx = np.empty(n_scales)
    qy = np.empty(n_scales)
    worst = np.empty(n_scales)
    opening = np.empty(n_scales)
    bis_x = np.empty(n_scales)
    bis_y = np.empty(n_scales)
    for j in range(n):
        cand[j, _C_NSC] = 0.0
        xj = x[j]
        yj = y[j]
        for k in range(n_scales):
            passed[k] = False
            qx[k] = math.nan
            qy[k] = math.nan
            if want_table:
                table[j, k, 0] = math.nan
                table[j, k, 1] = math.nan
                table[j, k, 2] = 0.0
            if not screened[k, j]:
                continue
            s = start[k, j]
            e = stop[k, j]
            if min_extent > 0.0:  # option, not in the paper: both runs must reach out
                reach2 = (min_extent * scales[k]) ** 2
                far_a = (x[s] - xj) ** 2 + (y[s] - yj) ** 2
                far_d = (x[e] - xj) ** 2 + (y[e] - yj) ** 2
                if far_a < reach2 or far_d < reach2:
                    continue
            # arrival neighbourhood [s, j], departure [j, e]: sums from prefix sums
            ma, a0, a1, mse_a = select_from_sums(
                float(j - s + 1),
                ps[j + 1, 0] - ps[s, 0],
                ps[j + 1, 1] - ps[s, 1],
                ps[j + 1, 2] - ps[s, 2],
                ps[j + 1, 3] - ps[s, 3],
                ps[j + 1, 4] - ps[s, 4],
            )
            md, d0, d1, mse_d = select_from_sums(
                float(e - j + 1),
                ps[e + 1, 0] - ps[j, 0],
                ps[e + 1, 1] - ps[j, 1],
                ps[e + 1, 2] - ps[j, 2],
                ps[e + 1, 3] - ps[j, 3],
                ps[e + 1, 4] - ps[j, 4],
            )
            if mse_a > max_mse or mse_d > max_mse:  # eqs. 8-9, exact
                continue
            ix, iy, ok = intersect(ma, a0, a1, md, d0, d1)  # eqs. 10-13
            if not ok:
                continue
            ix += ox
            iy += oy
            qx[k] = ix
            qy[k] = iy
            if want_table:
                table[j, k, 0] = ix
                table[j, k, 1] = iy
            if (ix - xj) ** 2 + (iy - yj) ** 2 > max_pd2:
                continue
            # opening angle between the lines, each directed from the corner towards the far
            # end of its neighbourhood
            ua_x, ua_y = line_direction(ma, a1)
            ud_x, ud_y = line_direction(md, d1)
            if ua_x * (x[s] - ix) + ua_y * (y[s] - iy) < 0.0:
                ua_x = -ua_x
                ua_y = -ua_y
            if ud_x * (x[e] - ix) + ud_y * (y[e] - iy) < 0.0:
                ud_x = -ud_x
                ud_y = -ud_y
            cos_open = ua_x * ud_x + ua_y * ud_y
            cos_open = min(1.0, max(-1.0, cos_open))
            # opening angle in [min, max] <=> cos in [cos max, cos min] (cos decreases on
            # [0, 180]); the angle itself only for the scales that pass
            if cos_open > cos_min_angle or cos_open < cos_max_angle:
                continue
            passed[k] = True
            worst[k] = math.sqrt(max(mse_a, mse_d))
            opening[k] = math.degrees(math.acos(cos_open))
            bx = ua_x + ud_x
            by = ua_y + ud_y
            norm = math.sqrt(bx * bx + by * by)
            bis_x[k] = bx / norm if norm > 0.0 else 0.0
            bis_y[k] = by / norm if norm > 0.0 else 0.0
            if want_table:
                table[j, k, 2] = 1.0

        # --- runs of consecutive passing scales: longest valid run, ties -> smaller scales
        best_len = 0
        best_k0 = -1
        best_cx = 0.0
        best_cy = 0.0
        k = 0
        while k < n_scales:
            if not passed[k]:
                k += 1
                continue
            k0 = k
            while k < n_scales and passed[k]:
                k += 1
            run = k - k0
            if run < min_consecutive or run <= best_len:
                continue
            cx = 0.0
            cy = 0.0
            for kk in range(k0, k):
                cx += qx[kk]
                cy += qy[kk]
            cx /= run
            cy /= run
            compact = True
            for kk in range(k0, k):
                if (qx[kk] - cx) ** 2 + (qy[kk] - cy) ** 2 > max_cd2:
                    compact = False
                    break
            if compact:
                best_len = run
                best_k0 = k0
                best_cx = cx
                best_cy = cy
        if best_len == 0:
            continue
        w = 0.0
        o = 0.0
        sbx = 0.0
        sby = 0.0
        for kk in range(best_k0, best_k0 + best_len):
            w = max(w, worst[kk])
            o += opening[kk]
            sbx += bis_x[kk]
            sby += bis_y[kk]
        cand[j, _C_X] = best_cx
        cand[j, _C_Y] = best_cy
        cand[j, _C_NSC] = best_len
        cand[j, _C_K0] = best_k0
        cand[j, _C_RMSE] = w
        cand[j, _C_OPEN] = o / best_len
        cand[j, _C_ORIENT] = math.atan2(sby, sbx)


@nb.njit(cache=True, nogil=True, error_model="numpy")
def _merge(cand: NDArray[np.float64], merge_radius: float, merged: NDArray[np.float64]) -> int:
    """Merge per-point candidates by single linkage within ``merge_radius``.

    Writes one row per merged keypoint into ``merged`` (_NM columns) and returns their count.
    """
    n = cand.shape[0]
    idx = np.empty(n, dtype=np.int64)
    m = 0
    for j in range(n):
        if cand[j, _C_NSC] > 0.0:
            idx[m] = j
            m += 1
    parent = np.arange(m)
    r2 = merge_radius * merge_radius
    for a in range(m):
        ja = idx[a]
        for b in range(a + 1, m):
            jb = idx[b]
            d2 = (cand[ja, _C_X] - cand[jb, _C_X]) ** 2 + (cand[ja, _C_Y] - cand[jb, _C_Y]) ** 2
            if d2 <= r2:
                ra = a
                while parent[ra] != ra:
                    ra = parent[ra]
                rb = b
                while parent[rb] != rb:
                    rb = parent[rb]
                if ra != rb:
                    parent[max(ra, rb)] = min(ra, rb)
    # roots in order of first member: output ordered by beam index of the first candidate
    label = np.empty(m, dtype=np.int64)
    n_out = 0
    root_label = np.full(m, -1, dtype=np.int64)
    for a in range(m):
        r = a
        while parent[r] != r:
            r = parent[r]
        if root_label[r] < 0:
            root_label[r] = n_out
            n_out += 1
        label[a] = root_label[r]
    count = np.zeros(n_out, dtype=np.int64)
    rep = np.full(n_out, -1, dtype=np.int64)
    worst = np.zeros(n_out)
    for a in range(m):
        c = label[a]
        j = idx[a]
        count[c] += 1
        worst[c] = max(worst[c], cand[j, _C_RMSE])
        r = rep[c]
        if (
            r < 0
            or cand[j, _C_RMSE] < cand[r, _C_RMSE]
            or (cand[j, _C_RMSE] == cand[r, _C_RMSE] and cand[j, _C_NSC] > cand[r, _C_NSC])
        ):
            rep[c] = j
    for c in range(n_out):
        r = rep[c]
        merged[c, _M_X] = cand[r, _C_X]
        merged[c, _M_Y] = cand[r, _C_Y]
        merged[c, _M_BEAM] = r
        merged[c, _M_OPEN] = cand[r, _C_OPEN]
        merged[c, _M_ORIENT] = cand[r, _C_ORIENT]
        merged[c, _M_NSC] = cand[r, _C_NSC]
        merged[c, _M_RMSE] = worst[c]
        merged[c, _M_NMERGED] = count[c]
    return n_out


@nb.njit(cache=True, nogil=True, error_model="numpy")
def _refine(
    x: NDArray[np.float64],
    y: NDArray[np.float64],
    rows: NDArray[np.float64],
    n_rows: int,
    radius: float,
    exclude: float,
    min_points: int,
    max_rmse: float,
    max_shift: float,
) -> None:
    """Re-estimate keypoints from longer wall fits (option ``refine_radius``, not in the paper).

    For each keypoint row: the scan point nearest to it (searched outwards from its beam),
    then on each side of that point the run of consecutive valid points within ``radius`` of
    the keypoint, leaving out those closer than ``exclude``; both runs are fitted (eqs. 2-9,
    sums relative to the keypoint) and intersected (eqs. 10-13). While a fit's RMSE exceeds
    ``max_rmse`` (the run reaches past the next corner) the radius is halved, down to
    ``4 * exclude``. The intersection replaces the keypoint when both runs have
    ``min_points`` points and it moved at most ``max_shift``. O(points within ``radius``) per
    keypoint and halving.
    """
    n = x.shape[0]
    e2 = exclude * exclude
    s2 = max_shift * max_shift
    max_mse = max_rmse * max_rmse
    sums = np.zeros((2, 6))
    for m in range(n_rows):
        cx = rows[m, _M_X]
        cy = rows[m, _M_Y]
        b = int(rows[m, _M_BEAM])
        r2 = radius * radius
        apex = b
        best = (x[b] - cx) ** 2 + (y[b] - cy) ** 2
        for side in range(2):
            step = -1 if side == 0 else 1
            i = b + step
            while 0 <= i < n and math.isfinite(x[i]):
                d2 = (x[i] - cx) ** 2 + (y[i] - cy) ** 2
                if d2 > r2:
                    break
                if d2 < best:
                    best = d2
                    apex = i
                i += step
        rad = radius
        while rad >= 4.0 * exclude:
            r2 = rad * rad
            for side in range(2):
                step = -1 if side == 0 else 1
                for c in range(6):
                    sums[side, c] = 0.0
                i = apex + step
                while 0 <= i < n and math.isfinite(x[i]):
                    dx = x[i] - cx
                    dy = y[i] - cy
                    d2 = dx * dx + dy * dy
                    if d2 > r2:
                        break
                    if d2 >= e2:
                        sums[side, 0] += 1.0
                        sums[side, 1] += dx
                        sums[side, 2] += dy
                        sums[side, 3] += dx * dx
                        sums[side, 4] += dy * dy
                        sums[side, 5] += dx * dy
                    i += step
            if sums[0, 0] < min_points or sums[1, 0] < min_points:
                break
            ma, a0, a1, mse_a = select_from_sums(
                sums[0, 0], sums[0, 1], sums[0, 2], sums[0, 3], sums[0, 4], sums[0, 5]
            )
            md, d0, d1, mse_d = select_from_sums(
                sums[1, 0], sums[1, 1], sums[1, 2], sums[1, 3], sums[1, 4], sums[1, 5]
            )
            if mse_a > max_mse or mse_d > max_mse:
                rad *= 0.5
                continue
            qx, qy, ok = intersect(ma, a0, a1, md, d0, d1)
            if ok and qx * qx + qy * qy <= s2:
                rows[m, _M_X] = cx + qx
                rows[m, _M_Y] = cy + qy
            break


@nb.njit(cache=True, parallel=True, error_model="numpy")
def _detect_batch(
    ranges: NDArray[np.float64],
    cos_a: NDArray[np.float64],
    sin_a: NDArray[np.float64],
    range_min: float,
    range_max: float,
    scales: NDArray[np.float64],
    min_points: int,
    min_angle_deg: float,
    max_angle_deg: float,
    max_fit_rmse: float,
    max_point_distance: float,
    max_centroid_distance: float,
    min_consecutive: int,
    merge_radius: float,
    min_extent: float,
    refine_radius: float,
    refine_exclude: float,
    merged: NDArray[np.float64],
    counts: NDArray[np.int64],
) -> None:
    """Detect keypoints in every row of ``ranges`` (S, N), in parallel over scans."""
    n_scans, n = ranges.shape
    no_table = np.empty((0, 0, 3))
    for s in nb.prange(n_scans):
        x = np.empty(n)
        y = np.empty(n)
        _polar_to_xy(ranges[s], cos_a, sin_a, range_min, range_max, x, y)
        cand = np.empty((n, _NC))
        _candidates(
            x,
            y,
            scales,
            min_points,
            min_angle_deg,
            max_angle_deg,
            max_fit_rmse,
            max_point_distance,
            max_centroid_distance,
            min_consecutive,
            min_extent,
            cand,
            no_table,
        )
        if merge_radius > 0.0:
            counts[s] = _merge(cand, merge_radius, merged[s])
        else:
            counts[s] = _raw_rows(cand, merged[s])
        if refine_radius > 0.0:
            _refine(
                x,
                y,
                merged[s],
                counts[s],
                refine_radius,
                refine_exclude,
                min_points,
                max_fit_rmse,
                merge_radius if merge_radius > 0.0 else _REFINE_MAX_SHIFT,
            )


@nb.njit(cache=True, nogil=True, error_model="numpy")
def _raw_rows(cand: NDArray[np.float64], out: NDArray[np.float64]) -> int:
    """Copy every per-point candidate into ``out`` as an unmerged keypoint row."""
    m = 0
    for j in range(cand.shape[0]):
        if cand[j, _C_NSC] > 0.0:
            out[m, _M_X] = cand[j, _C_X]
            out[m, _M_Y] = cand[j, _C_Y]
            out[m, _M_BEAM] = j
            out[m, _M_OPEN] = cand[j, _C_OPEN]
            out[m, _M_ORIENT] = cand[j, _C_ORIENT]
            out[m, _M_NSC] = cand[j, _C_NSC]
            out[m, _M_RMSE] = cand[j, _C_RMSE]
            out[m, _M_NMERGED] = 1
            m += 1
    return m


def _keypoints_from_rows(
    rows: NDArray[np.float64], stamp: float | None, frame_id: str
) -> Keypoints:
    columns = rows.T  # one row per field: contiguous copies below
    return Keypoints._from_valid_arrays(
        stamp,
        frame_id,
        xy=rows[:, _M_X : _M_Y + 1].copy(),
        beam_index=columns[_M_BEAM].astype(np.int64),
        opening_angle_deg=columns[_M_OPEN].copy(),
        orientation=columns[_M_ORIENT].copy(),
        n_scales=columns[_M_NSC].astype(np.int64),
        rmse=columns[_M_RMSE].copy(),
        n_merged=columns[_M_NMERGED].astype(np.int64),
    )


class ScaleTable:
    """Per-point, per-scale intermediate results of one scan, for analysis and figures.

    Attributes
    ----------
    intersections : ndarray, shape (N, K, 2)
        Line intersection at each point and scale (NaN where none was computed).
    passed : ndarray of bool, shape (N, K)
        Whether the scale passed all per-scale tests.
    scales : ndarray, shape (K,)
        The radii R_k.
    """

    def __init__(self, table: NDArray[np.float64], scales: NDArray[np.float64]) -> None:
        self.intersections = table[:, :, :2]
        self.passed = table[:, :, 2] > 0.5
        self.scales = scales


class CornerDetector:
    """Corner-like keypoint detector for 2D laser scans (Sousa et al., ICARA 2024).

    Parameters
    ----------
    params : DetectorParams, optional
        Detector parameters; the paper's defaults when omitted.

    References
    ----------
    .. [1] Sousa, R. B., Sobreira, H. M., Silva, M. F., Moreira, A. P., "Line Fitting-Based
       Corner-Like Detector for 2D Laser Scanners Data", ICARA 2024,
       doi:10.1109/ICARA60736.2024.10553006.

    Examples
    --------
    >>> import numpy as np
    >>> from laser_corners import CornerDetector, LaserScan
    >>> from laser_corners.sim import corner_scan
    >>> scan = corner_scan()   # a clean right-angle corner at (2, 1) seen by a UST-10LX
    >>> kps = CornerDetector().detect(scan)
    >>> len(kps), np.round(kps.xy, 2).tolist()
    (1, [[2.0, 1.0]])
    """

    def __init__(self, params: DetectorParams | None = None) -> None:
        self.params = params if params is not None else DetectorParams()
        self._scales = np.asarray(self.params.scales, dtype=np.float64)
        self._geometry: tuple[int, float, float] | None = None
        self._cos = np.empty(0)
        self._sin = np.empty(0)

    def __repr__(self) -> str:
        return f"CornerDetector({self.params!r})"

    # ----------------------------------------------------------------- helpers
    def _trig(self, scan: LaserScan) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        geometry = (scan.n_beams, scan.angle_min, scan.angle_increment)
        if geometry != self._geometry:
            angles = scan.angles
            self._cos = np.cos(angles)
            self._sin = np.sin(angles)
            self._geometry = geometry
        return self._cos, self._sin

    def _scan_xy(self, scan: LaserScan) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        if not isinstance(scan, LaserScan):
            raise InvalidScanError(f"expected a LaserScan, got {type(scan).__name__}")
        cos_a, sin_a = self._trig(scan)
        x = np.empty(scan.n_beams)
        y = np.empty(scan.n_beams)
        _polar_to_xy(scan.ranges, cos_a, sin_a, scan.range_min, scan.range_max, x, y)
        return x, y

    def _run_candidates(
        self, x: NDArray[np.float64], y: NDArray[np.float64], table: NDArray[np.float64]
    ) -> NDArray[np.float64]:
        p = self.params
        cand = np.empty((x.shape[0], _NC))
        _candidates(
            x,
            y,
            self._scales,
            p.min_points,
            p.min_angle_deg,
            p.max_angle_deg,
            p.max_fit_rmse,
            p.max_point_distance,
            p.max_centroid_distance,
            p.min_consecutive_scales,
            p.min_extent_ratio,
            cand,
            table,
        )
        return cand

    def _finish(
        self,
        cand: NDArray[np.float64],
        x: NDArray[np.float64],
        y: NDArray[np.float64],
        stamp: float | None,
        frame_id: str,
        with_raw: bool,
    ) -> Keypoints | tuple[Keypoints, Keypoints]:
        n = cand.shape[0]
        rows = np.empty((n, _NM))
        p = self.params
        if p.merge_radius > 0.0:
            n_out = _merge(cand, p.merge_radius, rows)
        else:
            n_out = _raw_rows(cand, rows)
        if p.refine_radius > 0.0:
            _refine(
                x,
                y,
                rows,
                n_out,
                p.refine_radius,
                p.refine_exclude,
                p.min_points,
                p.max_fit_rmse,
                p.merge_radius if p.merge_radius > 0.0 else _REFINE_MAX_SHIFT,
            )
        keypoints = _keypoints_from_rows(rows[:n_out], stamp, frame_id)
        if not with_raw:
            return keypoints
        raw = np.empty((n, _NM))
        n_raw = _raw_rows(cand, raw)
        return keypoints, _keypoints_from_rows(raw[:n_raw], stamp, frame_id)

    # ----------------------------------------------------------------- public API
    @overload
    def detect(self, scan: LaserScan, return_candidates: Literal[False] = ...) -> Keypoints: ...

    @overload
    def detect(
        self, scan: LaserScan, return_candidates: Literal[True]
    ) -> tuple[Keypoints, Keypoints]: ...

    def detect(
        self, scan: LaserScan, return_candidates: bool = False
    ) -> Keypoints | tuple[Keypoints, Keypoints]:
        """Detect corner-like keypoints in one scan.

        Parameters
        ----------
        scan : LaserScan
            The scan.
        return_candidates : bool
            Also return the raw per-point candidates (before duplicate merging).

        Returns
        -------
        keypoints : Keypoints
            One keypoint per physical corner, sensor frame.
        candidates : Keypoints
            Only with ``return_candidates``: every scan point that passed, with its own
            keypoint (``n_merged`` is 1).
        """
        x, y = self._scan_xy(scan)
        cand = self._run_candidates(x, y, np.empty((0, 0, 3)))
        return self._finish(cand, x, y, scan.stamp, scan.frame_id, return_candidates)

    def detect_points(
        self, xy: NDArray[np.float64], return_candidates: bool = False
    ) -> Keypoints | tuple[Keypoints, Keypoints]:
        """Detect keypoints in Cartesian points given in angular (beam) order.

        Parameters
        ----------
        xy : ndarray, shape (N, 2)
            Scan points in beam order; rows with a NaN are gaps.
        return_candidates : bool
            As in :meth:`detect`.
        """
        pts = np.asarray(xy, dtype=np.float64)
        if pts.ndim != 2 or pts.shape[1] != 2:
            raise InvalidScanError(f"points must have shape (N, 2), got {pts.shape}")
        x = np.ascontiguousarray(pts[:, 0])
        y = np.ascontiguousarray(pts[:, 1])
        # a point with a NaN or inf in either coordinate is a gap
        bad = ~(np.isfinite(x) & np.isfinite(y))
        x[bad] = np.nan
        y[bad] = np.nan
        cand = self._run_candidates(x, y, np.empty((0, 0, 3)))
        return self._finish(cand, x, y, None, "", return_candidates)

    def scale_table(self, scan: LaserScan) -> ScaleTable:
        """Per-point, per-scale intersections and pass flags (for analysis and figures)."""
        table = np.empty((scan.n_beams, self._scales.shape[0], 3))
        x, y = self._scan_xy(scan)
        self._run_candidates(x, y, table)
        return ScaleTable(table, self._scales.copy())

    def detect_many(self, scans: Sequence[LaserScan] | Iterable[LaserScan]) -> list[Keypoints]:
        """Detect keypoints in a batch of scans of the same geometry, in parallel over scans.

        All scans must share ``len(ranges)``, ``angle_min``, ``angle_increment``,
        ``range_min`` and ``range_max``; use :meth:`detect` otherwise.
        """
        scans = list(scans)
        for i, scan in enumerate(scans):
            if not isinstance(scan, LaserScan):
                raise InvalidScanError(f"detect_many: item {i} is a {type(scan).__name__}")
        if not scans:
            return []
        first = scans[0]
        geometry = (
            first.n_beams,
            first.angle_min,
            first.angle_increment,
            first.range_min,
            first.range_max,
        )
        for i, scan in enumerate(scans):
            if (
                scan.n_beams,
                scan.angle_min,
                scan.angle_increment,
                scan.range_min,
                scan.range_max,
            ) != geometry:
                raise InvalidScanError(
                    f"detect_many: scan {i} has a different geometry from scan 0; "
                    "call detect() per scan instead"
                )
        ranges = np.stack([scan.ranges for scan in scans])
        cos_a, sin_a = self._trig(first)
        p = self.params
        merged = np.empty((len(scans), first.n_beams, _NM))
        counts = np.zeros(len(scans), dtype=np.int64)
        _detect_batch(
            ranges,
            cos_a,
            sin_a,
            first.range_min,
            first.range_max,
            self._scales,
            p.min_points,
            p.min_angle_deg,
            p.max_angle_deg,
            p.max_fit_rmse,
            p.max_point_distance,
            p.max_centroid_distance,
            p.min_consecutive_scales,
            p.merge_radius,
            p.min_extent_ratio,
            p.refine_radius,
            p.refine_exclude,
            merged,
            counts,
        )
        return [
            _keypoints_from_rows(merged[s, : counts[s]], scan.stamp, scan.frame_id)
            for s, scan in enumerate(scans)
        ]
