"""Loop closure: candidates near the current estimate, verified by correlative search + ICP.

Candidates are older keyframes (reached more than ``loop.recent_distance`` of travel ago)
within ``loop.radius`` plus the search window of the current estimate. The window grows with
the current keyframe's marginal position uncertainty (iSAM2) so the search survives the drift
of a long loop. Verification: the candidate's submap (neighbouring keyframes) is rasterised
into a likelihood grid, the query scan is placed by an exhaustive correlative search over the
window (:mod:`~laser_corners.registration.correlative`), refined by point-to-line ICP, and accepted
when enough of its points lie on the submap and the alignment is not degenerate (corridor).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray

from laser_corners.pose import between_many, compose, invert, relative_pose
from laser_corners.registration.align import PointMap, icp, match_share
from laser_corners.registration.correlative import ScoreGrid, search
from laser_corners.registration.points import ScanPoints, rotate, transform
from laser_corners.slam.options import SlamOptions
from laser_corners.slam.result import LoopClosure

__all__ = [
    "ClosureGate",
    "SubmapCache",
    "candidates",
    "query_points",
    "submap_points",
    "thin_points",
    "verify",
]

SEARCH_RESOLUTION = 0.15
"""Cell size (m) of the correlative search grid (refined by ICP afterwards)."""
QUERY_CELL = 0.1
"""Cell (m) of the voxel thinning of a multi-keyframe loop query."""
MAX_WINDOW_XY = 5.0
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
    """Older keyframes near keyframe ``k``: nearest first, at most ``loop.candidates``, from
    different submaps."""
    old = travelled[k] - travelled[:k] > options.loop.recent_distance
    if not old.any():
        return []
    idx = np.flatnonzero(old)
    dist = np.hypot(*(estimate[idx, :2] - estimate[k, :2]).T)
    near = idx[dist < options.loop.radius + window]
    order = near[np.argsort(dist[dist < options.loop.radius + window])]
    chosen: list[int] = []
    for j in order:
        if all(abs(int(j) - c) > 2 * options.loop.submap_keyframes for c in chosen):
            chosen.append(int(j))
        if len(chosen) == options.loop.candidates:
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
    lo = max(0, j - options.loop.submap_keyframes)
    hi = min(k, j + options.loop.submap_keyframes + 1)
    members = [
        i for i in range(lo, hi) if travelled[k] - travelled[i] > options.loop.recent_distance
    ]
    return submap_points(j, members, points, estimate)


def submap_points(
    anchor: int, members: list[int], points: list[ScanPoints], estimate: NDArray[np.float64]
) -> tuple[NDArray, NDArray, NDArray]:
    """Points (all), points with normals and their normals of the keyframes ``members`` at
    their ``estimate``, in keyframe ``anchor``'s frame (a loop closure's or the refinement
    pass's submap)."""
    rel = between_many(estimate[anchor], estimate[members])
    all_xy, line_xy, normals = [], [], []
    for i, pose in zip(members, rel, strict=True):
        p = points[i]
        moved = transform(p.xy, pose)
        all_xy.append(moved)
        line_xy.append(moved[p.has_normal])
        normals.append(rotate(p.normals[p.has_normal], pose[2]))
    return np.concatenate(all_xy), np.concatenate(line_xy), np.concatenate(normals)


def query_points(
    k: int, points: list[ScanPoints], estimate: NDArray[np.float64], n: int
) -> NDArray[np.float64]:
    """Points of keyframe ``k`` and its ``n - 1`` predecessors in ``k``'s frame, thinned."""
    parts = []
    for i in range(max(0, k - n + 1), k + 1):
        parts.append(transform(points[i].xy, np.array(relative_pose(estimate[k], estimate[i]))))
    xy = np.concatenate(parts)
    return xy if len(parts) == 1 else thin_points(xy, QUERY_CELL)


def thin_points(xy: NDArray[np.float64], cell: float) -> NDArray[np.float64]:
    """One point per ``cell``-sized square (the first one), in the input order."""
    cells = np.floor(xy / cell).astype(np.int64)
    _, keep = np.unique(cells[:, 0] * 1_000_003 + cells[:, 1], return_index=True)
    return xy[np.sort(keep)]


class SubmapCache:
    """Submaps (search grid, line map, point map) of recent candidates, by keyframe; cleared
    whenever the estimates change much (a loop closure, a full read of the estimates)."""

    def __init__(self, size: int = 16) -> None:
        self.size = size
        self.version = 0
        self._items: dict[int, tuple[ScoreGrid, PointMap, PointMap]] = {}

    def invalidate(self) -> None:
        """Forget every submap (the estimates moved)."""
        self._items.clear()
        self.version += 1

    def get(
        self, j: int, build: Callable[[], tuple[ScoreGrid, PointMap, PointMap] | None]
    ) -> tuple[ScoreGrid, PointMap, PointMap] | None:
        """The submap of ``j``, built with ``build`` when not cached (None: too few points)."""
        if j not in self._items:
            built = build()
            if built is None:
                return None
            if len(self._items) >= self.size:
                self._items.pop(next(iter(self._items)))
            self._items[j] = built
        return self._items[j]


