"""A transparent reference implementation of the detector: plain Python loops, straight from
the paper's equations (section III), with none of the kernel's tricks (no prefix sums, no
reuse between scales, no pre-checks). Used to check the numba kernel.
"""

from __future__ import annotations

import math

from laser_corners import DetectorParams, LaserScan


def points_of(scan: LaserScan) -> list[tuple[float, float] | None]:
    """Cartesian points in beam order; None for a gap."""
    out: list[tuple[float, float] | None] = []
    for i, r in enumerate(scan.ranges.tolist()):
        if math.isfinite(r) and scan.range_min < r < scan.range_max:
            a = scan.angle_min + i * scan.angle_increment
            out.append((r * math.cos(a), r * math.sin(a)))
        else:
            out.append(None)
    return out


def fit(points: list[tuple[float, float]]) -> tuple[str, float, float, float]:
    """Both models (eqs. 2-7), RMSE (eqs. 8-9), the lower one kept (ties: y|x)."""
    n = len(points)
    mx = sum(p[0] for p in points) / n
    my = sum(p[1] for p in points) / n
    sxx = sum((p[0] - mx) ** 2 for p in points)
    syy = sum((p[1] - my) ** 2 for p in points)
    sxy = sum((p[0] - mx) * (p[1] - my) for p in points)
    rmse_yx = rmse_xy = math.inf
    if sxx > 0:
        b1 = sxy / sxx  # eq. 3
        b0 = my - b1 * mx  # eq. 4
        rmse_yx = math.sqrt(sum((p[1] - b0 - b1 * p[0]) ** 2 for p in points) / n)  # eq. 8
    if syy > 0:
        a1 = sxy / syy  # eq. 6
        a0 = mx - a1 * my  # eq. 7
        rmse_xy = math.sqrt(sum((p[0] - a0 - a1 * p[1]) ** 2 for p in points) / n)  # eq. 9
    if rmse_yx == math.inf and rmse_xy == math.inf:
        return "none", math.nan, math.nan, math.inf
    if rmse_yx <= rmse_xy:
        return "y|x", b0, b1, rmse_yx
    return "x|y", a0, a1, rmse_xy


def intersection(
    la: tuple[str, float, float, float], lb: tuple[str, float, float, float]
) -> tuple[float, float] | None:
    """Eqs. 10-13."""
    ma, a0, a1, _ = la
    mb, b0, b1, _ = lb
    if "none" in (ma, mb):
        return None
    if ma == "y|x" and mb == "y|x":
        if a1 == b1:
            return None
        x = (b0 - a0) / (a1 - b1)
        return x, a0 + a1 * x
    if ma == "x|y" and mb == "x|y":
        if a1 == b1:
            return None
        y = (b0 - a0) / (a1 - b1)
        return a0 + a1 * y, y
    if ma == "y|x":  # y = a0 + a1 x, x = b0 + b1 y
        if 1 - a1 * b1 == 0:
            return None
        x = (b0 + b1 * a0) / (1 - a1 * b1)
        return x, a0 + a1 * x
    if 1 - a1 * b1 == 0:  # x = a0 + a1 y, y = b0 + b1 x
        return None
    y = (b0 + b1 * a0) / (1 - a1 * b1)
    return a0 + a1 * y, y


def direction(line: tuple[str, float, float, float]) -> tuple[float, float]:
    model, _, slope, _ = line
    norm = math.sqrt(1 + slope * slope)
    return (1 / norm, slope / norm) if model == "y|x" else (slope / norm, 1 / norm)


def neighbourhood(pts: list, j: int, step: int, radius: float, max_gap: int) -> list:
    """p_j, then the consecutive points from p_j towards ``step`` within ``radius`` of it;
    a run of at most ``max_gap`` gaps followed by a point is stepped over (option
    ``max_gap_beams``, 0 in the paper: every gap ends the neighbourhood)."""
    pj = pts[j]
    out = [pj]
    i = j + step
    while 0 <= i < len(pts):
        if pts[i] is None:
            gap_end = i
            while 0 <= gap_end < len(pts) and pts[gap_end] is None:
                gap_end += step
            if abs(gap_end - i) > max_gap or not 0 <= gap_end < len(pts):
                break
            i = gap_end
        if math.dist(pts[i], pj) > radius:
            break
        out.append(pts[i])
        i += step
    return out


