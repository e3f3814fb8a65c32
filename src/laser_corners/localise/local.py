"""Tracking where the saved map is silent: :class:`LocalMap` (issue 20, a later visit).

A robot of a later visit drives where the mapping robot never went. The saved map then
explains only part of each scan, and tracking against it alone either gives up (no pose while
the robot is outside the map) or is pulled back to where the map explains more of the scan
(a corridor whose far end the map never saw: its mapped part matches the scan best when the
pose slides back along it).

:class:`LocalMap` keeps what the saved map does not explain: the points of the recent tracked
scans that lie more than :data:`UNEXPLAINED` from any map point (read off the map's likelihood
grid), placed at their estimated poses in the map frame, one frame per :data:`FRAME_STEP` of
travel, the last :data:`LOCAL_TRAVEL` metres of them. Each new scan is aligned to it by the SLAM
front end's point-to-line ICP (:func:`~laser_corners.registration.align.icp`, the same code as the
map alignment) and the two alignments are fused by their information (:func:`fuse`), so the
map and the local submap each weigh by how many of the scan's points they explain: a
corridor's unmapped far end holds the pose against the mapped part's pull. A scan mostly
outside the map is then tracked by the local submap alone, chained to the last map-anchored
pose (its covariance grows); once the scan agrees with the map again the map's points take
over. The local points are only those the map does not explain, so a pose that slid to a
wrong place of the map cannot be held there by its own past scans (the localiser also allows
a local estimate only while the scan sees enough of the unmapped space).
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from laser_corners.localise.freespace import Support
from laser_corners.localise.options import LocaliseOptions
from laser_corners.registration.align import Alignment, PointMap, icp, match_share
from laser_corners.registration.correlative import ScoreGrid
from laser_corners.registration.points import ScanPoints, rotate, transform

__all__ = ["Fit", "LocalMap", "explained_share", "fuse"]

UNEXPLAINED = 0.25
"""A scan point farther than this (m) from every map point is one the map does not explain
(on the map's likelihood grid, 0.1 m cells: a little more than two cells)."""
FRAME_STEP = 0.2
"""Travel (m, turns 0.5 m per radian) between two frames of the local submap."""
LOCAL_TRAVEL = 10.0
"""The local submap holds the frames of the last this many metres of travel."""
MIN_POINTS = 10
"""A local submap with fewer points is not aligned to."""


@dataclass
class Fit:
    """A tracked scan's pose and how the map and the local submap explain the scan."""

    pose: NDArray[np.float64]
    information: NDArray[np.float64]
    """Of the alignments (without the odometry prior's)."""
    mapped: float
    """Share of the scan's points within ``inlier_distance`` of a map point."""
    local: float
    """The same for the local submap's points (disjoint from the map's)."""
    support: Support
    unmapped: float
    """Share of the scan's points farther than :data:`UNEXPLAINED` from any map point."""

    def explained(self, partly: float) -> float:
        """Share of the scan's points that the map or the local submap explains; when more
        than ``partly`` (``partly_outside``) of them are far from any map point (the robot
        sees space the map does not cover), the share among the points the two could
        explain (near a map point, or local): entering unmapped space, the newly seen
        part of the scan is explained by nothing yet."""
        return explained_share(self.mapped, self.local, self.unmapped, partly)


def explained_share(mapped: float, local: float, unmapped: float, partly: float) -> float:
    """:meth:`Fit.explained` of the shares ``mapped`` (near a map point), ``local`` (near a
    local point) and ``unmapped`` (far from every map point) of a scan's points."""
    both = mapped + local
    if unmapped <= partly:
        return min(1.0, both)
    return min(1.0, both / max(1.0 - unmapped + local, 0.05))


class LocalMap:
    """The recent scans' points the saved map does not explain (see the module notes).

    Parameters
    ----------
    grid : ScoreGrid
        The saved map's likelihood grid (``exp(-d² / 2σ²)`` of the distance to a map point).
    sigma : float
        Its σ (m).
    """

    def __init__(self, grid: ScoreGrid, sigma: float) -> None:
        self.grid = grid
        self.threshold = math.exp(-0.5 * (UNEXPLAINED / sigma) ** 2)
        self.frames: deque[tuple[float, NDArray, NDArray, NDArray]] = deque()
        self.travel = 0.0
        self._last = -math.inf
        self.lines: PointMap | None = None
        self.every: PointMap | None = None

    def __len__(self) -> int:
        return 0 if self.every is None else len(self.every)

    def clear(self) -> None:
        """Forget every frame (a new fix, a lost track, a set pose)."""
        self.frames.clear()
        self.lines = self.every = None
        self._last = -math.inf

    def unexplained(self, xy: NDArray[np.float64]) -> NDArray[np.bool_]:
        """Which of the map-frame points ``xy`` (N, 2) no map point explains."""
        return self.grid.at(xy, outside=0.0) < self.threshold

    def add(self, pose: NDArray[np.float64], pts: ScanPoints, step: float) -> None:
        """Count ``step`` of travel; keep the scan's unexplained points at ``pose`` when the
        robot moved :data:`FRAME_STEP` since the last frame, and forget old frames."""
        self.travel += step
        if self.travel - self._last < FRAME_STEP:
            return
        self._last = self.travel
        world = transform(pts.xy, pose)
        keep = self.unexplained(world)
        normals = rotate(pts.normals[keep], float(pose[2]))
        self.frames.append((self.travel, world[keep], normals, pts.has_normal[keep]))
        while self.frames and self.travel - self.frames[0][0] > LOCAL_TRAVEL:
            self.frames.popleft()
        xy = np.concatenate([f[1] for f in self.frames])
        nrm = np.concatenate([f[2] for f in self.frames])
        line = np.concatenate([f[3] for f in self.frames])
        self.every = PointMap.build(xy, np.zeros_like(xy))
        self.lines = PointMap.build(xy[line], nrm[line])

    def align(
        self,
        xy: NDArray[np.float64],
        guess: NDArray[np.float64],
        prior: NDArray[np.float64],
        options: LocaliseOptions,
    ) -> Alignment | None:
        """ICP of the scan ``xy`` (base frame) to the local submap from ``guess``, or None
        when the submap is (nearly) empty."""
        if self.lines is None or len(self.lines) < MIN_POINTS:
            return None
        return icp(
            xy,
            self.lines,
            guess,
            prior,
            options.icp,
            inlier_distance=options.inlier_distance,
            sigma=options.match_sigma,
            overlap_map=self.every,
        )

    def share(self, xy: NDArray[np.float64], pose: NDArray[np.float64], distance: float) -> float:
        """Share of the scan's points within ``distance`` of a local point at ``pose``."""
        if self.every is None:
            return 0.0
        return match_share(xy, self.every, pose, distance)


def fuse(
    pred: NDArray[np.float64],
    prior: NDArray[np.float64],
    first: Alignment,
    second: Alignment | None,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The pose that both alignments (each made from ``pred`` under the information
    ``prior``) and the prior agree on, weighed by their information, and the summed
    information of the two alignments (without the prior's).

    Each ICP solves ``(P + I) (x - p) = I (z - p)`` for its measurement ``z``; the joint
    solution of the prior and both measurements is therefore
    ``(P + I₁ + I₂) (x - p) = (P + I₁) (x₁ - p) + (P + I₂) (x₂ - p)`` (linearised at ``p``).
    """
    if second is None:
        return first.pose, first.information
    d1 = _wrapped(first.pose - pred)
    d2 = _wrapped(second.pose - pred)
    info = first.information + second.information
    rhs = (prior + first.information) @ d1 + (prior + second.information) @ d2
    try:
        step = np.linalg.solve(prior + info, rhs)
    except np.linalg.LinAlgError:  # pragma: no cover - singular system
        return first.pose, first.information
    pose = pred + step
    pose[2] = _wrapped(pose)[2]
    return pose, info


def _wrapped(d: NDArray[np.float64]) -> NDArray[np.float64]:
    """``d`` with its angle wrapped to ``[-π, π)``."""
    out = np.array(d, dtype=np.float64)
    out[2] = (out[2] + math.pi) % (2 * math.pi) - math.pi
    return out
