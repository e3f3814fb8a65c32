"""Point-to-line ICP of scan points against a point map with normals (numba, no Python loop
per iteration).

The map's points are bucketed in a grid of cells (:class:`PointMap`); the nearest map point
of a scan point is searched in the cells around it. Each iteration pairs every scan point
with its nearest map point within ``max_distance`` and minimises the Huber-weighted sum of
squared point-to-line distances ``n_q · (R p + t - q)`` (or distances to the implicit
surface of the map points around p, :func:`_surface`) plus a prior pulling the pose towards
the prediction with information ``prior_info``, so a corridor (lines in one direction only)
keeps the predicted position along itself.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar, NamedTuple

import numba
import numpy as np
from numpy.typing import NDArray
from pydantic import Field

from laser_corners.options import Options
from laser_corners.pose import check_pose, relative_pose, wrap_angle

__all__ = ["Alignment", "IcpOptions", "PointMap", "icp", "match_share"]

CELL = 0.3
STEP_XY = 1.0 / 30.0
"""ICP stops when a step moves the pose by less than this share of the point noise ``sigma``
(1 mm for 3 cm) and turns it by less than :data:`STEP_YAW`: the implicit surface's
correspondences can flip between two sets a tenth of a millimetre apart forever."""
STEP_YAW = 1e-4
"""Rotation (rad) below which an ICP step counts as converged (with :data:`STEP_XY`)."""
SURFACE_AGREE = 0.94
"""|cos| of the angle (20 degrees) within which a map point's normal must agree with the
nearest point's to join that point's implicit surface (:func:`_surface`): the lines of one
surface, not of a corner's other wall or around a pillar."""
"""Grid cell (m) of a :class:`PointMap`; a search within CELL looks at the 3 x 3 cells around."""


class IcpOptions(Options):
    """The ICP's settings (:func:`icp`): the ``icp`` group of
    :class:`~laser_corners.slam.SlamOptions` and :class:`~laser_corners.localise.LocaliseOptions`
    (``--set icp.max_distance=0.2``, a YAML ``icp:`` table, the ROS 2 parameter
    ``icp.max_distance``).

    The two have their own defaults: the SLAM aligns each scan to its own recent keyframes,
    a few tenths of a second old, so a 0.15 m gate (five times the 3 cm point noise) and 20
    iterations; the localiser aligns to a map made another day (furniture moved, the map's own
    error), so a wider gate, 0.3 m, and 15 iterations per scan.

    Attributes
    ----------
    max_distance : float
        Largest point-to-map distance (m) of a correspondence in the last ICP iterations.
    iterations : int
        Maximum point-to-line ICP iterations per alignment.

    Examples
    --------
    >>> IcpOptions(max_distance=0.2).with_overrides(["iterations=5"])
    IcpOptions(max_distance=0.2, iterations=5)
    """

    title: ClassVar[str] = "IcpOptions"
    what: ClassVar[str] = "option"

    max_distance: float = Field(0.15, ge=0.01, le=5.0)
    iterations: int = Field(20, ge=1, le=200)


@numba.njit(cache=True)
def _bucket(
    xy: NDArray[np.float64], origin: NDArray[np.float64], cell: float, nx: int, ny: int
) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """CSR layout of points by cell: ``order[start[c]:start[c + 1]]`` are the points of cell c."""
    n = xy.shape[0]
    ids = np.empty(n, dtype=np.int64)
    for i in range(n):
        cx = int((xy[i, 0] - origin[0]) / cell)
        cy = int((xy[i, 1] - origin[1]) / cell)
        ids[i] = cy * nx + cx
    order = np.argsort(ids, kind="mergesort")
    start = np.zeros(nx * ny + 1, dtype=np.int64)
    for i in range(n):
        start[ids[i] + 1] += 1
    for c in range(nx * ny):
        start[c + 1] += start[c]
    return start, order


