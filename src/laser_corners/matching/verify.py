"""Scan verification of a registration: do the two scans agree under the estimated pose?

A keypoint hypothesis (one match with its orientation, or two matches) fixes an SE(2) pose
from a handful of points; the scans themselves then say whether it is right. The points of
scan B, moved into A's sensor frame by the pose, are looked up along A's beams
(:func:`scan_agreement`, an O(points) numba loop):

* a point is **tested** when it lies inside A's field of view and range interval and A has a
  valid return on its beam or on one of the two neighbouring beams;
* it **agrees** when one of those returns is within ``tolerance`` of the point's range
  (the same surface; the neighbouring beams absorb small rotation errors and grazing walls);
* it **conflicts** ("seen through") when it is closer than every one of those returns by more
  than ``tolerance``: A's beams went through the place where B saw a surface;
* otherwise it is occluded in A (behind A's return) and says nothing.

The check runs both ways (B into A and A into B); the registration passes when, in both
directions, at least ``min_points`` points were tested, at least ``min_agreement`` of them
agree and at most ``max_conflict`` of them conflict. The *agreement* of the registration is
the smaller of the two agreement fractions.

Scans enter the kernels as flat arrays (:func:`scan_arrays`): the ranges (NaN where there is
no valid return), the geometry ``(angle_min, angle_increment, range_min, range_max)`` and up to
``max_points`` valid points, evenly spread over the beams.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np
from numpy.typing import NDArray

from laser_corners.matching.kernel_args import KernelOptions, ScanArrays, scan_geometry
from laser_corners.scan import LaserScan

__all__ = [
    "ScanArrays",
    "align",
    "beam_of",
    "precheck",
    "scan_agreement",
    "scan_arrays",
    "verify_pose",
]

PRECHECK = 16
"""Points of the cheap first look of :func:`verify_pose`."""
PRECHECK_CONFLICTS = 2
"""Conflicts allowed among them (with the first look's loose tolerance)."""


def scan_arrays(scan: LaserScan, max_points: int = 90) -> ScanArrays:
    """Flat arrays of ``scan`` for the verification kernels.

    Parameters
    ----------
    scan : LaserScan
        The scan.
    max_points : int
        The valid points are evenly thinned to at most this many.

    Returns
    -------
    ScanArrays
        ``ranges`` (N,), NaN where the beam has no valid return; ``geometry`` (4,),
        ``angle_min, angle_increment, range_min, range_max``; ``points`` (P, 2), the valid
        points (sensor frame), at most ``max_points``.
    """
    xy, valid = scan.to_cartesian()
    pts = xy[valid]
    if len(pts) > max_points:
        pts = pts[np.linspace(0, len(pts) - 1, max_points).round().astype(np.int64)]
    # interleaved order: any prefix is spread over the whole scan (the cheap first look)
    stride = max(1, len(pts) // PRECHECK)
    pts = pts[np.argsort(np.arange(len(pts)) % stride, kind="stable")]
    ranges = np.where(valid, scan.ranges, np.nan).astype(np.float64)
    geom = np.array(
        [scan.angle_min, scan.angle_increment, scan.range_min, scan.range_max], dtype=np.float64
    )
    return ScanArrays(ranges, geom, np.ascontiguousarray(pts, dtype=np.float64))


@nb.njit(cache=True, nogil=True)
def beam_of(bearing: float, amin: float, ainc: float) -> float:
    """Fractional beam index of a bearing (any sign of ``ainc``, any wrap of the scan)."""
    d = bearing - amin
    d = d - 2.0 * math.pi * math.floor(d / (2.0 * math.pi))  # [0, 2 pi)
    if ainc < 0.0:
        d -= 2.0 * math.pi
    return d / ainc


@nb.njit(cache=True, nogil=True)
def scan_agreement(
    ranges: NDArray[np.float64],
    geom: NDArray[np.float64],
    pts: NDArray[np.float64],
    pose: tuple[float, float, float],
    tol: float,
    max_conflicts: int,
) -> tuple[int, int, int]:
    """Points ``pts`` (another scan's frame), moved by ``pose`` (tx, ty, th: ``p' = R(th)·p +
    t``), looked up along the beams of the scan ``(ranges, geom)``; returns ``(tested, agree,
    conflict)``.

    Stops early (returning what it counted) once ``conflict`` exceeds ``max_conflicts``.
    """
    tx, ty, th = pose
    n = ranges.shape[0]
    g = scan_geometry(geom)
    amin, ainc = g.angle_min, g.angle_increment
    c = math.cos(th)
    s = math.sin(th)
    tested = 0
    agree = 0
    conflict = 0
    for p in range(pts.shape[0]):
        x = c * pts[p, 0] - s * pts[p, 1] + tx
        y = s * pts[p, 0] + c * pts[p, 1] + ty
        r = math.sqrt(x * x + y * y)
        if not g.range_min < r < g.range_max:
            continue
        k = math.floor(beam_of(math.atan2(y, x), amin, ainc) + 0.5)
        if k < 0 or k >= n:
            continue
        best = math.inf
        nearest = math.inf
        for j in range(max(k - 1, 0), min(k + 2, n)):
            rj = ranges[j]
            if rj == rj:  # not NaN: a valid return
                best = min(best, abs(rj - r))
                nearest = min(nearest, rj)
        if nearest == math.inf:
            continue
        tested += 1
        if best <= tol:
            agree += 1
        elif r < nearest - tol:
            conflict += 1
            if conflict > max_conflicts:
                break
    return tested, agree, conflict


@nb.njit(cache=True, nogil=True)
def align(
    ranges: NDArray[np.float64],
    geom: NDArray[np.float64],
    pts: NDArray[np.float64],
    pose: tuple[float, float, float],
    iterations: int,
    max_d: float,
) -> tuple[float, float, float]:
    """Refine ``pose`` (tx, ty, th: ``p' = R(th)·p + t``) of ``pts`` onto the scan ``(ranges,
    geom)``: Gauss-Newton on point-to-line distances, each moved point paired with the return
    on its beam (the line through the two neighbouring returns), pairs farther than ``max_d``
    (halved at each iteration, not below 0.05 m) left out. Returns the pose unchanged when
    under-determined."""
    tx, ty, th = pose
    n = ranges.shape[0]
    g = scan_geometry(geom)
    amin, ainc = g.angle_min, g.angle_increment
    ca, sa = math.cos(ainc), math.sin(ainc)
    h = np.zeros((3, 3))
    g = np.zeros(3)
    d_max = max_d
    for _ in range(iterations):
        h[:, :] = 0.0
        g[:] = 0.0
        c = math.cos(th)
        s = math.sin(th)
        used = 0
        for p in range(pts.shape[0]):
            bx, by = pts[p, 0], pts[p, 1]
            x = c * bx - s * by + tx
            y = s * bx + c * by + ty
            k = math.floor(beam_of(math.atan2(y, x), amin, ainc) + 0.5)
            if k < 1 or k >= n - 1:
                continue
            r0, r1, r2 = ranges[k - 1], ranges[k], ranges[k + 1]
            if not (abs(r0 - r1) < 0.2 and abs(r2 - r1) < 0.2):  # NaN fails too
                continue
            c1 = math.cos(amin + k * ainc)
            s1 = math.sin(amin + k * ainc)
            x1, y1 = r1 * c1, r1 * s1
            # the neighbouring beams' directions by rotating beam k's by -+ ainc
            x0, y0 = r0 * (c1 * ca + s1 * sa), r0 * (s1 * ca - c1 * sa)
            x2, y2 = r2 * (c1 * ca - s1 * sa), r2 * (s1 * ca + c1 * sa)
            nx, ny = y0 - y2, x2 - x0
            norm = math.hypot(nx, ny)
            if norm == 0.0:
                continue
            nx /= norm
            ny /= norm
            e = nx * (x - x1) + ny * (y - y1)
            if abs(e) > d_max:
                continue
            # d e / d(tx, ty, th)
            j = (nx, ny, nx * (-s * bx - c * by) + ny * (c * bx - s * by))
            for u in range(3):
                g[u] += j[u] * e
                for v in range(3):
                    h[u, v] += j[u] * j[v]
            used += 1
        if used < 6 or not abs(np.linalg.det(h)) > 1e-9:
            break
        step = np.linalg.solve(h, g)
        tx -= step[0]
        ty -= step[1]
        th -= step[2]
        d_max = max(0.5 * d_max, 0.05)
    return tx, ty, th


@nb.njit(cache=True, nogil=True)
def _one_way(
    a: ScanArrays, b: ScanArrays, pose: tuple[float, float, float], options: KernelOptions
) -> float:
    """Share of B's points (moved by ``pose``) that agree with A's scan; -1 when the check
    fails (:class:`~laser_corners.matching.kernel_args.KernelOptions` ``options``)."""
    pts = b.points
    max_conflict = options.max_scan_conflict
    tested, agree, conflict = scan_agreement(
        a.ranges, a.geometry, pts, pose, options.scan_tolerance, int(max_conflict * pts.shape[0])
    )
    share = agree / max(pts.shape[0], 1)
    if (
        tested < options.min_scan_points
        or conflict > max_conflict * tested
        or share < options.min_scan_agreement
    ):
        return -1.0
    return share


@nb.njit(cache=True, nogil=True)
def precheck(
    a: ScanArrays, b: ScanArrays, pose: tuple[float, float, float], options: KernelOptions
) -> bool:
    """The cheap first look of :func:`verify_pose`: the first ``PRECHECK`` points of B
    (stored evenly spread) with a tolerance of ``3·scan_tolerance``; fails when fewer than
    ``min_scan_agreement`` of them agree or more than ``PRECHECK_CONFLICTS`` conflict. True
    when the check is off (``options.verify_scan`` false)."""
    if not options.verify_scan:
        return True
    pre = b.points[:PRECHECK]
    _, agree, conflict = scan_agreement(
        a.ranges, a.geometry, pre, pose, 3.0 * options.scan_tolerance, PRECHECK_CONFLICTS
    )
    return agree >= options.min_scan_agreement * pre.shape[0] and conflict <= PRECHECK_CONFLICTS


@nb.njit(cache=True, nogil=True)
def verify_pose(
    a: ScanArrays, b: ScanArrays, pose: tuple[float, float, float], options: KernelOptions
) -> tuple[float, tuple[float, float, float]]:
    """Both-way scan check of the pose (tx, ty, θ) of B in A (``p_A = R·p_B + t``).

    ``options``: the ``verify_scan``, ``scan_tolerance``, ``min_scan_agreement``,
    ``max_scan_conflict``, ``min_scan_points`` and ``align_iterations`` fields of
    :class:`~laser_corners.matching.kernel_args.KernelOptions`. First the cheap
    :func:`precheck`, then the pose is refined on A's scan (:func:`align`) and checked both
    ways. Returns ``(agreement, pose)``: the smaller share of agreeing points of the two
    directions and the refined pose, or agreement -1 when the check fails; 1.0 and the pose
    unchanged when the check is disabled.
    """
    if not options.verify_scan:
        return 1.0, pose
    if not precheck(a, b, pose, options):
        return -1.0, pose
    pose = align(
        a.ranges, a.geometry, b.points, pose, options.align_iterations, 4.0 * options.scan_tolerance
    )
    ab = _one_way(a, b, pose, options)
    if ab < 0.0:
        return -1.0, pose
    # the inverse pose: p_B = Rᵀ·(p_A - t)
    tx, ty, th = pose
    c = math.cos(th)
    s = math.sin(th)
    ba = _one_way(b, a, (-(c * tx + s * ty), s * tx - c * ty, -th), options)
    if ba < 0.0:
        return -1.0, pose
    return min(ab, ba), pose