def verify(
    k: int,
    j: int,
    points: list[ScanPoints],
    estimate: NDArray[np.float64],
    travelled: NDArray[np.float64],
    window: tuple[float, float],
    options: SlamOptions,
    cache: SubmapCache | None = None,
) -> LoopClosure:
    """Try to close keyframe ``k`` against the older keyframe ``j``."""
    guess = between_many(estimate[j], estimate[k])
    query = query_points(k, points, estimate, options.loop.query_keyframes)

    def build() -> tuple[ScoreGrid, PointMap, PointMap] | None:
        all_xy, line_xy, normals = _submap(j, k, points, estimate, travelled, options)
        if line_xy.shape[0] < 20:
            return None
        grid = ScoreGrid.build(all_xy, SEARCH_RESOLUTION, SEARCH_RESOLUTION, MAX_WINDOW_XY + 0.5)
        return grid, PointMap.build(line_xy, normals), PointMap.build(all_xy, np.zeros_like(all_xy))

    submap = (cache or SubmapCache()).get(j, build)
    if query.shape[0] < 20 or submap is None:
        return LoopClosure(k, j, tuple(guess), False, "too few points")
    grid, pointmap, full = submap
    score, found = search(grid, thin_points(query, SEARCH_RESOLUTION), guess, window[0], window[1])
    aligned = icp(
        query,
        pointmap,
        found,
        np.eye(3) * 1e-6,
        options.icp.with_overrides({"max_distance": 3.0 * SEARCH_RESOLUTION}),
        inlier_distance=options.inlier_distance,
    )
    aligned = icp(
        query,
        pointmap,
        aligned.pose,
        np.eye(3) * 1e-6,
        options.icp,
        inlier_distance=options.inlier_distance,
    )
    relative = tuple(float(v) for v in aligned.pose)
    overlap = match_share(query, full, aligned.pose, options.inlier_distance)
    if overlap < options.loop.min_score:
        return LoopClosure(k, j, relative, False, f"low overlap {overlap:.2f}")
    if aligned.degenerate():
        return LoopClosure(k, j, relative, False, "degenerate (corridor)")
    moved = float(np.hypot(*(aligned.pose[:2] - found[:2])))
    if moved > 3.0 * SEARCH_RESOLUTION:
        return LoopClosure(k, j, relative, False, f"ICP left the search peak by {moved:.2f} m")
    return LoopClosure(k, j, relative, True, f"ok (overlap {overlap:.2f}, score {score:.2f})")


class ClosureGate:
    """Accepts verified closures only when they agree with the map or with each other.

    A verified closure implies a correction of the current estimate (where it puts the query
    keyframe relative to where the graph has it). A small correction (within ``agree_xy`` /
    ``agree_yaw``) agrees with the map and is accepted at once; a larger one waits until
    another verified closure from a later keyframe within ``horizon`` keyframes implies the
    same correction, and then both are accepted. A single wrong match (a symmetric room, a
    door) therefore cannot move the map; a pending closure that is never confirmed is
    rejected.
    """

    def __init__(self, agree_xy: float, agree_yaw: float, horizon: int) -> None:
        self.agree_xy = agree_xy
        self.agree_yaw = agree_yaw
        self.horizon = horizon
        self.pending: list[tuple[LoopClosure, NDArray[np.float64]]] = []

    def _agree(self, a: NDArray[np.float64], b: NDArray[np.float64]) -> bool:
        d = relative_pose(a, b)
        return bool(np.hypot(d[0], d[1]) <= self.agree_xy and abs(d[2]) <= self.agree_yaw)

    def offer(self, closure: LoopClosure, estimate: NDArray[np.float64]) -> list[LoopClosure]:
        """Offer a verified closure; returns the closures to add to the graph now, and drops
        (marks rejected) pending ones older than the horizon."""
        k, j = closure.query, closure.match
        implied = compose(estimate[j], closure.relative)
        correction = np.array(relative_pose(estimate[k], implied))  # in k's frame
        # a correction expressed as a map-frame transform, comparable across keyframes
        shift = np.array(compose(compose(estimate[k], correction), invert(estimate[k])))
        expired = [p for p in self.pending if k - p[0].query > self.horizon]
        for p, _ in expired:
            p.accepted = False
            p.reason = "unconfirmed: no later closure agreed"
        self.pending = [p for p in self.pending if k - p[0].query <= self.horizon]
        if self._agree(np.zeros(3), correction):
            return [closure]
        agreeing = [p for p, s in self.pending if p.query != k and self._agree(s, shift)]
        if agreeing:
            self.pending = [(p, s) for p, s in self.pending if p not in agreeing]
            return [*agreeing, closure]
        closure.accepted = False
        closure.reason = "pending confirmation"
        self.pending.append((closure, shift))
        return []
