"""The map as localisation uses it, precomputed once at load: point maps and a global search.

:class:`MapModel` moves every keyframe point of a
:class:`~laser_corners.registration.mapfolder.SavedMap` into the map frame, thins them to one
point per ``map_spacing`` voxel and keeps

* a :class:`~laser_corners.registration.align.PointMap` of the points with a line normal (ICP),
* one of every point (the agreement: share of scan points within ``inlier_distance``),
* a likelihood grid (:class:`~laser_corners.registration.correlative.ScoreGrid`, 0.1 m cells,
  ``exp(-d² / 2σ²)`` with σ = 0.2 m) and the lattice of candidate positions within
  ``global_reach`` of a keyframe (the robot drives where the mapping robot drove) and not
  inside a wall, for :meth:`MapModel.global_search`.

The global search scores every (position, heading) of that lattice by the mean likelihood of
the scan's points (one numba kernel, no Python loop per pose): its cost grows with the
explored area (positions) times the headings times the points, and is paid only while
searching, every ``global_every`` scans. Tracking costs do not grow with the map: the point
maps are bucketed in cells, and a lookup visits the cells around the point.
"""

from __future__ import annotations

import math

import numba
import numpy as np
from numpy.typing import NDArray

from laser_corners.localise.freespace import FreeSpace
from laser_corners.localise.options import LocaliseOptions
from laser_corners.pose import distinct_poses
from laser_corners.registration.align import PointMap
from laser_corners.registration.correlative import ScoreGrid
from laser_corners.registration.mapfolder import SavedMap

__all__ = ["MapModel"]

GLOBAL_GRID = 0.1
"""Cell (m) of the likelihood grid of the global search."""
GLOBAL_SIGMA = 0.2
"""Width (m) of the likelihood of the global search (tolerates its coarse lattice)."""
GLOBAL_POINTS = 120
"""Scan points used by the global search at most (evenly subsampled)."""
LOCAL_POINTS = 80
"""Scan points used by the local (recovery) search at most."""
LOCAL_YAW_STEP = 0.02
"""Heading step (rad) of the local (recovery) search: 0.2 m at 10 m, within the likelihood's
width."""
WINDOW_STEP = 0.2
"""Position step (m) of the window search after a lost track (finer than the global lattice:
the window is small)."""
WALL_CLEARANCE = 0.15
"""Candidate positions closer than this (m) to a map point are not searched."""


@numba.njit(cache=True)
def _search(
    score: NDArray[np.float32],
    origin: NDArray[np.float64],
    res: float,
    rotated: NDArray[np.float64],
    positions: NDArray[np.float64],
) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """Best mean score and heading index per position of ``rotated`` (Y, N, 2) points."""
    ny, nx = score.shape
    n_yaw, n = rotated.shape[0], rotated.shape[1]
    best = np.zeros(positions.shape[0])
    arg = np.zeros(positions.shape[0], dtype=np.int64)
    for p in range(positions.shape[0]):
        ox = positions[p, 0] - origin[0]
        oy = positions[p, 1] - origin[1]
        for y in range(n_yaw):
            acc = 0.0
            for k in range(n):
                ix = math.floor((rotated[y, k, 0] + ox) / res)
                iy = math.floor((rotated[y, k, 1] + oy) / res)
                if 0 <= ix < nx and 0 <= iy < ny:
                    acc += score[iy, ix]
            if acc > best[p]:
                best[p] = acc
                arg[p] = y
        best[p] /= max(n, 1)
    return best, arg


def _voxel_thin(xy: NDArray, spacing: float) -> NDArray[np.int64]:
    """Indices of one point per ``spacing`` voxel (the first)."""
    keys = np.floor(xy / spacing).astype(np.int64)
    _, first = np.unique(keys, axis=0, return_index=True)
    return np.sort(first)


