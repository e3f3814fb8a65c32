"""Virtual keyframes of an occupancy grid: a map another package made, ready for localisation.

Most robots already have a map from slam_toolbox, Cartographer or GMapping, saved as a ROS
``map_server`` map (``map.yaml`` + image, read by :func:`~laser_corners.io.occupancy.read_map`).
Localisation (:mod:`laser_corners.localise`) needs keyframes: poses with their scan points and
normals. :func:`virtual_keyframes` makes them from the grid alone:

1. **Poses.** The grid is cut into blocks of ``spacing`` metres (default :data:`SPACING`); in
   every block, the free cell farthest from any occupied or unknown cell (Euclidean distance
   transform, cells outside the image count as unknown) becomes a keyframe when it is at least
   ``clearance`` (:data:`CLEARANCE`) from them. Picking the most central cell of each block,
   rather than a fixed lattice, puts a keyframe in every door and corridor wider than twice the
   clearance. The heading is the grid's (``origin`` yaw): the virtual scanner sees all around.
2. **Virtual scans.** At each pose a 360° scanner of :data:`BEAMS` beams (0.5°) and range
   :data:`RANGE_MAX` (30 m, the SLAM's ``max_range``) is cast through the grid (one numba
   kernel, Amanatides-Woo cell traversal): a beam ends in the first *occupied* cell
   (occupancy >= :data:`~laser_corners.io.occupancy.OCCUPIED_PERCENT`), at the middle of its
   path through that cell (a wall's surface lies anywhere in the cell it marks, so the middle
   is unbiased), or where it passes between two occupied cells less than
   :data:`_WIDTH` cells on either side of it (walls seen sparsely, every other cell, or drawn
   8-connected, do not leak); it gives no return (``inf``) when it first meets an unknown or
   uncertain cell, leaves the image or passes ``range_max``: unknown space is not evidence of
   a wall. Free cells are those with occupancy 0..:data:`~laser_corners.io.occupancy.FREE_PERCENT`,
   and so are unknown *specks* (unknown cells that a 3 x 3 opening removes: the cells between
   the rays of a far, sparse scan), which would otherwise stop the beams and keep keyframes
   out of most of a room.
3. **Points.** The scans become keyframe points + normals exactly as a real keyframe's do
   (:func:`~laser_corners.registration.mapfolder.keyframe_arrays` ->
   :func:`~laser_corners.registration.points.scan_points`, the SLAM's default range limits and
   spacing), with a zero mount (the virtual scanner is at the base).

The virtual scans are kept as :class:`~laser_corners.scan.LaserScan` (``frame_id``
:data:`FRAME`, stamp 0) so that anything built per keyframe from scans (a keypoint index)
can be built from them too.

Cost: the distance transform is linear in the grid's cells; the ray casting is
``K x BEAMS`` beams, each visiting the cells up to its end (at most ``RANGE_MAX /
resolution``): linear in the free area (``K`` = area / ``spacing``²) times the mean free
path. Measured figures are in docs/localise.md ("Maps made by other packages").
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numba
import numpy as np
from numpy.typing import NDArray
from scipy.ndimage import binary_dilation, binary_opening, distance_transform_edt

from laser_corners.io.occupancy import FREE_PERCENT, OCCUPIED_PERCENT, OccupancyGrid
from laser_corners.registration.place_index import PlaceOptions
from laser_corners.scan import LaserScan

__all__ = [
    "BEAMS",
    "CLEARANCE",
    "FRAME",
    "RANGE_MAX",
    "SPACING",
    "PointSettings",
    "VirtualKeyframes",
    "cast_grid",
    "free_poses",
    "virtual_keyframes",
]

SPACING = 0.75
"""Side (m) of the blocks of free space that get one virtual keyframe each."""
CLEARANCE = 0.3
"""A virtual keyframe is at least this far (m) from every occupied or unknown cell."""
BEAMS = 720
"""Beams of the virtual 360° scanner (0.5° apart)."""
RANGE_MAX = 30.0
"""Range (m) of the virtual scanner (the SLAM's default ``max_range``)."""
FRAME = "virtual"
"""``frame_id`` of the virtual scans."""
_FREE, _OCCUPIED, _STOP, _NEAR = 0, 1, 2, 4
"""Cell states of the ray casting: free (walk on), occupied (a return), anything else (stop,
no return); the flag ``_NEAR`` marks the cells next to an occupied one."""
_KIND = 3
"""The bits of the free / occupied / stop state."""
_WIDTH = 1.5
"""A beam passing between two occupied cells whose centres are within this (cells) of it,
one on each side, stops there: walls with one-cell holes or drawn 8-connected (Bresenham) do
not leak."""


@numba.njit(cache=True)
def _gap(
    state: NDArray[np.int8], ix: int, iy: int, x0: float, y0: float, dx: float, dy: float
) -> float:
    """Along-ray distance (cells) at which the ray passes between two occupied cells of the
    3 x 3 around ``(ix, iy)``, one on each side within :data:`_WIDTH` of it (a wall with a
    one-cell hole, or drawn 8-connected); ``inf`` when it does not."""
    rows, cols = state.shape
    left = np.inf
    right = np.inf
    for y in range(iy - 1, iy + 2):
        for x in range(ix - 1, ix + 2):
            if 0 <= x < cols and 0 <= y < rows and state[y, x] & _KIND == _OCCUPIED:
                cx, cy = x + 0.5 - x0, y + 0.5 - y0
                along = cx * dx + cy * dy
                across = cx * dy - cy * dx
                if 0.0 < across <= _WIDTH:
                    left = min(left, along)
                elif -_WIDTH <= across < 0.0:
                    right = min(right, along)
    return max(left, right)


@numba.njit(cache=True)
def _cast(
    state: NDArray[np.int8],
    starts: NDArray[np.float64],
    angles: NDArray[np.float64],
    limit: float,
) -> NDArray[np.float64]:
    """Ranges (K, N) in cells of the beams ``angles`` from ``starts`` (K, 2; cell units, x =
    column, y = row): to the middle of the first occupied cell's stretch, or to where the
    beam passes between two occupied cells; ``inf`` at an unknown cell, off the grid or past
    ``limit`` cells."""
    rows, cols = state.shape
    out = np.full((starts.shape[0], angles.size), np.inf)
    for k in range(starts.shape[0]):
        x0, y0 = starts[k, 0], starts[k, 1]
        for b in range(angles.size):
            dx, dy = math.cos(angles[b]), math.sin(angles[b])
            ix, iy = math.floor(x0), math.floor(y0)
            step_x = 1 if dx > 0 else -1
            step_y = 1 if dy > 0 else -1
            next_x = np.inf if dx == 0 else ((ix + (dx > 0)) - x0) / dx
            next_y = np.inf if dy == 0 else ((iy + (dy > 0)) - y0) / dy
            delta_x = np.inf if dx == 0 else abs(1.0 / dx)
            delta_y = np.inf if dy == 0 else abs(1.0 / dy)
            entry = 0.0
            while entry <= limit and 0 <= ix < cols and 0 <= iy < rows:
                s = state[iy, ix]
                leave = min(next_x, next_y)
                hit = np.inf
                if s & _KIND == _OCCUPIED:
                    hit = 0.5 * (entry + leave)
                elif s & _NEAR:
                    gap = _gap(state, ix, iy, x0, y0, dx, dy)
                    if gap <= leave + 1.0:  # the gap is here, not cells ahead
                        hit = max(gap, entry)
                if hit < np.inf:
                    if hit <= limit:
                        out[k, b] = hit
                    break
                if s & _KIND != _FREE:
                    break
                if next_x < next_y:
                    ix += step_x
                    entry = next_x
                    next_x += delta_x
                else:
                    iy += step_y
                    entry = next_y
                    next_y += delta_y
    return out


def _states(grid: OccupancyGrid) -> NDArray[np.int8]:
    """Free / occupied / stop state of every cell (row 0 the bottom), with the flag
    :data:`_NEAR` on the cells next to an occupied one."""
    occ = grid.occupancy
    state = np.full(occ.shape, _STOP, dtype=np.int8)
    state[(occ >= 0) & (occ <= FREE_PERCENT)] = _FREE
    occupied = occ >= OCCUPIED_PERCENT
    state[occupied] = _OCCUPIED
    # unknown specks inside free space (between the rays of a far, sparse scan): free
    stop = state == _STOP
    state[stop & ~binary_opening(stop, np.ones((3, 3), bool))] = _FREE
    near = binary_dilation(occupied, np.ones((3, 3), bool))
    return state | np.where(near, _NEAR, 0).astype(np.int8)


def _to_map(grid: OccupancyGrid, local: NDArray[np.float64]) -> NDArray[np.float64]:
    """Poses (K, 3) in the grid's own frame (lower-left corner, yaw 0) moved into the map
    frame by the grid's ``origin``."""
    x0, y0, yaw = grid.origin
    c, s = math.cos(yaw), math.sin(yaw)
    x = x0 + c * local[:, 0] - s * local[:, 1]
    y = y0 + s * local[:, 0] + c * local[:, 1]
    return np.column_stack([x, y, local[:, 2] + yaw])


def free_poses(
    grid: OccupancyGrid, spacing: float = SPACING, clearance: float = CLEARANCE
) -> NDArray[np.float64]:
    """Virtual keyframe poses (K, 3) in the map frame: per ``spacing`` block the free cell
    farthest from every occupied or unknown cell, kept when at least ``clearance`` (m) away;
    heading the grid's. Ordered by block (row-major from the grid's lower-left corner)."""
    res = grid.resolution
    free = (_states(grid) & _KIND) == _FREE
    padded = np.pad(free, 1, constant_values=False)  # beyond the image: unknown
    distance = distance_transform_edt(padded)[1:-1, 1:-1] * res
    rows, cols = np.nonzero(distance >= max(clearance, 1e-9))
    if rows.size == 0:
        return np.zeros((0, 3))
    block = max(1, round(spacing / res))
    key = (rows // block) * (cols.max() // block + 1) + cols // block
    order = np.lexsort((-distance[rows, cols], key))  # by block, the most central first
    _, first = np.unique(key[order], return_index=True)
    pick = order[first]
    local = np.column_stack(
        [(cols[pick] + 0.5) * res, (rows[pick] + 0.5) * res, np.zeros(pick.size)]
    )
    return _to_map(grid, local)


def cast_grid(
    grid: OccupancyGrid,
    poses: NDArray[np.float64],
    beams: int = BEAMS,
    range_max: float = RANGE_MAX,
) -> NDArray[np.float64]:
    """Ranges (K, beams) of a 360° scanner at each pose (map frame) through the grid: beam
    ``i`` at ``-pi + i * 2 pi / beams`` from the pose's heading; ``inf`` for no return (see
    the module notes)."""
    poses = np.asarray(poses, dtype=np.float64).reshape(-1, 3)
    x0, y0, yaw = grid.origin
    c, s = math.cos(yaw), math.sin(yaw)
    dx, dy = poses[:, 0] - x0, poses[:, 1] - y0
    starts = np.column_stack([c * dx + s * dy, -s * dx + c * dy]) / grid.resolution
    headings = poses[:, 2] - yaw
    angles = -math.pi + (2.0 * math.pi / beams) * np.arange(beams)
    state = _states(grid)
    limit = range_max / grid.resolution
    out = np.empty((len(poses), beams))
    for h in np.unique(headings):  # one kernel call per heading (one for virtual keyframes)
        rows = headings == h
        out[rows] = _cast(state, np.ascontiguousarray(starts[rows]), angles + h, limit)
    return out * grid.resolution


@dataclass(frozen=True)
class PointSettings:
    """Range limits and point spacing of virtual keyframe points: the SLAM's defaults
    (``SlamOptions`` ``min_range``, ``max_range``, ``point_spacing``), its place index's."""

    min_range: float = 0.1
    max_range: float = 30.0
    point_spacing: float = 0.05
    places: PlaceOptions = field(default_factory=PlaceOptions)


@dataclass
class VirtualKeyframes:
    """Virtual keyframes of a grid, shaped as a SLAM result is for
    :func:`~laser_corners.registration.mapfolder.keyframe_arrays` (``keyframe_poses``, ``scans``,
    ``keyframes``, ``stamps``, ``mount``, ``options``).

    Attributes
    ----------
    keyframe_poses : ndarray, shape (K, 3)
        Base poses in the map frame (the virtual scanner is at the base).
    scans : list of LaserScan
        The virtual 360° scans (``BEAMS`` beams from ``-pi``, ``range_max`` ``RANGE_MAX``,
        ``inf`` where a beam gives no return).
    options : PointSettings
        Range limits and point spacing of the keyframe points (the SLAM's defaults).
    """

    keyframe_poses: NDArray[np.float64]
    scans: list[LaserScan]
    options: PointSettings = field(default_factory=PointSettings)

    def __len__(self) -> int:
        return len(self.scans)

    @property
    def keyframes(self) -> NDArray[np.int64]:
        """Index of each keyframe among the scans: ``0..K-1``."""
        return np.arange(len(self), dtype=np.int64)

    @property
    def stamps(self) -> NDArray[np.float64]:
        """Zero: a virtual keyframe has no time."""
        return np.zeros(len(self))

    @property
    def mount(self) -> NDArray[np.float64]:
        """Zero: the virtual scanner is at the base."""
        return np.zeros(3)


def virtual_keyframes(
    grid: OccupancyGrid,
    spacing: float = SPACING,
    clearance: float = CLEARANCE,
    beams: int = BEAMS,
    range_max: float = RANGE_MAX,
) -> VirtualKeyframes:
    """Virtual keyframes over the free space of ``grid`` (see the module notes).

    Parameters
    ----------
    grid : OccupancyGrid
    spacing : float
        One keyframe per ``spacing`` x ``spacing`` m block of free space.
    clearance : float
        Least distance (m) of a keyframe from an occupied or unknown cell.
    beams : int
        Beams of the virtual 360° scanner.
    range_max : float
        Its range (m).

    Returns
    -------
    VirtualKeyframes
        Empty when no free cell is ``clearance`` from the walls.

    Raises
    ------
    ValueError
        ``spacing`` or ``range_max`` not a finite number > 0, ``clearance`` < 0 or not finite,
        ``beams`` < 8 (named).
    """
    for name, value, low in (("spacing", spacing, 0.0), ("range_max", range_max, 0.0)):
        if not (math.isfinite(value) and value > low):
            raise ValueError(f"{name} must be a finite number > 0, got {value}")
    if not (math.isfinite(clearance) and clearance >= 0.0):
        raise ValueError(f"clearance must be a finite number >= 0, got {clearance}")
    if int(beams) != beams or beams < 8:
        raise ValueError(f"beams must be an integer >= 8, got {beams}")
    poses = free_poses(grid, spacing, clearance)
    ranges = cast_grid(grid, poses, beams, range_max)
    increment = 2.0 * math.pi / beams
    scans = [
        LaserScan(r, -math.pi, increment, 0.0, range_max, stamp=0.0, frame_id=FRAME) for r in ranges
    ]
    return VirtualKeyframes(poses, scans)
