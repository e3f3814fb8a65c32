"""Corner keypoints with descriptors in a base frame, and queries chained by odometry.

:class:`Corners` are a scan's corner keypoints (the paper's detector) with their ``csc``
descriptors (:mod:`laser_corners.matching.descriptors`), moved into the robot's base frame;
:class:`QueryBuffer` keeps the corners of the last metres of scans, chained by odometry, as
one query in the newest scan's frame (:mod:`~laser_corners.registration.place_index` asks
the map's index where it could be).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray
from scipy.spatial import cKDTree

from laser_corners.detector import CornerDetector
from laser_corners.matching.descriptors import DescriptorParams, describe
from laser_corners.pose import between_many, compose_many, wrap_angle
from laser_corners.scan import LaserScan

__all__ = [
    "KEEP_STEP",
    "Corners",
    "QueryBuffer",
    "corner_detector",
    "merge_close",
    "nearest_corners",
    "scan_corners",
]


@dataclass
class Corners:
    """Corner keypoints in a base frame, with descriptors.

    Attributes
    ----------
    xy : ndarray, shape (M, 2)
        Positions (m).
    orientation : ndarray, shape (M,)
        Bisector orientations (rad).
    opening : ndarray, shape (M,)
        Opening angles (degrees).
    descriptor : ndarray, shape (M, D), float32
        ``csc`` descriptors (rotation invariant: the frame does not change them).
    """

    xy: NDArray[np.float64]
    orientation: NDArray[np.float64]
    opening: NDArray[np.float64]
    descriptor: NDArray[np.float32]

    def __len__(self) -> int:
        return int(self.xy.shape[0])

    @classmethod
    def empty(cls, width: int = 0) -> Corners:
        return cls(np.zeros((0, 2)), np.zeros(0), np.zeros(0), np.zeros((0, width), np.float32))

    def moved(self, pose: NDArray[np.float64]) -> Corners:
        """The corners in the frame where this frame's origin is at ``pose``."""
        if len(self) == 0:
            return self
        xyt = compose_many(pose, np.column_stack([self.xy, self.orientation]))
        return Corners(xyt[:, :2], xyt[:, 2], self.opening, self.descriptor)

    @staticmethod
    def joined(parts: list[Corners]) -> Corners:
        """One set of the corners of ``parts`` (same frame)."""
        full = [p for p in parts if len(p)]
        if not full:
            return Corners.empty(parts[0].descriptor.shape[1] if parts else 0)
        parts = full
        return Corners(
            np.concatenate([p.xy for p in parts]).reshape(-1, 2),
            np.concatenate([p.orientation for p in parts]),
            np.concatenate([p.opening for p in parts]),
            np.concatenate([p.descriptor for p in parts]),
        )


def corner_detector(preset: str, scan: LaserScan) -> CornerDetector:
    """The detector of ``preset`` for ``scan``'s sensor (``auto``/``robust`` read the scan)."""
    if preset == "paper":
        return CornerDetector("paper")
    return CornerDetector.from_preset(preset, scan)


def scan_corners(scan: LaserScan, detector: CornerDetector, mount: NDArray[np.float64]) -> Corners:
    """The corners of ``scan`` with ``csc`` descriptors, moved into the base frame by
    ``mount`` (base -> laser)."""
    kp = detector.detect(scan)
    desc = describe(scan, kp, DescriptorParams("csc")).values.astype(np.float32)
    ok = np.isfinite(kp.orientation) & np.isfinite(kp.xy).all(axis=1)
    sensor = Corners(
        np.asarray(kp.xy, dtype=np.float64)[ok],
        np.asarray(kp.orientation, dtype=np.float64)[ok],
        np.asarray(kp.opening_angle_deg, dtype=np.float64)[ok],
        desc[ok],
    )
    return sensor.moved(np.asarray(mount, dtype=np.float64))


def merge_close(corners: Corners, radius: float, yaw: float) -> Corners:
    """One corner per physical corner: a corner within ``radius`` and ``yaw`` of an earlier
    kept one is dropped (the query's scans see one corner many times)."""
    if len(corners) < 2:
        return corners
    tree = cKDTree(corners.xy)
    keep = np.ones(len(corners), dtype=bool)
    for i, near in enumerate(tree.query_ball_point(corners.xy, radius)):
        if not keep[i]:
            continue
        near = np.asarray([j for j in near if j > i], dtype=np.int64)
        if near.size:
            same = np.abs(wrap_angle(corners.orientation[near] - corners.orientation[i])) <= yaw
            keep[near[same]] = False
    return Corners(
        corners.xy[keep], corners.orientation[keep], corners.opening[keep], corners.descriptor[keep]
    )


def nearest_corners(corners: Corners, most: int) -> Corners:
    """The ``most`` corners nearest the frame's origin (all of them, the same object, when
    there are no more): a query's corners around the robot, which its newest scans saw from
    closest and whose odometry chain is the shortest."""
    if len(corners) <= most:
        return corners
    keep = np.sort(np.argsort(np.hypot(corners.xy[:, 0], corners.xy[:, 1]), kind="stable")[:most])
    return Corners(
        corners.xy[keep], corners.orientation[keep], corners.opening[keep], corners.descriptor[keep]
    )


KEEP_STEP = 0.2
"""A scan's corners join the query buffer after this much travel (m, turns 0.5 m per radian)
since the last kept scan: consecutive scans see the same corners."""


@dataclass
class QueryBuffer:
    """The corners of the last scans, chained by odometry: a query in the newest base frame.

    :meth:`add` keeps a scan's corners (its base frame) with its odometry pose when the robot
    moved :data:`KEEP_STEP` since the last kept scan; scans more than ``travel`` metres of
    odometry before the newest are dropped.
    """

    travel: float
    _items: list[tuple[NDArray[np.float64], float, Corners]] = field(
        default_factory=list, init=False, repr=False
    )
    _travelled: float = field(default=0.0, init=False, repr=False)
    _last: NDArray[np.float64] | None = field(default=None, init=False, repr=False)

    def add(self, odometry: NDArray[np.float64], corners: Corners) -> None:
        odometry = np.asarray(odometry, dtype=np.float64)
        if self._last is not None:
            d = between_many(self._last, odometry)
            self._travelled += math.hypot(d[0], d[1]) + 0.5 * abs(d[2])
        self._last = odometry
        if self._items and self._travelled - self._items[-1][1] < KEEP_STEP:
            return
        self._items.append((odometry, self._travelled, corners))
        while self._travelled - self._items[0][1] > self.travel:
            self._items.pop(0)

    def clear(self) -> None:
        self._items.clear()
        self._travelled = 0.0
        self._last = None

    def query(self) -> Corners:
        """Every kept scan's corners in the newest scan's base frame (the last :meth:`add`)."""
        if not self._items or self._last is None:
            return Corners.empty()
        parts = [c.moved(between_many(self._last, odo)) for odo, _, c in self._items if len(c)]
        return Corners.joined(parts)
