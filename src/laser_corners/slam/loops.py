"""Loop closure: candidates near the current estimate, verified by correlative search + ICP.

Candidates are older keyframes (reached more than ``loop_recent_distance`` of travel ago)
within ``loop_radius`` plus the search window of the current estimate. The window grows with
the current keyframe's marginal position uncertainty (iSAM2) so the search survives the drift
of a long loop. Verification: the candidate's submap (neighbouring keyframes) is rasterised
into a likelihood grid, the query scan is placed by an exhaustive correlative search over the
window (:mod:`~laser_corners.slam.correlative`), refined by point-to-line ICP, and accepted
when enough of its points lie on the submap and the alignment is not degenerate (corridor).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from laser_corners.slam.align import PointMap, icp, match_share
from laser_corners.slam.correlative import ScoreGrid, search
from laser_corners.slam.geometry import between_many
from laser_corners.slam.options import SlamOptions
from laser_corners.slam.points import ScanPoints
from laser_corners.slam.result import LoopClosure

__all__ = ["candidates", "verify"]

SEARCH_RESOLUTION = 0.15
"""Cell size (m) of the correlative search grid (refined by ICP afterwards)."""
MAX_WINDOW_XY = 3.0
"""Largest half-width (m) of the search window, whatever the uncertainty says."""
MAX_WINDOW_YAW = 0.6
"""Largest half-width (rad) of the yaw search window."""


def candidates(
    k: int,
    estimate: NDArray[np.float64],
    travelled: NDArray[np.float64],
    window: float,
    options: SlamOptions,
) -> list[int]:
    """Older keyframes near keyframe ``k``: nearest first, at most ``loop_candidates``, from
    different submaps."""
    old = travelled[k] - travelled[:k] > options.loop_recent_distance
    if not old.any():
        return []
    idx = np.flatnonzero(old)
    dist = np.hypot(*(estimate[idx, :2] - estimate[k, :2]).T)
    near = idx[dist < options.loop_radius + window]
    order = near[np.argsort(dist[dist < options.loop_radius + window])]
    chosen: list[int] = []
    for j in order:
        if all(abs(int(j) - c) > 2 * options.loop_submap_keyframes for c in chosen):
            chosen.append(int(j))
        if len(chosen) == options.loop_candidates:
            break
    return chosen


def _submap(
    j: int,
    k: int,
    points: list[ScanPoints],
    estimate: NDArray[np.float64],
    travelled: NDArray[np.float64],
    options: SlamOptions,
) -> tuple[NDArray, NDArray, NDArray]:
    """Points (all), points with normals and their normals of the submap around keyframe
    ``j``, in ``j``'s frame."""
    lo = max(0, j - options.loop_submap_keyframes)
    hi = min(k, j + options.loop_submap_keyframes + 1)
    members = [
        i for i in range(lo, hi) if travelled[k] - travelled[i] > options.loop_recent_distance
    ]
    rel = between_many(estimate[j], estimate[members])
    all_xy, line_xy, normals = [], [], []
    for i, pose in zip(members, rel, strict=True):
        p = points[i]
        c, s = np.cos(pose[2]), np.sin(pose[2])
        rot = np.array([[c, s], [-s, c]])
        moved = p.xy @ rot + pose[:2]
        all_xy.append(moved)
        line_xy.append(moved[p.has_normal])
        normals.append(p.normals[p.has_normal] @ rot)
    return np.concatenate(all_xy), np.concatenate(line_xy), np.concatenate(normals)


def verify(
    k: int,
    j: int,
    points: list[ScanPoints],
    estimate: NDArray[np.float64],
    travelled: NDArray[np.float64],
    window: tuple[float, float],
    options: SlamOptions,
) -> LoopClosure:
    """Try to close keyframe ``k`` against the older keyframe ``j``."""
    guess = between_many(estimate[j], estimate[k])
    query = points[k].xy
    all_xy, line_xy, normals = _submap(j, k, points, estimate, travelled, options)
    if query.shape[0] < 20 or line_xy.shape[0] < 20:
        return LoopClosure(k, j, tuple(guess), False, "too few points")
    grid = ScoreGrid.build(all_xy, SEARCH_RESOLUTION, SEARCH_RESOLUTION, window[0] + 0.5)
    score, found = search(grid, query, guess, window[0], window[1])
    pointmap = PointMap.build(line_xy, normals)
    aligned = icp(
        query,
        pointmap,
        found,
        np.eye(3) * 1e-6,
        max_distance=3.0 * SEARCH_RESOLUTION,
        inlier_distance=options.loop_inlier_distance,
        iterations=options.icp_iterations,
    )
    aligned = icp(
        query,
        pointmap,
        aligned.pose,
        np.eye(3) * 1e-6,
        max_distance=options.icp_max_distance,
        inlier_distance=options.loop_inlier_distance,
        iterations=options.icp_iterations,
    )
    relative = tuple(float(v) for v in aligned.pose)
    full = PointMap.build(all_xy, np.zeros_like(all_xy))
    overlap = match_share(query, full, aligned.pose, options.loop_inlier_distance)
    if overlap < options.loop_min_score:
        return LoopClosure(k, j, relative, False, f"low overlap {overlap:.2f}")
    if aligned.degenerate():
        return LoopClosure(k, j, relative, False, "degenerate (corridor)")
    moved = float(np.hypot(*(aligned.pose[:2] - found[:2])))
    if moved > 3.0 * SEARCH_RESOLUTION:
        return LoopClosure(k, j, relative, False, f"ICP left the search peak by {moved:.2f} m")
    return LoopClosure(k, j, relative, True, f"ok (overlap {overlap:.2f}, score {score:.2f})")
