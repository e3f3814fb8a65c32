"""Sensor poses of bag scans: odometry interpolated at the scan stamp, then the laser mount.

Each scan gets the pose of its ``header.frame_id`` in the odometry frame: the odometry is
interpolated linearly (x, y and the unwrapped yaw) at the scan stamp, then composed with the
transform from the odometry's ``child_frame_id`` to the laser frame found in ``/tf_static``
(and in ``/tf`` for transforms other than odometry -> base, first value kept, ``/tf_static``
wins). No odometry, no transform chain, or a stamp more than :data:`POSE_TOLERANCE_S` outside
the odometry's time span: no pose.

:class:`PoseTrack` is the track of a whole bag (odometry and transforms read first);
:class:`StreamingTrack` builds the same track while the bag is read once, so a scan's pose can
be given as soon as the odometry around its stamp is in.
"""

from __future__ import annotations

import bisect
import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from laser_corners.scan import Pose2D

__all__ = [
    "POSE_TOLERANCE_S",
    "OdomSample",
    "PoseTrack",
    "StreamingTrack",
    "Transform",
    "compose",
    "frame_name",
    "yaw_from_quaternion",
]

POSE_TOLERANCE_S = 0.5
"""How far (s) a scan stamp may lie outside the odometry's time span and still get a pose."""

OdomSample = tuple[float, float, float, float]
"""One odometry sample: stamp (s), x, y, yaw."""
Transform = tuple[str, str, Pose2D]
"""One transform: parent frame, child frame, planar transform."""


def yaw_from_quaternion(x: float, y: float, z: float, w: float) -> float:
    """Yaw (rotation about z) of a unit quaternion, radians."""
    return math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))


def compose(a: Pose2D, b: Pose2D) -> Pose2D:
    """The planar transform ``a`` followed by ``b`` (``b`` expressed in ``a``'s frame)."""
    c, s = math.cos(a[2]), math.sin(a[2])
    theta = math.atan2(math.sin(a[2] + b[2]), math.cos(a[2] + b[2]))
    return (a[0] + c * b[0] - s * b[1], a[1] + s * b[0] + c * b[1], theta)


def frame_name(name: str) -> str:
    """A tf frame name without its leading slash (ROS 1 ``/base_link`` is ``base_link``)."""
    return name.lstrip("/")


@dataclass
class PoseTrack:
    """Odometry samples plus static transforms: the pose of any linked frame at any stamp."""

    odom_frame: str
    base_frame: str
    times: NDArray[np.float64]
    x: NDArray[np.float64]
    y: NDArray[np.float64]
    yaw: NDArray[np.float64]
    parents: dict[str, tuple[str, Pose2D]]
    _mount: dict[str, Pose2D | None] = field(default_factory=dict)

    def mount(self, frame: str) -> Pose2D | None:
        """Transform from the base frame to ``frame`` through the static tree, or None."""
        frame = frame_name(frame)
        if frame not in self._mount:
            chain: Pose2D | None = (0.0, 0.0, 0.0)
            current = frame
            seen = set()
            while current != self.base_frame:
                if current in seen or current not in self.parents:
                    chain = None
                    break
                seen.add(current)
                parent, transform = self.parents[current]
                chain = compose(transform, chain)  # type: ignore[arg-type]
                current = parent
            self._mount[frame] = chain
        return self._mount[frame]

    def pose(self, stamp: float, frame: str) -> Pose2D | None:
        """Pose of ``frame`` in the odometry frame at ``stamp`` (s), or None."""
        mount = self.mount(frame)
        if mount is None or self.times.size == 0:
            return None
        if stamp < self.times[0] - POSE_TOLERANCE_S or stamp > self.times[-1] + POSE_TOLERANCE_S:
            return None
        base = (
            float(np.interp(stamp, self.times, self.x)),
            float(np.interp(stamp, self.times, self.y)),
            float(np.interp(stamp, self.times, self.yaw)),
        )
        return compose(base, mount)


def track_from(
    samples: list[OdomSample],
    transforms: dict[str, tuple[str, Pose2D, bool]],
    odom_frame: str,
    base_frame: str,
) -> PoseTrack | None:
    """The :class:`PoseTrack` of whole-bag odometry samples and ``child -> (parent, pose,
    static)`` transforms (odometry -> base left out: the samples give it); None without
    samples."""
    if not samples:
        return None
    parents = {
        child: (parent, pose)
        for child, (parent, pose, _) in transforms.items()
        if not (child == base_frame and parent == odom_frame)
    }
    data = np.array(sorted(samples), dtype=np.float64)
    return PoseTrack(
        odom_frame, base_frame, data[:, 0], data[:, 1], data[:, 2], np.unwrap(data[:, 3]),
        parents,
    )  # fmt: skip


