"""Observability maps of map-frame keypoints (paper section IV, fig. 4).

A grid of square cells (0.03 m in the paper) covers the map. For every cell the map counts
the scans in which the cell was *in view* (inside the sensor's field of view and range and, by
default, not occluded: not farther than the range the scan measured along that bearing) and
the scans in which at least one keypoint fell in the cell. Their ratio is the cell's
observability; the *N8* version counts a hit when a keypoint fell in the cell or in one of its
8 neighbours.

The visibility test :func:`points_in_view` is the one used everywhere in the package's
evaluation (also by :mod:`laser_corners.eval.repeatability`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numba as nb
import numpy as np
from numpy.typing import ArrayLike, NDArray

from laser_corners.scan import LaserScan, Pose2D

__all__ = [
    "Grid",
    "ObservabilityMap",
    "PersistentFeatures",
    "observability_map",
    "persistent_features",
    "points_in_view",
    "refine_positions",
]


@nb.njit(cache=True)
def _point_in_view(
    px: float,
    py: float,
    ranges: NDArray[np.float64],
    angle_min: float,
    angle_increment: float,
    range_min: float,
    max_range: float,
    tolerance: float,
    occlusion: bool,
) -> bool:
    """Whether a point (sensor frame) is in view; ``ranges`` has NaN for beams without return.

    The point must lie within ``[range_min, max_range]`` and between the first and the last
    beam (half a beam of margin). With ``occlusion`` it must also be at most ``tolerance``
    beyond the range measured by one of the two beams that bracket its bearing; beams without
    a return do not make a point visible.
    """
    d = math.sqrt(px * px + py * py)
    if d < range_min or d > max_range:
        return False
    n = ranges.shape[0]
    bearing = math.atan2(py, px)
    f = (bearing - angle_min) / angle_increment
    # the FOV may wrap: try the bearing and its +-2 pi aliases
    turns = 2.0 * math.pi / abs(angle_increment)
    found = False
    for shift in (0.0, turns, -turns):
        g = f + shift
        if -0.5 <= g <= n - 0.5:
            f = g
            found = True
            break
    if not found:
        return False
    if not occlusion:
        return True
    i0 = math.floor(f)
    for i in (i0, i0 + 1):
        if 0 <= i < n:
            r = ranges[i]
            if math.isfinite(r) and d <= r + tolerance:
                return True
    return False


@nb.njit(cache=True)
def _points_in_view(
    xy: NDArray[np.float64],
    ranges: NDArray[np.float64],
    angle_min: float,
    angle_increment: float,
    range_min: float,
    max_range: float,
    tolerance: float,
    occlusion: bool,
    out: NDArray[np.bool_],
) -> None:
    for k in range(xy.shape[0]):
        out[k] = _point_in_view(
            xy[k, 0], xy[k, 1], ranges, angle_min, angle_increment, range_min, max_range,
            tolerance, occlusion,
        )  # fmt: skip


def _ranges_with_nan(scan: LaserScan) -> NDArray[np.float64]:
    return np.where(scan.valid, scan.ranges, np.nan)


def _max_range(scan: LaserScan, max_range: float | None) -> float:
    limit = scan.range_max if math.isfinite(scan.range_max) else 1e9
    return limit if max_range is None else min(limit, float(max_range))


def points_in_view(
    scan: LaserScan,
    points: ArrayLike,
    tolerance: float = 0.06,
    occlusion: bool = True,
    max_range: float | None = None,
) -> NDArray[np.bool_]:
    """Which points (sensor frame of ``scan``) the scan could have seen.

    Parameters
    ----------
    scan : LaserScan
        The scan; its beams define the field of view.
    points : array_like, shape (M, 2)
        Points in the scan's sensor frame, metres.
    tolerance : float
        With ``occlusion``, how far beyond the measured range a point may lie and still count
        as seen (keypoints are line intersections, so they may sit slightly behind the hit).
    occlusion : bool
        Ray-cast against the scan itself: a point behind the measured surface, or along a beam
        without a return, is not in view.
    max_range : float, optional
        Ignore points farther than this (default: the scan's ``range_max``).

    Returns
    -------
    ndarray of bool, shape (M,)
    """
    xy = np.ascontiguousarray(np.asarray(points, dtype=np.float64).reshape(-1, 2))
    out = np.zeros(xy.shape[0], dtype=np.bool_)
    _points_in_view(
        xy, _ranges_with_nan(scan), scan.angle_min, scan.angle_increment, scan.range_min,
        _max_range(scan, max_range), float(tolerance), bool(occlusion), out,
    )  # fmt: skip
    return out


@dataclass(frozen=True)
class Grid:
    """A regular grid of square cells over the map frame.

    Cell ``(row, col)`` covers ``x in [x0 + col*res, x0 + (col+1)*res)`` and
    ``y in [y0 + row*res, y0 + (row+1)*res)``: row 0 is the bottom (``origin="lower"``).

    Attributes
    ----------
    x0, y0 : float
        Lower-left corner of the grid, metres.
    resolution : float
        Cell side, metres.
    shape : tuple of int
        ``(rows, cols)``.
    """

    x0: float
    y0: float
    resolution: float
    shape: tuple[int, int]

    @classmethod
    def covering(cls, points: ArrayLike, resolution: float = 0.03, margin: float = 1.0) -> Grid:
        """The smallest grid holding ``points`` (shape (M, 2)) with ``margin`` around them."""
        xy = np.asarray(points, dtype=np.float64).reshape(-1, 2)
        xy = xy[np.all(np.isfinite(xy), axis=1)]
        if xy.shape[0] == 0:
            xy = np.zeros((1, 2))
        lo = xy.min(axis=0) - margin
        hi = xy.max(axis=0) + margin
        cols = math.ceil((hi[0] - lo[0]) / resolution)
        rows = math.ceil((hi[1] - lo[1]) / resolution)
        return cls(float(lo[0]), float(lo[1]), float(resolution), (max(rows, 1), max(cols, 1)))

    @property
    def extent(self) -> tuple[float, float, float, float]:
        """``(left, right, bottom, top)`` for ``imshow(..., origin="lower", extent=...)``."""
        rows, cols = self.shape
        return (
            self.x0,
            self.x0 + cols * self.resolution,
            self.y0,
            self.y0 + rows * self.resolution,
        )

    def cell_of(self, points: ArrayLike) -> NDArray[np.int64]:
        """``(row, col)`` of each point, shape (M, 2); may lie outside the grid."""
        xy = np.asarray(points, dtype=np.float64).reshape(-1, 2)
        col = np.floor((xy[:, 0] - self.x0) / self.resolution).astype(np.int64)
        row = np.floor((xy[:, 1] - self.y0) / self.resolution).astype(np.int64)
        return np.stack([row, col], axis=1)

    def center_of(self, cells: ArrayLike) -> NDArray[np.float64]:
        """Map-frame centres of ``(row, col)`` cells, shape (M, 2)."""
        rc = np.asarray(cells, dtype=np.float64).reshape(-1, 2)
        return np.stack(
            [self.x0 + (rc[:, 1] + 0.5) * self.resolution,
             self.y0 + (rc[:, 0] + 0.5) * self.resolution],
            axis=1,
        )  # fmt: skip


_BLOCK = 16
"""Side of the cell blocks culled at once by the visibility pass."""


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
    angle_min: float,
    angle_increment: float,
    range_min: float,
    max_range: float,
    tolerance: float,
    occlusion: bool,
    keypoint_cells: NDArray[np.int64],
    in_view: NDArray[np.int32],
    in_view_n8: NDArray[np.int32],
    hits: NDArray[np.int32],
    hits_n8: NDArray[np.int32],
    mark_view: NDArray[np.int32],
    mark_view_n8: NDArray[np.int32],
    mark_hit: NDArray[np.int32],
    mark_hit_n8: NDArray[np.int32],
) -> None:
    """Add one scan to the counts; marks hold the id of the last scan that counted a cell."""
    rows, cols = in_view.shape
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
    n = ranges.shape[0]
    turns = 2.0 * math.pi / abs(angle_increment)
    half_diag = 0.5 * math.sqrt(2.0) * _BLOCK * res
    # blocks of _BLOCK x _BLOCK cells: skip those wholly out of the FOV, range or behind the
    # measured ranges of every beam that could reach them; test the others cell by cell
    for br in range(r0, r1 + 1, _BLOCK):
        for bc in range(c0, c1 + 1, _BLOCK):
            dx = x0 + (bc + 0.5 * _BLOCK) * res - pose_x
            dy = y0 + (br + 0.5 * _BLOCK) * res - pose_y
            px = c * dx + s * dy
            py = -s * dx + c * dy
            dc = math.sqrt(px * px + py * py)
            if dc - half_diag > reach:
                continue
            if dc > half_diag:
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
                    continue
                if occlusion and (farthest < 0.0 or dc - half_diag > farthest + tolerance):
                    continue
            for row in range(br, min(br + _BLOCK, r1 + 1)):
                dy = y0 + (row + 0.5) * res - pose_y
                for col in range(bc, min(bc + _BLOCK, c1 + 1)):
                    dx = x0 + (col + 0.5) * res - pose_x
                    # map -> sensor frame
                    px = c * dx + s * dy
                    py = -s * dx + c * dy
                    if _point_in_view(
                        px, py, ranges, angle_min, angle_increment, range_min, max_range,
                        tolerance, occlusion,
                    ):  # fmt: skip
                        in_view[row, col] += 1
                        mark_view[row, col] = scan_id
                        in_view_n8[row, col] += 1
                        mark_view_n8[row, col] = scan_id
    # keypoint hits; a cell with a keypoint was in view by definition
    for k in range(keypoint_cells.shape[0]):
        row = keypoint_cells[k, 0]
        col = keypoint_cells[k, 1]
        if row < 0 or row >= rows or col < 0 or col >= cols:
            continue
        if mark_hit[row, col] != scan_id:
            mark_hit[row, col] = scan_id
            hits[row, col] += 1
            if mark_view[row, col] != scan_id:
                mark_view[row, col] = scan_id
                in_view[row, col] += 1
        for nr in range(max(0, row - 1), min(rows, row + 2)):
            for nc in range(max(0, col - 1), min(cols, col + 2)):
                if mark_hit_n8[nr, nc] != scan_id:
                    mark_hit_n8[nr, nc] = scan_id
                    hits_n8[nr, nc] += 1
                    if mark_view_n8[nr, nc] != scan_id:
                        mark_view_n8[nr, nc] = scan_id
                        in_view_n8[nr, nc] += 1


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
        Visibility test, as in :func:`points_in_view`.

    Returns
    -------
    ObservabilityMap

    References
    ----------
    .. [1] Sousa et al., ICARA 2024, section IV (observability map, fig. 4).
    """
    if len(keypoints_xy) != len(scans):
        raise ValueError(f"{len(scans)} scans but {len(keypoints_xy)} keypoint arrays")
    if poses is not None and len(poses) != len(scans):
        raise ValueError(f"{len(scans)} scans but {len(poses)} poses")
    shape = grid.shape
    in_view = np.zeros(shape, dtype=np.int32)
    hits = np.zeros(shape, dtype=np.int32)
    in_view_n8 = np.zeros(shape, dtype=np.int32)
    hits_n8 = np.zeros(shape, dtype=np.int32)
    marks = [np.full(shape, -1, dtype=np.int32) for _ in range(4)]
    n_used = 0
    for i, scan in enumerate(scans):
        pose = poses[i] if poses is not None else scan.pose
        if pose is None:
            continue
        cells = grid.cell_of(keypoints_xy[i])
        _accumulate_scan(
            i, grid.x0, grid.y0, grid.resolution, float(pose[0]), float(pose[1]),
            float(pose[2]), _ranges_with_nan(scan), scan.angle_min, scan.angle_increment,
            scan.range_min, _max_range(scan, max_range), float(tolerance), bool(occlusion),
            np.ascontiguousarray(cells), in_view, in_view_n8, hits, hits_n8, *marks,
        )  # fmt: skip
        n_used += 1
    return ObservabilityMap(grid, in_view, hits, in_view_n8, hits_n8, n_used)


@dataclass(frozen=True)
class PersistentFeatures:
    """Automatically selected persistent features (peaks of the N8 observability).

    Attributes
    ----------
    xy : ndarray, shape (F, 2)
        Map-frame positions (cell centres, refined by :func:`refine_positions` when used).
    ratio_n8 : ndarray, shape (F,)
        N8 observability of each feature's cell.
    in_view_n8 : ndarray of int, shape (F,)
        Scans in which each feature's cell was in view.
    cells : ndarray of int, shape (F, 2)
        ``(row, col)`` of each feature's cell.
    """

    xy: NDArray[np.float64]
    ratio_n8: NDArray[np.float64]
    in_view_n8: NDArray[np.int64]
    cells: NDArray[np.int64]

    def __len__(self) -> int:
        return int(self.xy.shape[0])

    def count_at_least(self, ratio: float) -> int:
        """Number of features whose N8 observability is ``>= ratio``."""
        return int(np.count_nonzero(self.ratio_n8 >= ratio - 1e-12))


def persistent_features(
    obs: ObservabilityMap,
    min_ratio: float = 0.25,
    min_views: int = 20,
    nms_radius: float = 0.2,
) -> PersistentFeatures:
    """Pick persistent features: peaks of the N8 observability with non-maximum suppression.

    A cell is a candidate when its N8 observability is at least ``min_ratio`` and it was in
    view in at least ``min_views`` scans. Candidates are taken greedily, best first (higher
    N8 ratio, then more views, then more hits in the cell itself), and every candidate within
    ``nms_radius`` of an accepted one is dropped.

    Parameters
    ----------
    obs : ObservabilityMap
        The map.
    min_ratio : float
        Lowest N8 observability of a persistent feature, in [0, 1].
    min_views : int
        Fewest scans that must have seen the cell (a cell seen once with a hit is not
        persistent).
    nms_radius : float
        Suppression radius, metres.

    Returns
    -------
    PersistentFeatures
    """
    from scipy.spatial import cKDTree

    ratio = np.nan_to_num(obs.ratio_n8, nan=0.0)
    ok = (ratio >= min_ratio) & (obs.in_view_n8 >= min_views) & (obs.hits_n8 > 0)
    rows, cols = np.nonzero(ok)
    cand_ratio = ratio[rows, cols]
    cand_views = obs.in_view_n8[rows, cols]
    cand_hits = obs.hits[rows, cols]
    order = np.lexsort((-cand_hits, -cand_views, -cand_ratio))
    cells = np.stack([rows, cols], axis=1)[order]
    centers = obs.grid.center_of(cells)
    keep = np.ones(len(cells), dtype=bool)
    if len(cells):
        tree = cKDTree(centers)
        for i in range(len(cells)):
            if not keep[i]:
                continue
            for j in tree.query_ball_point(centers[i], nms_radius):
                if j > i:
                    keep[j] = False
    cells = cells[keep]
    return PersistentFeatures(
        xy=centers[keep],
        ratio_n8=ratio[cells[:, 0], cells[:, 1]],
        in_view_n8=obs.in_view_n8[cells[:, 0], cells[:, 1]].astype(np.int64),
        cells=cells.astype(np.int64),
    )


def refine_positions(
    features: PersistentFeatures, keypoints_xy: NDArray[np.float64], radius: float
) -> PersistentFeatures:
    """Move each feature to the mean of the map-frame keypoints within ``radius`` of it.

    ``keypoints_xy`` (shape (M, 2)) holds all scans' map-frame keypoints stacked; features
    with no keypoint nearby keep their cell centre.
    """
    from scipy.spatial import cKDTree

    if len(features) == 0 or len(keypoints_xy) == 0:
        return features
    tree = cKDTree(keypoints_xy)
    xy = features.xy.copy()
    for i, near in enumerate(tree.query_ball_point(features.xy, radius)):
        if near:
            xy[i] = keypoints_xy[near].mean(axis=0)
    return PersistentFeatures(xy, features.ratio_n8, features.in_view_n8, features.cells)