@dataclass
class PointMap:
    """Map points with unit normals (map frame), bucketed in a grid."""

    xy: NDArray[np.float64]
    normals: NDArray[np.float64]
    origin: NDArray[np.float64]
    shape: tuple[int, int]
    start: NDArray[np.int64]
    order: NDArray[np.int64]

    @classmethod
    def build(cls, xy: NDArray[np.float64], normals: NDArray[np.float64]) -> PointMap:
        """A map from points and normals (zero normals: points for overlap only)."""
        xy = np.ascontiguousarray(xy, dtype=np.float64).reshape(-1, 2)
        normals = np.ascontiguousarray(normals, dtype=np.float64).reshape(-1, 2)
        if xy.shape[0] == 0:
            origin, nx, ny = np.zeros(2), 1, 1
        else:
            low, high = xy.min(axis=0), xy.max(axis=0)
            if not (np.isfinite(low).all() and np.isfinite(high).all()):
                raise ValueError("PointMap: map points must be finite")
            origin = low - CELL
            nx, ny = (np.floor((xy.max(axis=0) - origin) / CELL).astype(int) + 2).tolist()
        start, order = _bucket(xy, origin, CELL, nx, ny)
        return cls(xy, normals, origin, (nx, ny), start, order)

    def __len__(self) -> int:
        return int(self.xy.shape[0])

    def buckets(self) -> Buckets:
        """The points and their grid as the kernels take them."""
        nx, ny = self.shape
        return Buckets(self.xy, self.origin, nx, ny, self.start, self.order)


class Buckets(NamedTuple):
    """A :class:`PointMap`'s points and grid as the kernels read them
    (:meth:`PointMap.buckets`)."""

    xy: NDArray[np.float64]
    origin: NDArray[np.float64]
    nx: int
    ny: int
    start: NDArray[np.int64]
    order: NDArray[np.int64]


@numba.njit(cache=True)
def _nearest(px: float, py: float, grid: Buckets, max_d: float) -> int:
    """Index of the nearest map point within ``max_d`` of (px, py), or -1."""
    xy, origin, nx, ny, start, order = grid
    reach = min(math.ceil(max_d / CELL), 3)
    cx = math.floor((px - origin[0]) / CELL)
    cy = math.floor((py - origin[1]) / CELL)
    best = max_d * max_d
    found = -1
    for iy in range(max(cy - reach, 0), min(cy + reach + 1, ny)):
        for ix in range(max(cx - reach, 0), min(cx + reach + 1, nx)):
            c = iy * nx + ix
            for k in range(start[c], start[c + 1]):
                j = order[k]
                dx = xy[j, 0] - px
                dy = xy[j, 1] - py
                d = dx * dx + dy * dy
                if d < best:
                    best = d
                    found = j
    return found