def add_transforms(
    known: dict[str, tuple[str, Pose2D, bool]], transforms: list[Transform], is_static: bool
) -> bool:
    """Add transforms to ``known`` (first value wins; ``/tf_static`` wins over ``/tf``).

    Returns whether ``known`` changed.
    """
    changed = False
    for parent, child, pose in transforms:
        child = frame_name(child)
        found = known.get(child)
        if found is not None and (found[2] or not is_static):
            continue
        known[child] = (frame_name(parent), pose, is_static)
        changed = True
    return changed


class StreamingTrack:
    """The whole-bag :class:`PoseTrack`, built while the bag is read once.

    Odometry samples are kept sorted as ``sorted()`` sorts them there and the yaw is unwrapped
    step by step exactly as ``np.unwrap`` does, so the pose of a scan asked for once the
    samples around its stamp are in equals the one of the whole-bag track.
    """

    def __init__(self) -> None:
        self.odom_frame = self.base_frame = ""
        self._samples: list[OdomSample] = []
        self._data = np.empty((4, 64), dtype=np.float64)  # rows t, x, y, unwrapped yaw
        self._correction = 0.0  # the running sum of np.unwrap's corrections
        self._rebuild = False
        self._candidates: dict[str, tuple[str, Pose2D, bool]] = {}
        self._mount: dict[str, Pose2D | None] = {}
        self._track: PoseTrack | None = None

    def add_odometry(self, frame_id: str, child_frame_id: str, sample: OdomSample) -> None:
        """Add one ``nav_msgs/Odometry`` sample (``frame_id, child_frame_id, sample``)."""
        self.odom_frame = self.odom_frame or frame_name(frame_id)
        self.base_frame = self.base_frame or frame_name(child_frame_id)
        self._track = None
        if self._rebuild or (self._samples and sample < self._samples[-1]):
            bisect.insort(self._samples, sample)  # out of order: rebuilt when next used
            self._rebuild = True
            return
        n = len(self._samples)
        self._samples.append(sample)
        if n == self._data.shape[1]:
            self._data = np.concatenate([self._data, np.empty_like(self._data)], axis=1)
        yaw = sample[3]
        if n:
            step = yaw - self._samples[n - 1][3]
            wrapped = float(np.mod(step + math.pi, 2 * math.pi)) - math.pi
            if wrapped == -math.pi and step > 0:
                wrapped = math.pi
            if abs(step) >= math.pi:
                self._correction += wrapped - step
            yaw = yaw + self._correction
        self._data[:, n] = (sample[0], sample[1], sample[2], yaw)

    def add_transforms(self, transforms: list[Transform], is_static: bool) -> None:
        """Add the transforms of one ``tf2_msgs/TFMessage`` (first value wins; static wins)."""
        if add_transforms(self._candidates, transforms, is_static):
            self._mount = {}  # the tree changed
            self._track = None

    def _current(self) -> PoseTrack | None:
        if not self._samples:
            return None
        if self._rebuild:
            data = np.array(self._samples, dtype=np.float64).T
            data[3] = np.unwrap(data[3])
            self._data = np.concatenate([data, np.empty_like(data)], axis=1)
            self._correction = float(data[3, -1] - self._samples[-1][3])
            self._rebuild = False
        if self._track is None:
            parents = {
                child: (parent, pose)
                for child, (parent, pose, _) in self._candidates.items()
                if not (child == self.base_frame and parent == self.odom_frame)
            }
            t, x, y, yaw = self._data[:, : len(self._samples)]  # contiguous rows
            self._track = PoseTrack(
                self.odom_frame, self.base_frame, t, x, y, yaw, parents, self._mount,
            )  # fmt: skip
        return self._track

    def ready(self, stamp_ns: int, frame_id: str) -> bool:
        """Whether the pose at ``stamp_ns`` is final: odometry after it, a known mount."""
        if not self._samples or self._samples[-1][0] <= stamp_ns * 1e-9:
            return False
        track = self._current()
        return track is not None and track.mount(frame_id) is not None

    def pose(self, stamp: float, frame: str) -> Pose2D | None:
        """Pose of ``frame`` at ``stamp`` from what has been read (as :meth:`PoseTrack.pose`)."""
        track = self._current()
        return track.pose(stamp, frame) if track is not None else None
