"""The map as localisation uses it, precomputed once at load: point maps and a global search.

:class:`MapModel` moves every keyframe point of a
:class:`~laser_corners.registration.mapfolder.SavedMap` into the map frame, thins them to one
point per ``map_spacing`` voxel and keeps

* a :class:`~laser_corners.registration.align.PointMap` of the points with a line normal (ICP),
* one of every point (the agreement: share of scan points within ``inlier_distance``),
* a likelihood grid (:class:`~laser_corners.registration.correlative.ScoreGrid`, 0.1 m cells,
  ``exp(-d² / 2σ²)`` with σ = 0.2 m), its max-pooled levels
  (:class:`~laser_corners.registration.global_search.Pyramid`) and the lattice of candidate
  positions within ``global_reach`` of a keyframe (the robot drives where the mapping robot
  drove) and not inside a wall, for :meth:`MapModel.global_search`.

The global search finds the best (position, heading) poses of that lattice by the mean
likelihood of the scan's points, those that scoring every pose would find, by a multi-level
branch and bound (:func:`~laser_corners.registration.global_search.best_poses`): the pooled
levels cost about 7 float32 grids of the map's 0.1 m cells (28 bytes per cell: 28 MB for a
100 m x 100 m bounding box), made once at load; a search costs a few milliseconds where the
scan fits one place, growing with the map's area, the headings and the points, and is paid
only while searching, every ``global_every`` scans. Tracking costs do not grow with the map:
the point maps are bucketed in cells, and a lookup visits the cells around the point.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from laser_corners.localise.freespace import FreeSpace
from laser_corners.localise.options import LocaliseOptions
from laser_corners.registration.align import PointMap
from laser_corners.registration.correlative import ScoreGrid
from laser_corners.registration.global_search import Lattice, Pyramid, SlicedSearch, best_poses
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
        self.lattice = self._lattice(saved.poses[:, :2], options)
        self.pyramid = Pyramid.build(self.grid, self.lattice.cells)
        self.space = FreeSpace.build(saved)

    def _lattice(self, centres: NDArray, options: LocaliseOptions) -> Lattice:
        """Lattice positions within ``global_reach`` of a keyframe, clear of the walls; the
        step is ``global_resolution`` to the nearest whole number of grid cells."""
        cells = max(1, round(options.global_resolution / GLOBAL_GRID))
        step = cells * GLOBAL_GRID
        origin = step * np.floor(self.grid.origin / step)
        extent = self.grid.origin + GLOBAL_GRID * np.array(self.grid.score.shape[::-1])
        cols, rows = np.ceil((extent - origin) / step).astype(np.int64) + 1
        disc = np.round(_disc(options.global_reach, step) / step).astype(np.int64)
        near = np.round((centres - origin) / step).astype(np.int64)[:, None, :] + disc[None]
        near = near.reshape(-1, 2)
        near = near[(near >= 0).all(axis=1) & (near[:, 0] < cols) & (near[:, 1] < rows)]
        allowed = np.zeros((rows, cols), dtype=bool)
        allowed[near[:, 1], near[:, 0]] = True
        lattice = Lattice(origin, cells, allowed)
        i, j = np.nonzero(allowed)
        allowed[i, j] = self._clear(lattice.positions(GLOBAL_GRID))
        return lattice

    @property
    def positions(self) -> NDArray[np.float64]:
        """The positions (K, 2) of the global search."""
        return self.lattice.positions(GLOBAL_GRID)

    def local_search(
        self, points: NDArray[np.float64], centre: NDArray[np.float64], xy: float, yaw: float
    ) -> NDArray[np.float64]:
        """The best pose of ``points`` (base frame) within ``xy`` (m) and ``yaw`` (rad) of
        ``centre`` on the likelihood grid: a lattice of :data:`GLOBAL_GRID` and
        :data:`LOCAL_YAW_STEP` steps (the global search's); ``centre`` when no point lands
        near the map."""
        n = math.ceil(xy / GLOBAL_GRID)
        origin = np.asarray(centre[:2], dtype=np.float64) - n * GLOBAL_GRID
        lattice = Lattice(origin, 1, np.ones((2 * n + 1, 2 * n + 1), dtype=bool))
        k = math.ceil(yaw / LOCAL_YAW_STEP)
        yaws = centre[2] + LOCAL_YAW_STEP * np.arange(-k, k + 1)
        found = best_poses(
            self.pyramid, lattice, _subsample(points, LOCAL_POINTS), yaws, 1, (0.0, 0.0)
        )
        return found[0][0] if found else np.array(centre, dtype=np.float64)

    def global_search(
        self, points: NDArray[np.float64], yaw_step: float, count: int
    ) -> list[tuple[NDArray[np.float64], float]]:
        """The ``count`` best poses of ``points`` (base frame) over the whole map, at least
        1 m or 0.3 rad apart, with their mean likelihood."""
        return self.global_slices(points, yaw_step, count).finish()

    def global_slices(
        self, points: NDArray[np.float64], yaw_step: float, count: int
    ) -> SlicedSearch:
        """:meth:`global_search`, to be run in slices (:class:`SlicedSearch`)."""
        yaws = np.arange(-math.pi, math.pi, yaw_step)
        pts = _subsample(points)
        return SlicedSearch(self.pyramid, self.lattice, pts, yaws, count, (1.0, 0.3))

    def window_slices(
        self,
        points: NDArray[np.float64],
        centre: NDArray[np.float64],
        xy: float,
        yaw: float,
        yaw_step: float,
        count: int,
        apart: tuple[float, float],
    ) -> SlicedSearch:
        """The global search restricted to a window, to be run in slices
        (:class:`SlicedSearch`; ``.finish()`` runs it whole): the ``count`` best poses of
        ``points`` (base frame) within ``xy`` (m, a disc) and ``yaw`` (rad) of ``centre``, on
        a lattice of :data:`WINDOW_STEP` clear of the walls, at least ``apart`` (m, rad) apart.

        Used after a lost track, around its dead-reckoned pose: the prior excludes the
        look-alikes elsewhere in the map, and the lattice does not need a keyframe nearby.
        """
        cells = max(1, round(WINDOW_STEP / GLOBAL_GRID))
        n = math.floor(xy / WINDOW_STEP + 1e-9)
        off = WINDOW_STEP * np.arange(-n, n + 1)
        inside = np.hypot(off[:, None], off[None, :]) <= xy + 1e-9
        lattice = Lattice(np.asarray(centre[:2], dtype=np.float64) + off[0], cells, inside)
        i, j = np.nonzero(inside)
        inside[i, j] = self._clear(lattice.positions(GLOBAL_GRID))
        k = math.ceil(yaw / yaw_step)
        yaws = centre[2] + yaw_step * np.arange(-k, k + 1)
        return SlicedSearch(self.pyramid, lattice, _subsample(points), yaws, count, apart)

    def _clear(self, xy: NDArray[np.float64]) -> NDArray[np.bool_]:
        """Whether each position of ``xy`` is on the likelihood grid and not inside a wall."""
        wall = math.exp(-0.5 * (WALL_CLEARANCE / GLOBAL_SIGMA) ** 2)
        return self.grid.at(xy, outside=np.inf) < wall  # off the grid: not searched


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