@numba.njit(cache=True)
def _surface(
    px: float,
    py: float,
    grid: Buckets,
    nrm: NDArray,
    max_d: float,
    width: float,
    near: NDArray[np.int64],
) -> tuple[float, float, float, bool]:
    """Signed distance of (px, py) to the map's implicit surface (IMLS: Kolluri, ACM TALG
    2008; Deschaud, ICRA 2018) and that surface's normal: the Gaussian-weighted (``width``)
    means of ``n_i · (p - q_i)`` and of ``n_i`` over the map points within ``2 width`` of p
    whose normals agree with the nearest point's (which must be within ``max_d``) within
    :data:`SURFACE_AGREE`, turned to its side. One pass over the cells finds the nearest point
    and keeps the points within ``2 width`` in ``near`` (scratch, at least the map's size).
    Returns (distance, nx, ny, found)."""
    xy, origin, nx, ny, start, order = grid
    rad = 2.0 * width
    reach = min(math.ceil(max(rad, max_d) / CELL), 3)
    cx = math.floor((px - origin[0]) / CELL)
    cy = math.floor((py - origin[1]) / CELL)
    best = max_d * max_d
    j0 = -1
    m = 0
    for iy in range(max(cy - reach, 0), min(cy + reach + 1, ny)):
        for ix in range(max(cx - reach, 0), min(cx + reach + 1, nx)):
            c = iy * nx + ix
            for k in range(start[c], start[c + 1]):
                j = order[k]
                dx = xy[j, 0] - px
                dy = xy[j, 1] - py
                d2 = dx * dx + dy * dy
                if d2 < best:
                    best = d2
                    j0 = j
                if d2 <= rad * rad:
                    near[m] = j
                    m += 1
    if j0 < 0:
        return 0.0, 0.0, 0.0, False
    inv = 0.5 / (width * width)
    sw = 0.0
    sd = 0.0
    snx = 0.0
    sny = 0.0
    for i in range(m):
        j = near[i]
        dx = px - xy[j, 0]
        dy = py - xy[j, 1]
        ax = nrm[j, 0]
        ay = nrm[j, 1]
        dot = ax * nrm[j0, 0] + ay * nrm[j0, 1]
        if abs(dot) < SURFACE_AGREE:
            continue
        if dot < 0.0:
            ax = -ax
            ay = -ay
        w = math.exp(-(dx * dx + dy * dy) * inv)
        sw += w
        sd += w * (ax * dx + ay * dy)
        snx += w * ax
        sny += w * ay
    if sw <= 0.0:  # pragma: no cover - j0 itself is within the radius
        return 0.0, 0.0, 0.0, False
    return sd / sw, snx / sw, sny / sw, True


@numba.njit(cache=True)
def _icp(
    src: NDArray,
    grid: Buckets,
    nrm: NDArray,
    guess: NDArray,
    prior: NDArray,
    max_d: float,
    sigma: float,
    iterations: int,
    surface: float,
) -> tuple[NDArray, NDArray]:
    xy = grid.xy
    pose = guess.copy()
    info = np.zeros((3, 3))
    near = np.empty(xy.shape[0], dtype=np.int64)
    scale = 1.0 / (sigma * sigma)
    huber = 2.0 * sigma
    for _ in range(iterations):
        h = np.zeros((3, 3))
        g = np.zeros(3)
        c = math.cos(pose[2])
        s = math.sin(pose[2])
        used = 0
        for i in range(src.shape[0]):
            rx = c * src[i, 0] - s * src[i, 1]
            ry = s * src[i, 0] + c * src[i, 1]
            px = rx + pose[0]
            py = ry + pose[1]
            if surface > 0.0:
                r, ux, uy, found = _surface(px, py, grid, nrm, max_d, surface, near)
                if not found:
                    continue
            else:
                j = _nearest(px, py, grid, max_d)
                if j < 0:
                    continue
                ux = nrm[j, 0]
                uy = nrm[j, 1]
                r = ux * (px - xy[j, 0]) + uy * (py - xy[j, 1])
            jac = np.array([ux, uy, -ux * ry + uy * rx])
            w = 1.0 if abs(r) <= huber else huber / abs(r)
            for a in range(3):
                g[a] += w * jac[a] * r
                for b in range(3):
                    h[a, b] += w * jac[a] * jac[b]
            used += 1
        if used < 3:
            break
        diff = pose - guess
        diff[2] = (diff[2] + math.pi) % (2 * math.pi) - math.pi
        info = h * scale
        step = np.linalg.solve(info + prior, -(g * scale + prior @ diff))
        pose += step
        if abs(step[0]) + abs(step[1]) < STEP_XY * sigma and abs(step[2]) < STEP_YAW:
            break
    return pose, info


@numba.njit(cache=True)
def _share(src: NDArray, grid: Buckets, pose: NDArray, max_d: float) -> float:
    c = math.cos(pose[2])
    s = math.sin(pose[2])
    hit = 0
    for i in range(src.shape[0]):
        px = c * src[i, 0] - s * src[i, 1] + pose[0]
        py = s * src[i, 0] + c * src[i, 1] + pose[1]
        if _nearest(px, py, grid, max_d) >= 0:
            hit += 1
    return hit / max(src.shape[0], 1)