class MapModel:
    """Point maps, likelihood grid and search lattice of a saved map (see the module notes)."""

    def __init__(self, saved: SavedMap, options: LocaliseOptions) -> None:
        xy, normals, line = saved.world_points()
        keep = _voxel_thin(xy, options.map_spacing) if len(xy) else np.zeros(0, np.int64)
        xy, normals, line = xy[keep], normals[keep], line[keep]
        self.saved = saved
        self.n_points = len(xy)
        self.lines = PointMap.build(xy[line], normals[line])
        self.every = PointMap.build(xy, np.zeros_like(xy))
        self.grid = ScoreGrid.build(xy, GLOBAL_GRID, GLOBAL_SIGMA, margin=1.0)
        self.positions = self._lattice(saved.poses[:, :2], options)
        self.space = FreeSpace.build(saved)

    def _lattice(self, centres: NDArray, options: LocaliseOptions) -> NDArray[np.float64]:
        """Lattice positions within ``global_reach`` of a keyframe, clear of the walls."""
        step = options.global_resolution
        disc = _disc(options.global_reach, step)
        cells = np.round(centres / step).astype(np.int64)[:, None, :]
        cells = cells + np.round(disc / step).astype(np.int64)[None]
        return self._clear(np.unique(cells.reshape(-1, 2), axis=0) * step)

    def local_search(
        self, points: NDArray[np.float64], centre: NDArray[np.float64], xy: float, yaw: float
    ) -> NDArray[np.float64]:
        """The best pose of ``points`` (base frame) within ``xy`` (m) and ``yaw`` (rad) of
        ``centre`` on the likelihood grid: a lattice of :data:`GLOBAL_GRID` and
        :data:`LOCAL_YAW_STEP` steps, scored exhaustively by the global search's kernel."""
        n = math.ceil(xy / GLOBAL_GRID)
        off = GLOBAL_GRID * np.arange(-n, n + 1)
        ox, oy = np.meshgrid(off, off)
        positions = np.column_stack([ox.ravel() + centre[0], oy.ravel() + centre[1]])
        yaws = centre[2] + LOCAL_YAW_STEP * np.arange(
            -math.ceil(yaw / LOCAL_YAW_STEP), math.ceil(yaw / LOCAL_YAW_STEP) + 1
        )
        best, arg = self._score(_subsample(points, LOCAL_POINTS), positions, yaws)
        p = int(np.argmax(best))
        return np.array([*positions[p], yaws[arg[p]]])

    def _score(
        self, points: NDArray, positions: NDArray, yaws: NDArray
    ) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
        """Best mean likelihood and heading index per position."""
        c, s = np.cos(yaws)[:, None], np.sin(yaws)[:, None]
        rotated = np.stack(
            [c * points[:, 0] - s * points[:, 1], s * points[:, 0] + c * points[:, 1]], axis=-1
        )
        return _search(
            self.grid.score,
            self.grid.origin,
            self.grid.resolution,
            np.ascontiguousarray(rotated),
            np.ascontiguousarray(positions, dtype=np.float64),
        )

    def global_search(
        self, points: NDArray[np.float64], yaw_step: float, count: int
    ) -> list[tuple[NDArray[np.float64], float]]:
        """The ``count`` best poses of ``points`` (base frame) over the whole map, at least
        1 m or 0.3 rad apart, with their mean likelihood."""
        if len(points) == 0 or len(self.positions) == 0:
            return []
        yaws = np.arange(-math.pi, math.pi, yaw_step)
        return self._best(_subsample(points), self.positions, yaws, count, (1.0, 0.3))

    def window_search(
        self,
        points: NDArray[np.float64],
        centre: NDArray[np.float64],
        xy: float,
        yaw: float,
        yaw_step: float,
        count: int,
        apart: tuple[float, float],
    ) -> list[tuple[NDArray[np.float64], float]]:
        """The global search restricted to a window: the ``count`` best poses of ``points``
        (base frame) within ``xy`` (m, a disc) and ``yaw`` (rad) of ``centre``, on a lattice of
        :data:`WINDOW_STEP` clear of the walls, at least ``apart`` (m, rad) apart.

        Used after a lost track, around its dead-reckoned pose: the prior excludes the
        look-alikes elsewhere in the map, and the lattice does not need a keyframe nearby.
        """
        if len(points) == 0:
            return []
        positions = self._clear(_disc(xy, WINDOW_STEP) + np.asarray(centre[:2], float))
        if len(positions) == 0:
            return []
        k = math.ceil(yaw / yaw_step)
        yaws = centre[2] + yaw_step * np.arange(-k, k + 1)
        return self._best(_subsample(points), positions, yaws, count, apart)

    def _clear(self, xy: NDArray[np.float64]) -> NDArray[np.float64]:
        """The positions of ``xy`` on the likelihood grid and not inside a wall."""
        wall = math.exp(-0.5 * (WALL_CLEARANCE / GLOBAL_SIGMA) ** 2)
        clear = self.grid.at(xy, outside=np.inf) < wall  # off the grid: not searched
        return np.ascontiguousarray(xy[clear], dtype=np.float64)

    def _best(
        self,
        points: NDArray[np.float64],
        positions: NDArray[np.float64],
        yaws: NDArray[np.float64],
        count: int,
        apart: tuple[float, float],
    ) -> list[tuple[NDArray[np.float64], float]]:
        """The ``count`` best (position, heading) poses, at least ``apart`` (m, rad) apart."""
        best, arg = self._score(points, positions, yaws)
        poses = np.column_stack([positions, yaws[arg]])
        chosen = distinct_poses(poses, np.argsort(-best), count, *apart)
        return [(poses[p], float(best[p])) for p in chosen]


def _disc(radius: float, step: float) -> NDArray[np.float64]:
    """Offsets (K, 2) of a square lattice of ``step`` within ``radius`` of the origin."""
    n = math.floor(radius / step + 1e-9)
    off = step * np.arange(-n, n + 1)
    ox, oy = np.meshgrid(off, off)
    disc = np.column_stack([ox.ravel(), oy.ravel()])
    return disc[np.hypot(disc[:, 0], disc[:, 1]) <= radius + 1e-9]


def _subsample(points: NDArray[np.float64], most: int = GLOBAL_POINTS) -> NDArray[np.float64]:
    """At most ``most`` of ``points``, evenly spread over the scan."""
    if len(points) <= most:
        return np.ascontiguousarray(points)
    return np.ascontiguousarray(points[np.linspace(0, len(points) - 1, most).astype(int)])
