"""Scan points for alignment: beams to points, thinning and line normals (numba kernels)."""

from __future__ import annotations

import numba
import numpy as np
from numpy.typing import NDArray

from laser_corners.scan import LaserScan

__all__ = ["ScanPoints", "scan_points", "transform"]


@numba.njit(cache=True)
def _thin(xy: NDArray[np.float64], spacing: float) -> NDArray[np.int64]:
    """Indices of points kept so consecutive kept points are at least ``spacing`` apart."""
    keep = np.empty(xy.shape[0], dtype=np.int64)
    n = 0
    s2 = spacing * spacing
    for i in range(xy.shape[0]):
        if n == 0:
            keep[n] = i
            n += 1
            continue
        j = keep[n - 1]
        dx = xy[i, 0] - xy[j, 0]
        dy = xy[i, 1] - xy[j, 1]
        if dx * dx + dy * dy >= s2:
            keep[n] = i
            n += 1
    return keep[:n]


@numba.njit(cache=True)
def _normals(
    xy: NDArray[np.float64], radius: float
) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
    """Unit normal of the line through each point's scan neighbours within ``radius``
    (principal axes of their scatter); ``ok`` False where the neighbourhood is not a line."""
    n = xy.shape[0]
    normals = np.zeros((n, 2))
    ok = np.zeros(n, dtype=np.bool_)
    r2 = radius * radius
    for i in range(n):
        sx = 0.0
        sy = 0.0
        cnt = 0
        lo = i
        while lo > 0 and (xy[lo - 1, 0] - xy[i, 0]) ** 2 + (xy[lo - 1, 1] - xy[i, 1]) ** 2 < r2:
            lo -= 1
        hi = i
        while hi < n - 1 and (xy[hi + 1, 0] - xy[i, 0]) ** 2 + (xy[hi + 1, 1] - xy[i, 1]) ** 2 < r2:
            hi += 1
        for k in range(lo, hi + 1):
            sx += xy[k, 0]
            sy += xy[k, 1]
            cnt += 1
        if cnt < 3:
            continue
        mx = sx / cnt
        my = sy / cnt
        cxx = 0.0
        cxy = 0.0
        cyy = 0.0
        for k in range(lo, hi + 1):
            dx = xy[k, 0] - mx
            dy = xy[k, 1] - my
            cxx += dx * dx
            cxy += dx * dy
            cyy += dy * dy
        tr = cxx + cyy
        det = cxx * cyy - cxy * cxy
        disc = np.sqrt(max(tr * tr / 4.0 - det, 0.0))
        small = tr / 2.0 - disc  # smaller eigenvalue: spread across the line
        large = tr / 2.0 + disc
        if large <= 0.0 or small > 0.1 * large:
            continue
        # eigenvector of the small eigenvalue
        if abs(cxy) > 1e-12:
            nx = small - cyy
            ny = cxy
        elif cxx < cyy:
            nx = 1.0
            ny = 0.0
        else:
            nx = 0.0
            ny = 1.0
        norm = np.sqrt(nx * nx + ny * ny)
        normals[i, 0] = nx / norm
        normals[i, 1] = ny / norm
        ok[i] = True
    return normals, ok


@numba.njit(cache=True)
def _beams(
    ranges: NDArray[np.float64], angle_min: float, increment: float, lo: float, hi: float
) -> NDArray[np.float64]:
    """Sensor-frame points of the beams with ``lo < range < hi``, counter-clockwise order."""
    n = ranges.size
    out = np.empty((n, 2))
    m = 0
    for k in range(n):
        i = k if increment > 0 else n - 1 - k
        r = ranges[i]
        if np.isfinite(r) and lo < r < hi:
            a = angle_min + increment * i
            out[m, 0] = r * np.cos(a)
            out[m, 1] = r * np.sin(a)
            m += 1
    return out[:m]


class ScanPoints:
    """The thinned points of one scan in the base frame, with line normals.

    Attributes
    ----------
    xy : ndarray, shape (M, 2)
        Points in the base frame (mount applied).
    normals : ndarray, shape (M, 2)
        Unit normals (base frame); zero where ``has_normal`` is False.
    has_normal : ndarray of bool, shape (M,)
    """

    __slots__ = ("has_normal", "normals", "xy")

    def __init__(self, xy: NDArray, normals: NDArray, has_normal: NDArray) -> None:
        self.xy = xy
        self.normals = normals
        self.has_normal = has_normal


def scan_points(
    scan: LaserScan,
    mount: NDArray[np.float64],
    min_range: float,
    max_range: float,
    spacing: float,
) -> ScanPoints:
    """Valid beams of ``scan`` (within ``(min_range, max_range)`` and the scan's own limits)
    as points in the base frame, thinned to ``spacing``, with normals."""
    hi = min(max_range, scan.range_max)
    lo = max(min_range, scan.range_min)
    sensor = _beams(
        np.asarray(scan.ranges, dtype=np.float64), scan.angle_min, scan.angle_increment, lo, hi
    )
    if sensor.shape[0] == 0:
        empty = np.zeros((0, 2))
        return ScanPoints(empty, empty, np.zeros(0, dtype=bool))
    normals, ok = _normals(sensor, max(3.0 * spacing, 0.15))
    keep = _thin(sensor, spacing) if spacing > 0 else np.arange(sensor.shape[0])
    sensor, normals, ok = sensor[keep], normals[keep], ok[keep]
    c, s = np.cos(mount[2]), np.sin(mount[2])
    rot = np.array([[c, -s], [s, c]])
    xy = sensor @ rot.T + mount[:2]
    return ScanPoints(np.ascontiguousarray(xy), np.ascontiguousarray(normals @ rot.T), ok)


def transform(xy: NDArray[np.float64], pose: NDArray[np.float64]) -> NDArray[np.float64]:
    """Points ``xy`` (N, 2) moved by ``pose`` (x, y, yaw)."""
    c, s = np.cos(pose[2]), np.sin(pose[2])
    return xy @ np.array([[c, s], [-s, c]]) + pose[:2]


def rotate(v: NDArray[np.float64], yaw: float) -> NDArray[np.float64]:
    """Vectors ``v`` (N, 2) rotated by ``yaw``."""
    c, s = np.cos(yaw), np.sin(yaw)
    return v @ np.array([[c, s], [-s, c]])
