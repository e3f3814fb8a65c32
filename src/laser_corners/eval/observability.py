"""Observability maps of map-frame keypoints (paper section IV, fig. 4).

A grid of square cells (0.03 m in the paper) covers the map. For every cell the map counts
the scans in which the cell was *in view* (inside the sensor's field of view and range and, by
default, not occluded: not farther than the range the scan measured along that bearing) and
the scans in which at least one keypoint fell in the cell. Their ratio is the cell's
observability; the *N8* version counts a hit when a keypoint fell in the cell or in one of its
8 neighbours.

The visibility test is :func:`~laser_corners.eval.visibility.points_in_view`, the cells a
:class:`~laser_corners.eval.grid.Grid`, and the persistent features (peaks of the N8 map) are
picked by :mod:`laser_corners.eval.persistent`.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numba as nb
import numpy as np
from numpy.typing import ArrayLike, NDArray

from laser_corners.eval.grid import Grid
from laser_corners.eval.visibility import View, point_in_view, ranges_with_nan, view_of
from laser_corners.scan import LaserScan, Pose2D

__all__ = ["ObservabilityMap", "observability_map"]


_BLOCK = 16
"""Side of the cell blocks culled at once by the visibility pass."""


@nb.njit(cache=True)
def _block_may_be_seen(
    px: float,
    py: float,
    half_diag: float,
    reach: float,
    ranges: NDArray[np.float64],
    angle_min: float,
    angle_increment: float,
    tolerance: float,
    occlusion: bool,
) -> bool:
    """Whether a block of cells centred at ``(px, py)`` (sensor frame) may hold a visible cell.

    False when the block is wholly beyond ``reach``, outside the field of view, or (with
    occlusion) behind the measured ranges of every beam that could reach it.
    """
    dc = math.sqrt(px * px + py * py)
    if dc - half_diag > reach:
        return False
    if dc <= half_diag:  # the sensor is inside the block
        return True
    n = ranges.shape[0]
    turns = 2.0 * math.pi / abs(angle_increment)
    w = math.asin(half_diag / dc)
    b = math.atan2(py, px)
    fa = (b - w - angle_min) / angle_increment
    fb = (b + w - angle_min) / angle_increment
    f_lo = min(fa, fb)
    f_hi = max(fa, fb)
    overlaps = False
    farthest = -1.0
    for shift in (0.0, turns, -turns):
        lo = f_lo + shift
        hi = f_hi + shift
        if hi < -0.5 or lo > n - 0.5:
            continue
        overlaps = True
        for i in range(max(0, math.floor(lo)), min(n - 1, math.floor(hi) + 1) + 1):
            r = ranges[i]
            if math.isfinite(r) and r > farthest:
                farthest = r
    if not overlaps:
        return False
    return not (occlusion and (farthest < 0.0 or dc - half_diag > farthest + tolerance))


# planes of the counter array (8, rows, cols): counts, then the id of the last scan that
# counted the cell (so that a scan counts a cell once)
_VIEW, _VIEW8, _HIT, _HIT8 = range(4)
_MARK = 4  # plane of the mark of count plane p: _MARK + p


@nb.njit(cache=True)
def _count_once(counters: NDArray[np.int32], plane: int, scan_id: int, row: int, col: int) -> bool:
    """Count the cell in ``plane`` unless this scan already did; True when it counted."""
    if counters[_MARK + plane, row, col] == scan_id:
        return False
    counters[_MARK + plane, row, col] = scan_id
    counters[plane, row, col] += 1
    return True


@nb.njit(cache=True)
def _count_hits(
    scan_id: int, keypoint_cells: NDArray[np.int64], counters: NDArray[np.int32]
) -> None:
    """Count one scan's keypoint cells (and, for N8, their neighbours) once each.

    A cell with a keypoint was in view by definition: it counts as a view too.
    """
    rows, cols = counters.shape[1], counters.shape[2]
    for k in range(keypoint_cells.shape[0]):
        row = keypoint_cells[k, 0]
        col = keypoint_cells[k, 1]
        if row < 0 or row >= rows or col < 0 or col >= cols:
            continue
        if _count_once(counters, _HIT, scan_id, row, col):
            _count_once(counters, _VIEW, scan_id, row, col)
        for nr in range(max(0, row - 1), min(rows, row + 2)):
            for nc in range(max(0, col - 1), min(cols, col + 2)):
                if _count_once(counters, _HIT8, scan_id, nr, nc):
                    _count_once(counters, _VIEW8, scan_id, nr, nc)


@nb.njit(cache=True)
def _accumulate_scan(
    scan_id: int,
    x0: float,
    y0: float,
    res: float,
    pose_x: float,
    pose_y: float,
    pose_theta: float,
    ranges: NDArray[np.float64],
    view: View,
    keypoint_cells: NDArray[np.int64],
    counters: NDArray[np.int32],
) -> None:
    """Add one scan to the counters.

    ``view`` is (angle_min, angle_increment, range_min, max_range, tolerance, occlusion).
    """
    angle_min, angle_increment, _, max_range, tolerance, occlusion = view
    rows, cols = counters.shape[1], counters.shape[2]
    # cells in view: only the box around the sensor that the measured ranges can reach
    reach = 0.0
    for r in ranges:
        if math.isfinite(r) and r > reach:
            reach = r
    reach = min(reach + tolerance, max_range) if occlusion else max_range
    c0 = max(0, math.floor((pose_x - reach - x0) / res))
    c1 = min(cols - 1, math.floor((pose_x + reach - x0) / res))
    r0 = max(0, math.floor((pose_y - reach - y0) / res))
    r1 = min(rows - 1, math.floor((pose_y + reach - y0) / res))
    c = math.cos(pose_theta)
    s = math.sin(pose_theta)
    half_diag = 0.5 * math.sqrt(2.0) * _BLOCK * res
    # blocks of _BLOCK x _BLOCK cells: skip those wholly out of the FOV, range or behind the
    # measured ranges of every beam that could reach them; test the others cell by cell
    for br in range(r0, r1 + 1, _BLOCK):
        for bc in range(c0, c1 + 1, _BLOCK):
            dx = x0 + (bc + 0.5 * _BLOCK) * res - pose_x
            dy = y0 + (br + 0.5 * _BLOCK) * res - pose_y
            px = c * dx + s * dy
            py = -s * dx + c * dy
            if not _block_may_be_seen(
                px,
                py,
                half_diag,
                reach,
                ranges,
                angle_min,
                angle_increment,
                tolerance,
                occlusion,
            ):
                continue
            for row in range(br, min(br + _BLOCK, r1 + 1)):
                dy = y0 + (row + 0.5) * res - pose_y
                for col in range(bc, min(bc + _BLOCK, c1 + 1)):
                    dx = x0 + (col + 0.5) * res - pose_x
                    # map -> sensor frame
                    px = c * dx + s * dy
                    py = -s * dx + c * dy
                    if point_in_view(px, py, ranges, view):
                        _count_once(counters, _VIEW, scan_id, row, col)
                        _count_once(counters, _VIEW8, scan_id, row, col)
    _count_hits(scan_id, keypoint_cells, counters)


@dataclass(frozen=True)
class ObservabilityMap:
    """Per-cell counts and ratios of an observability map.

    Attributes
    ----------
    grid : Grid
        The cells.
    in_view, hits : ndarray of int32, shape grid.shape
        Scans in which the cell was in view; scans in which a keypoint fell in the cell.
    in_view_n8, hits_n8 : ndarray of int32
        The same for the N8 version (a hit: a keypoint in the cell or one of its 8
        neighbours; a scan with such a hit also counts as a view).
    n_scans : int
        Scans accumulated.
    """

    grid: Grid
    in_view: NDArray[np.int32]
    hits: NDArray[np.int32]
    in_view_n8: NDArray[np.int32]
    hits_n8: NDArray[np.int32]
    n_scans: int

    @property
    def ratio(self) -> NDArray[np.float64]:
        """``hits / in_view`` (NaN where the cell was never in view)."""
        return _ratio(self.hits, self.in_view)

    @property
    def ratio_n8(self) -> NDArray[np.float64]:
        """``hits_n8 / in_view_n8`` (NaN where never in view)."""
        return _ratio(self.hits_n8, self.in_view_n8)


def _ratio(num: NDArray[np.int32], den: NDArray[np.int32]) -> NDArray[np.float64]:
    out = np.full(num.shape, np.nan)
    np.divide(num, den, out=out, where=den > 0)
    return out


def observability_map(
    scans: Sequence[LaserScan],
    keypoints_xy: Sequence[ArrayLike],
    grid: Grid,
    poses: Sequence[Pose2D] | None = None,
    occlusion: bool = True,
    tolerance: float = 0.06,
    max_range: float | None = None,
    step: Callable[[int, int], None] | None = None,
) -> ObservabilityMap:
    """Count, per grid cell, the scans that saw it and the scans with a keypoint in it.

    Parameters
    ----------
    scans : sequence of LaserScan
        The scans, with their sensor poses in the map frame (``scan.pose``) unless ``poses``
        is given.
    keypoints_xy : sequence of array_like, shape (M_i, 2)
        Each scan's keypoints **in the map frame**.
    grid : Grid
        The cells (see :meth:`Grid.covering`).
    poses : sequence of (x, y, theta), optional
        Sensor poses in the map frame; default: each scan's ``pose`` (scans without one
        are skipped).
    occlusion, tolerance, max_range
        Visibility test, as in :func:`~laser_corners.eval.visibility.points_in_view`.
    step : callable, optional
        Called as ``step(done, total)`` every 200 scans and at the end (progress).

    Returns
    -------
    ObservabilityMap

    References
    ----------
    .. [1] R. B. Sousa, H. M. Sobreira, M. F. Silva, A. P. Moreira, "Line Fitting-Based
       Corner-Like Detector for 2D Laser Scanners Data", ICARA 2024, pp. 210-216, section IV
       (observability map, fig. 4), doi:10.1109/ICARA60736.2024.10553006.
    """
    if len(keypoints_xy) != len(scans):
        raise ValueError(f"{len(scans)} scans but {len(keypoints_xy)} keypoint arrays")
    if poses is not None and len(poses) != len(scans):
        raise ValueError(f"{len(scans)} scans but {len(poses)} poses")
    counters = np.zeros((8, *grid.shape), dtype=np.int32)
    counters[_MARK:] = -1
    n_used = 0
    for i, scan in enumerate(scans):
        if step is not None and i % 200 == 0 and i:
            step(i, len(scans))
        pose = poses[i] if poses is not None else scan.pose
        if pose is None:
            continue
        cells = grid.cell_of(keypoints_xy[i])
        view = view_of(scan, tolerance, occlusion, max_range)
        _accumulate_scan(
            i,
            grid.x0,
            grid.y0,
            grid.resolution,
            float(pose[0]),
            float(pose[1]),
            float(pose[2]),
            ranges_with_nan(scan),
            view,
            np.ascontiguousarray(cells),
            counters,
        )
        n_used += 1
    if step is not None:
        step(len(scans), len(scans))
    return ObservabilityMap(
        grid,
        counters[_VIEW].copy(),
        counters[_HIT].copy(),
        counters[_VIEW8].copy(),
        counters[_HIT8].copy(),
        n_used,
    )
