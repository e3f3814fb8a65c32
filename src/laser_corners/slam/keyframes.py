"""Keyframe storage: scans, points, stamps, travelled distance, estimates and the local map."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from laser_corners.registration.align import PointMap
from laser_corners.registration.points import ScanPoints
from laser_corners.scan import LaserScan

__all__ = ["SESSION_GAP", "KeyframeStore"]

SESSION_GAP = 1e4
"""Travel (m) counted between the last keyframe of a prior map and the first of the session
that grows it: no keyframe of an older session is ever a recent one (loop closure)."""


class KeyframeStore:
    """The keyframes of a run, in order.

    Attributes
    ----------
    first : int
        The first keyframe of this run's session: 0, or the number of keyframes of a prior
        map the run grows (they come first, :meth:`~.keyframer.Keyframer.seed`). The local
        maps of the session's keyframes never reach before it.
    """

    def __init__(self) -> None:
        self.first = 0
        self.scans: list[LaserScan] = []
        self.points: list[ScanPoints] = []
        self.scan_index: list[int] = []
        self.stamps: list[float] = []
        self.odometry: list[NDArray] = []
        self.travelled: list[float] = []
        self.estimate = np.zeros((0, 3))

    def __len__(self) -> int:
        return len(self.scans)

    def add(
        self,
        scan: LaserScan,
        points: ScanPoints,
        index: int,
        stamp: float,
        odometry: NDArray,
        pose: NDArray,
    ) -> None:
        """Append a keyframe (``pose``: its current estimate)."""
        step = 0.0
        if self.scans and len(self.scans) == self.first:
            step = SESSION_GAP
        elif self.scans:
            last = self.estimate[-1] if len(self.estimate) == len(self.scans) else pose
            step = float(np.hypot(*(pose[:2] - last[:2])))
        self.travelled.append((self.travelled[-1] if self.travelled else 0.0) + step)
        self.scans.append(scan)
        self.points.append(points)
        self.scan_index.append(index)
        self.stamps.append(float(stamp))
        self.odometry.append(np.asarray(odometry, dtype=np.float64))

    def travelled_array(self) -> NDArray[np.float64]:
        """Travelled distance (m) at each keyframe."""
        return np.asarray(self.travelled, dtype=np.float64)

    def local_map(
        self, n: int, around: NDArray[np.float64] | None = None, reach: float = 0.0
    ) -> tuple[PointMap, PointMap]:
        """The last ``n`` keyframes at their estimates: line points with normals (for ICP)
        and every point (for the overlap); of this session's keyframes only (:attr:`first`).
        ``around``: a pose in the map frame; the prior map's keyframes within ``reach`` (m)
        of it join them, the ``n`` nearest (a run localising in a frozen map tracks against
        the map where it is, and against its own keyframes where the map is not)."""
        chosen = np.arange(max(self.first, len(self.points) - n), len(self.points))
        if around is not None and self.first:
            prior = self.estimate[: self.first, :2]
            dist = np.hypot(*(prior - np.asarray(around)[:2]).T)
            near = np.flatnonzero(dist <= reach)
            near = near[np.argsort(dist[near], kind="stable")[:n]]
            chosen = np.r_[np.sort(near), chosen]
        return self.points_map(chosen)

    def span_map(self, first: int, stop: int) -> tuple[PointMap, PointMap]:
        """Keyframes ``first`` to ``stop`` (excluded) at their estimates, as
        :meth:`local_map`."""
        return self.points_map(np.arange(first, stop))

    def points_map(self, chosen: NDArray[np.int64]) -> tuple[PointMap, PointMap]:
        """The keyframes ``chosen`` at their estimates, as :meth:`local_map`."""
        parts = [self.points[k] for k in chosen]
        xy = np.concatenate([p.xy for p in parts])
        normals = np.concatenate([p.normals for p in parts])
        line = np.concatenate([p.has_normal for p in parts])
        owner = np.repeat(chosen, [len(p.xy) for p in parts])
        pose = self.estimate[owner]
        c, s = np.cos(pose[:, 2]), np.sin(pose[:, 2])
        moved = np.column_stack(
            [c * xy[:, 0] - s * xy[:, 1] + pose[:, 0], s * xy[:, 0] + c * xy[:, 1] + pose[:, 1]]
        )
        turned = np.column_stack(
            [c * normals[:, 0] - s * normals[:, 1], s * normals[:, 0] + c * normals[:, 1]]
        )
        every = PointMap.build(moved, np.zeros_like(moved))
        return PointMap.build(moved[line], turned[line]), every