def candidates(scan: LaserScan, params: DetectorParams) -> dict[int, dict]:
    """Per-point candidate keypoints, keyed by beam index."""
    pts = points_of(scan)
    n = len(pts)
    out: dict[int, dict] = {}
    for j in range(n):
        pj = pts[j]
        if pj is None:
            continue
        per_scale = []
        for radius in params.scales:
            arrival = neighbourhood(pts, j, -1, radius, params.max_gap_beams)[::-1]
            departure = neighbourhood(pts, j, 1, radius, params.max_gap_beams)
            per_scale.append(check_scale(arrival, departure, pj, params, radius))
        best = None
        k = 0
        while k < len(per_scale):
            if per_scale[k] is None:
                k += 1
                continue
            k0 = k
            while k < len(per_scale) and per_scale[k] is not None:
                k += 1
            run = per_scale[k0:k]
            if len(run) < params.min_consecutive_scales:
                continue
            cx = sum(r["q"][0] for r in run) / len(run)
            cy = sum(r["q"][1] for r in run) / len(run)
            if any(math.dist(r["q"], (cx, cy)) > params.max_centroid_distance for r in run):
                continue
            if best is None or len(run) > best["n_scales"]:
                bx = sum(r["bisector"][0] for r in run)
                by = sum(r["bisector"][1] for r in run)
                best = {
                    "xy": (cx, cy),
                    "n_scales": len(run),
                    "rmse": max(r["rmse"] for r in run),
                    "opening": sum(r["opening"] for r in run) / len(run),
                    "orientation": math.atan2(by, bx),
                }
        if best is not None:
            out[j] = best
    return out


def check_scale(arrival, departure, pj, params: DetectorParams, radius: float) -> dict | None:
    if len(arrival) < params.min_points or len(departure) < params.min_points:
        return None
    reach = params.min_extent_ratio * radius  # option min_extent_ratio (0 in the paper)
    if math.dist(arrival[0], pj) < reach or math.dist(departure[-1], pj) < reach:
        return None
    la = fit(arrival)
    ld = fit(departure)
    if la[3] > params.max_fit_rmse or ld[3] > params.max_fit_rmse:
        return None
    q = intersection(la, ld)
    if q is None or math.dist(q, pj) > params.max_point_distance:
        return None
    ua = direction(la)
    far = arrival[0]
    if ua[0] * (far[0] - q[0]) + ua[1] * (far[1] - q[1]) < 0:
        ua = (-ua[0], -ua[1])
    ud = direction(ld)
    far = departure[-1]
    if ud[0] * (far[0] - q[0]) + ud[1] * (far[1] - q[1]) < 0:
        ud = (-ud[0], -ud[1])
    opening = math.degrees(math.acos(max(-1.0, min(1.0, ua[0] * ud[0] + ua[1] * ud[1]))))
    if not params.min_angle_deg <= opening <= params.max_angle_deg:
        return None
    bx, by = ua[0] + ud[0], ua[1] + ud[1]
    norm = math.hypot(bx, by)
    return {
        "q": q,
        "rmse": max(la[3], ld[3]),
        "opening": opening,
        "bisector": (bx / norm, by / norm) if norm > 0 else (0.0, 0.0),
    }


def merge(cands: dict[int, dict], radius: float) -> list[dict]:
    """Single-linkage clusters within ``radius``; each cluster -> its lowest-RMSE candidate
    (ties: more scales), ordered by the first beam index of the cluster."""
    beams = sorted(cands)
    clusters: list[list[int]] = []
    for b in beams:
        here = cands[b]["xy"]
        linked = [c for c in clusters if any(math.dist(here, cands[o]["xy"]) <= radius for o in c)]
        merged = [b]
        for c in linked:
            merged.extend(c)
            clusters.remove(c)
        clusters.append(sorted(merged))
    clusters.sort(key=lambda c: c[0])
    out = []
    for c in clusters:
        rep = min(c, key=lambda j: (cands[j]["rmse"], -cands[j]["n_scales"], j))
        out.append(
            dict(cands[rep], beam=rep, n_merged=len(c), rmse=max(cands[j]["rmse"] for j in c))
        )
    return out