@dataclass
class Alignment:
    """Result of :func:`icp`: the pose, the share of points matched and the information."""

    pose: NDArray[np.float64]
    overlap: float
    n_points: int
    information: NDArray[np.float64]
    """Gauss-Newton information of the point residuals (3x3)."""

    def degenerate(self, ratio: float = 0.02) -> bool:
        """Whether the translation is poorly constrained (a corridor): the smaller eigenvalue
        of the translational information is below ``ratio`` times the larger."""
        ev = np.linalg.eigvalsh(self.information[:2, :2])
        return bool(ev[-1] <= 0 or ev[0] < ratio * ev[-1])

    def confirms(
        self, start: NDArray[np.float64], min_overlap: float, max_xy: float, max_yaw: float
    ) -> bool:
        """Whether this alignment, from ``start``, is a small and well-constrained correction:
        at least ``min_overlap`` of the points matched, not :meth:`degenerate`, and ``start``
        moved by at most ``max_xy`` (m) and ``max_yaw`` (rad). The check of the passes that
        re-align against a map that is consistent already (``refine``, ``rescan``)."""
        moved = relative_pose(start, self.pose)
        return (
            self.overlap >= min_overlap
            and not self.degenerate()
            and math.hypot(moved[0], moved[1]) <= max_xy
            and abs(moved[2]) <= max_yaw
        )


def match_share(
    points: NDArray[np.float64], pointmap: PointMap, pose: NDArray[np.float64], distance: float
) -> float:
    """Share of ``points`` (moved by ``pose``) within ``distance`` of a map point."""
    pose = check_pose(pose, "match_share")
    if len(pointmap) == 0 or points.shape[0] == 0:
        return 0.0
    return float(_share(np.ascontiguousarray(points), pointmap.buckets(), pose, distance))


def icp(
    points: NDArray[np.float64],
    pointmap: PointMap,
    guess: NDArray[np.float64],
    prior_info: NDArray[np.float64],
    settings: IcpOptions,
    *,
    inlier_distance: float,
    sigma: float = 0.03,
    overlap_map: PointMap | None = None,
    surface: float = 0.0,
) -> Alignment:
    """Align ``points`` (base frame) to ``pointmap`` starting from ``guess`` (map frame).

    ``settings`` gives the correspondence gate (``max_distance``, m) and the iteration cap.
    ``prior_info`` (3x3) weighs the pull towards ``guess`` against the point residuals of
    standard deviation ``sigma`` (m). The overlap is measured against ``overlap_map`` (all
    points, also those without a normal) when given, else against ``pointmap``.
    ``surface`` > 0: a point's residual is its distance to the map's implicit surface of that
    kernel width (m; :func:`_surface`), not to the line of its nearest map point: the pose
    no longer gains by putting scan points on map points (a keyframe's beam pattern), which
    the nearest point's line rewards wherever its normal is tilted by noise or the surface
    curves.
    """
    guess = check_pose(guess, "icp guess")
    src = np.ascontiguousarray(points, dtype=np.float64)
    if src.shape[0] == 0 or len(pointmap) == 0:
        return Alignment(guess.copy(), 0.0, src.shape[0], np.zeros((3, 3)))
    try:
        pose, info = _icp(
            src,
            pointmap.buckets(),
            pointmap.normals,
            guess,
            np.asarray(prior_info, dtype=np.float64),
            settings.max_distance,
            sigma,
            settings.iterations,
            surface,
        )
    except np.linalg.LinAlgError:  # pragma: no cover - singular system
        return Alignment(guess.copy(), 0.0, src.shape[0], np.zeros((3, 3)))
    pose[2] = wrap_angle(pose[2])
    overlap = match_share(src, overlap_map or pointmap, pose, inlier_distance)
    return Alignment(pose, overlap, src.shape[0], info)
