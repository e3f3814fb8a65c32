"""Occupancy grid of a SLAM map: log-odds ray casting of the keyframe scans at their poses.

Each keyframe scan is placed at ``pose ⊕ mount`` (the base pose in the map frame composed with
the base -> laser mounting). For every beam with a return (finite, strictly inside
``(range_min, range_max)``) the end cell gets the log-odds of a hit and the cells crossed on
the way (integer line traversal, Bresenham/Amanatides-Woo style) the log-odds of a miss, as in
Cartographer's probability grids: within one scan the hits are applied first and a cell is
updated at most once (a cell hit by one beam is not cleared by a grazing neighbour).

Beams without a return (``inf``, NaN, or at/over ``range_max``: the sensor saw nothing up to
its range, or the reading failed) clear free space only up to ``no_return_clear`` metres, and
by default (``0``) **not at all**: a max-range reading is also what glass, black surfaces and
read errors give, so it is not evidence of free space. Readings at or below ``range_min`` are
ignored.

Cost: one pass over every beam of every keyframe (linear in beams x keyframes, times the cells
a beam crosses); the traversal is one numba kernel (``cache=True``), with no Python loop per
beam. The grid's extent is the bounding box of the sensor positions and the beam ends.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numba as nb
import numpy as np
from numpy.typing import ArrayLike, NDArray

from laser_corners.errors import InvalidParamsError
from laser_corners.io.occupancy import OccupancyGrid
from laser_corners.scan import LaserScan, compose

__all__ = [
    "LOG_ODDS_FREE",
    "LOG_ODDS_HIT",
    "MAX_CELLS",
    "check_grid_size",
    "occupancy_grid",
    "result_grid",
]

LOG_ODDS_HIT = math.log(0.7 / 0.3)
"""Log-odds added to a cell where a beam ends (hit probability 0.7)."""
LOG_ODDS_FREE = math.log(0.35 / 0.65)
"""Log-odds added to a cell a beam crosses (occupancy after one miss 0.35: two misses make a
cell free, 23 %, on the map_saver threshold of 25 %)."""
LOG_ODDS_LIMIT = 5.0
"""Cells are clamped to ``±LOG_ODDS_LIMIT`` so the map can still change its mind."""
MAX_CELLS = 200_000_000
"""Largest grid built (cells); a larger one is an :class:`InvalidParamsError`."""


@nb.njit(cache=True, nogil=True)
def _traverse(
    log_odds: np.ndarray,
    touched: np.ndarray,
    stamp: int,
    r0: int,
    c0: int,
    r1: int,
    c1: int,
    delta: float,
    limit: float,
) -> None:
    """Add ``delta`` to the cells from (r0, c0) up to, not including, (r1, c1) (Bresenham),
    skipping cells already updated by scan ``stamp``."""
    dr, dc = abs(r1 - r0), abs(c1 - c0)
    sr = 1 if r1 > r0 else -1
    sc = 1 if c1 > c0 else -1
    err = dc - dr
    r, c = r0, c0
    rows, cols = log_odds.shape
    while r != r1 or c != c1:
        if 0 <= r < rows and 0 <= c < cols and touched[r, c] != stamp:
            touched[r, c] = stamp
            value = log_odds[r, c] + delta
            log_odds[r, c] = max(-limit, min(limit, value))
        e2 = 2 * err
        if e2 > -dr:
            err -= dr
            c += sc
        if e2 < dc:
            err += dc
            r += sr


@nb.njit(cache=True, nogil=True)
def _insert(
    log_odds: np.ndarray,
    touched: np.ndarray,
    starts: np.ndarray,
    origins: np.ndarray,
    ends: np.ndarray,
    hits: np.ndarray,
    hit: float,
    miss: float,
    limit: float,
) -> None:
    """Insert every scan: ``origins`` (S, 2) and ``ends`` (B, 2) as cell indices (row, col),
    scan ``s`` owning beams ``starts[s]:starts[s + 1]``; ``hits`` marks beams with a return."""
    rows, cols = log_odds.shape
    for s in range(starts.shape[0] - 1):
        stamp = s + 1
        for b in range(starts[s], starts[s + 1]):  # hits first
            if hits[b]:
                r, c = ends[b, 0], ends[b, 1]
                if 0 <= r < rows and 0 <= c < cols and touched[r, c] != stamp:
                    touched[r, c] = stamp
                    log_odds[r, c] = min(limit, log_odds[r, c] + hit)
        r0, c0 = origins[s, 0], origins[s, 1]
        for b in range(starts[s], starts[s + 1]):
            _traverse(log_odds, touched, stamp, r0, c0, ends[b, 0], ends[b, 1], miss, limit)


def _beams(
    scan: LaserScan, sensor: tuple[float, float, float], no_return_clear: float
) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
    """Map-frame beam ends of one scan and whether each is a hit (no-return beams shortened)."""
    ranges = scan.ranges
    with np.errstate(invalid="ignore"):
        hits = scan.valid
        no_return = ~np.isfinite(ranges) | (ranges >= scan.range_max)
    keep = hits | (no_return if no_return_clear > 0.0 else np.zeros_like(hits))
    r = np.where(hits, ranges, no_return_clear)[keep]
    angles = scan.angles[keep] + sensor[2]
    ends = np.column_stack([sensor[0] + r * np.cos(angles), sensor[1] + r * np.sin(angles)])
    return ends, hits[keep]


def occupancy_grid(
    poses: ArrayLike,
    scans: Sequence[LaserScan],
    mount: ArrayLike = (0.0, 0.0, 0.0),
    resolution: float = 0.05,
    no_return_clear: float = 0.0,
) -> OccupancyGrid:
    """The occupancy grid of ``scans`` taken at base poses ``poses``.

    Parameters
    ----------
    poses : array_like, shape (K, 3)
        Base pose ``x, y, yaw`` of each scan in the map frame.
    scans : sequence of LaserScan
        The scans, in the sensor frame (their own ``pose`` is ignored).
    mount : array_like, shape (3,)
        Base -> laser transform ``x, y, yaw``.
    resolution : float
        Cell size, metres (> 0).
    no_return_clear : float
        Metres of free space a beam without a return clears (0: none, the default).

    Returns
    -------
    OccupancyGrid
        Unknown (-1) where no beam reached; else ``100 * P(occupied)``, rounded.

    Raises
    ------
    InvalidParamsError
        A resolution that is not a positive number, a negative ``no_return_clear``, pose and
        scan counts that differ, or a grid of more than :data:`MAX_CELLS` cells.
    """
    if not (math.isfinite(resolution) and resolution > 0.0):
        raise InvalidParamsError(f"resolution must be a positive number, got {resolution}")
    if not (math.isfinite(no_return_clear) and no_return_clear >= 0.0):
        raise InvalidParamsError(f"no_return_clear must be >= 0, got {no_return_clear}")
    table = np.asarray(poses, dtype=np.float64).reshape(-1, 3)
    if len(table) != len(scans):
        raise InvalidParamsError(f"{len(table)} poses but {len(scans)} scans")
    m = tuple(float(v) for v in np.asarray(mount, dtype=np.float64).reshape(3))
    sensors = [compose(tuple(row), m) for row in table]  # type: ignore[arg-type]
    parts = [_beams(scan, s, no_return_clear) for scan, s in zip(scans, sensors, strict=True)]
    origins = np.asarray(sensors, dtype=np.float64).reshape(-1, 3)[:, :2]
    ends = np.concatenate([p[0] for p in parts]) if parts else np.zeros((0, 2))
    hits = np.concatenate([p[1] for p in parts]) if parts else np.zeros(0, dtype=bool)
    starts = np.zeros(len(parts) + 1, dtype=np.int64)
    starts[1:] = np.cumsum([len(p[1]) for p in parts])
    every = np.concatenate([origins, ends]) if len(origins) else np.zeros((1, 2))
    low = np.floor(every.min(axis=0) / resolution) * resolution - resolution
    high = every.max(axis=0)
    cols, rows = (int(v) for v in np.floor((high - low) / resolution) + 2)
    if rows * cols > MAX_CELLS:
        raise InvalidParamsError(
            f"a {cols} x {rows} grid at resolution {resolution:g} m exceeds {MAX_CELLS} cells; "
            "choose a coarser resolution"
        )
    log_odds = np.zeros((rows, cols), dtype=np.float64)
    touched = np.zeros((rows, cols), dtype=np.int64)

    def cells(xy: NDArray[np.float64]) -> NDArray[np.int64]:
        rc = np.floor((xy - low) / resolution).astype(np.int64)
        return np.ascontiguousarray(rc[:, ::-1])

    _insert(
        log_odds,
        touched,
        starts,
        cells(origins),
        cells(ends),
        hits,
        LOG_ODDS_HIT,
        LOG_ODDS_FREE,
        LOG_ODDS_LIMIT,
    )
    percent = np.rint(100.0 / (1.0 + np.exp(-log_odds))).astype(np.int8)
    percent[touched == 0] = -1
    return OccupancyGrid(percent, float(resolution), (float(low[0]), float(low[1]), 0.0))


def check_grid_size(resolution: float, reach: float) -> None:
    """Refuse, before any mapping, a ``resolution`` at which the grid of one scan (beams up to
    ``reach`` m every way: a square of ``2 * reach``) would already exceed :data:`MAX_CELLS`
    cells, so the map's grid certainly would as soon as a beam reaches that far.

    Raises
    ------
    InvalidParamsError
        Naming the resolution, the cells, and the finest resolution that fits.
    """
    side = math.floor(2.0 * reach / resolution) + 2
    if side * side > MAX_CELLS:
        finest = 2.0 * reach / (math.sqrt(MAX_CELLS) - 2.0)
        raise InvalidParamsError(
            f"resolution {resolution:g} m: the grid of one scan's reach ({2.0 * reach:g} m "
            f"across) would have {side * side:.3g} cells, more than {MAX_CELLS}; use "
            f"{math.ceil(finest * 1e4) / 1e4:g} m or coarser"
        )


def result_grid(
    result: Any, resolution: float = 0.05, no_return_clear: float = 0.0
) -> OccupancyGrid:
    """:func:`occupancy_grid` of a SLAM result's keyframes (``keyframe_poses``, ``scans``,
    ``mount``)."""
    return occupancy_grid(
        result.keyframe_poses, result.scans, result.mount, resolution, no_return_clear
    )
