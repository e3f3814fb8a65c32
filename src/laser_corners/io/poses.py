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
from operator import itemgetter
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from laser_corners.errors import InputError
from laser_corners.scan import Pose2D, compose

__all__ = [
    "FORGET_BATCH",
    "POSE_TOLERANCE_S",
    "Edge",
    "OdomSample",
    "PoseTrack",
    "StreamingTrack",
    "Transform",
    "frame_name",
    "interp_at",
    "ns_seconds",
    "stamped_transforms",
    "tf_odometry",
    "yaw_from_quaternion",
]

POSE_TOLERANCE_S = 0.5
"""How far (s) a scan stamp may lie outside the odometry's time span and still get a pose."""

FORGET_BATCH = 1_000
"""Fewest samples :meth:`StreamingTrack.forget_before` drops at once (it drops none below)."""

OdomSample = tuple[float, float, float, float]
"""One odometry sample: stamp (s), x, y, yaw."""
Transform = tuple[str, str, Pose2D]
"""One transform: parent frame, child frame, planar transform."""


def yaw_from_quaternion(x: float, y: float, z: float, w: float) -> float:
    """Yaw (rotation about z) of a unit quaternion, radians."""
    return math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))


def ns_seconds(stamp_ns: int) -> float:
    """A ROS stamp in nanoseconds as seconds, ``sec + 1e-9 * nsec`` as every odometry and tf
    stamp is read here (and by the ROS 2 node), so a scan stamped as an odometry sample gets
    that sample's pose: ``stamp_ns * 1e-9`` can differ by a float step (1.2e-7 s at the
    year 2000's 9.8e8 s), and odometry samples 1 ms apart make that 1e-4 of their step.

    >>> ns_seconds(976054571_000000000), 976054571_000000000 * 1e-9
    (976054571.0, 976054571.0000001)
    """
    sec, nsec = divmod(int(stamp_ns), 1_000_000_000)
    return sec + 1e-9 * nsec


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
        odom_frame,
        base_frame,
        data[:, 0],
        data[:, 1],
        data[:, 2],
        np.unwrap(data[:, 3]),
        parents,
    )


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


def interp_at(stamp: float, times: list[float], values: list[float], j: int) -> float:
    """``np.interp(stamp, times, values)`` for one stamp, bit for bit (numpy's formula and
    edge cases), with ``j = bisect_right(times, stamp) - 1`` already found."""
    if j < 0:
        return values[0]
    if j >= len(times) - 1:
        return values[-1]
    if times[j] == stamp:
        return values[j]
    slope = (values[j + 1] - values[j]) / (times[j + 1] - times[j])
    result = slope * (stamp - times[j]) + values[j]
    if math.isnan(result):  # numpy: try from the other end
        result = slope * (stamp - times[j + 1]) + values[j + 1]
        if math.isnan(result) and values[j] == values[j + 1]:
            result = values[j]
    return result


def _unwrap_corrections(yaw: NDArray[np.float64], start: float) -> NDArray[np.float64]:
    """The running corrections of ``np.unwrap(yaw)`` continued from ``start`` (the running
    correction at ``yaw[0]``): ``yaw + _unwrap_corrections(yaw, 0.0)`` is ``np.unwrap(yaw)``
    bit for bit (numpy's formula; its ``cumsum`` adds in order, so a prefix's last correction
    continues the sum exactly where the prefix was cut off)."""
    step = np.diff(yaw)
    wrapped = np.mod(step + math.pi, 2 * math.pi) - math.pi
    np.copyto(wrapped, math.pi, where=(wrapped == -math.pi) & (step > 0))
    correction = wrapped - step
    np.copyto(correction, 0.0, where=np.abs(step) < math.pi)
    return np.cumsum(np.concatenate(([start], correction)))


class StreamingTrack:
    """The whole-bag :class:`PoseTrack`, built while the bag is read once.

    Odometry samples are kept sorted as ``sorted()`` sorts them there and the yaw is unwrapped
    step by step exactly as ``np.unwrap`` does, so the pose of a scan asked for once the
    samples around its stamp are in equals the one of the whole-bag track (the interpolation
    is numpy's, done on Python lists: :func:`interp_at`).

    A bag is read once and every sample kept; a node running for days calls
    :meth:`forget_before` now and then. A sample costs about 230 bytes here (its tuple and
    four floats, 168 bytes; five list slots and the unwrapped yaw's float, 64; measured with
    ``tracemalloc``: 231): at 50 Hz, 4.3 million samples and 1 GB a day when nothing is
    forgotten.
    """

    def __init__(self) -> None:
        self.odom_frame = self.base_frame = ""
        self.restart()  # no samples yet
        self._candidates: dict[str, tuple[str, Pose2D, bool]] = {}
        self._mount: dict[str, Pose2D | None] = {}
        self._tree: PoseTrack | None = None  # the transforms (no samples), for mounts

    def add_odometry(self, frame_id: str, child_frame_id: str, sample: OdomSample) -> bool:
        """Add one ``nav_msgs/Odometry`` sample (``frame_id, child_frame_id, sample``).

        Returns whether it was taken: after :meth:`forget_before` dropped samples, one
        older than the samples kept is not (it would change the yaw unwrapping of the kept
        ones, and its stamp was forgotten).
        """
        if self._forgotten and sample < self._samples[0]:
            return False
        if not self.base_frame or not self.odom_frame:
            self.odom_frame = self.odom_frame or frame_name(frame_id)
            self.base_frame = self.base_frame or frame_name(child_frame_id)
            self._tree = None
            self._mount = {}
        if self._rebuild or (self._samples and sample < self._samples[-1]):
            bisect.insort(self._samples, sample)  # out of order: rebuilt when next used
            self._rebuild = True
            return True
        yaw = sample[3]
        if self._samples:
            step = yaw - self._samples[-1][3]
            wrapped = (step + math.pi) % (2 * math.pi) - math.pi  # np.mod's result for floats
            if wrapped == -math.pi and step > 0:
                wrapped = math.pi
            if abs(step) >= math.pi:
                self._correction += wrapped - step
            yaw = yaw + self._correction
        self._samples.append(sample)
        self._t.append(sample[0])
        self._x.append(sample[1])
        self._y.append(sample[2])
        self._yaw.append(yaw)
        return True

    def restart(self) -> None:
        """Forget every odometry sample, keep the transforms (the clock jumped back: a bag
        played again, a simulation restarted)."""
        self._samples: list[OdomSample] = []
        self._t: list[float] = []
        self._x: list[float] = []
        self._y: list[float] = []
        self._yaw: list[float] = []  # unwrapped
        self._correction = 0.0  # the running sum of np.unwrap's corrections
        self._first_correction = 0.0  # np.unwrap's running correction at _samples[0], exact
        self._forgotten = 0  # samples dropped by forget_before
        self._rebuild = False

    @property
    def n_kept(self) -> int:
        """The odometry samples held now (all those added, less the forgotten ones)."""
        return len(self._samples)

    @property
    def first_stamp(self) -> float | None:
        """The stamp of the oldest sample held, None without samples."""
        return self._samples[0][0] if self._samples else None

    @property
    def last_stamp(self) -> float | None:
        """The stamp of the newest sample held, None without samples."""
        return self._samples[-1][0] if self._samples else None

    def forget_before(self, stamp: float) -> int:
        """Drop the samples older than ``stamp`` but the newest at or before it.

        The pose at ``stamp`` and after stays what it was (bit for bit, the yaw unwrapping
        included); before the samples kept there is none from now on. Deleting a list's
        prefix moves the rest, O(n): samples are dropped only when at least
        :data:`FORGET_BATCH` and half of those held can go, so the cost is O(1) a dropped
        sample, and a track forgetting ``s`` seconds back holds at most about
        ``max(FORGET_BATCH, n) + n`` samples, ``n`` those of ``s`` seconds.

        Parameters
        ----------
        stamp : float
            The oldest stamp (s) whose pose is still needed.

        Returns
        -------
        int
            How many samples were dropped (0 when too few could go).
        """
        samples = self._samples
        first = bisect.bisect_right(samples, stamp, key=itemgetter(0)) - 1  # kept
        if first < max(FORGET_BATCH, len(samples) // 2):
            return 0
        yaw = np.array([sample[3] for sample in samples[: first + 1]], dtype=np.float64)
        self._first_correction = float(_unwrap_corrections(yaw, self._first_correction)[-1])
        del samples[:first]
        if self._rebuild:  # stale until rebuilt from the samples
            self._t, self._x, self._y, self._yaw = [], [], [], []
        else:
            for values in (self._t, self._x, self._y, self._yaw):
                del values[:first]
        self._forgotten += first
        return first

    def add_transforms(self, transforms: list[Transform], is_static: bool) -> None:
        """Add the transforms of one ``tf2_msgs/TFMessage`` (first value wins; static wins)."""
        if add_transforms(self._candidates, transforms, is_static):
            self._mount = {}  # the tree changed
            self._tree = None

    def _update(self) -> None:
        """Apply a pending rebuild (out-of-order samples) and the transform tree."""
        if self._rebuild:
            data = np.array(self._samples, dtype=np.float64).T
            data[3] += _unwrap_corrections(data[3], self._first_correction)  # np.unwrap
            self._t, self._x, self._y, self._yaw = (row.tolist() for row in data)
            self._correction = float(data[3, -1] - self._samples[-1][3])
            self._rebuild = False
        if self._tree is None:
            parents = {
                child: (parent, pose)
                for child, (parent, pose, _) in self._candidates.items()
                if not (child == self.base_frame and parent == self.odom_frame)
            }
            empty = np.empty(0)
            self._tree = PoseTrack(
                self.odom_frame, self.base_frame, empty, empty, empty, empty, parents, self._mount
            )

    def mount_of(self, frame: str) -> Pose2D | None:
        """Transform from the base frame to ``frame`` from what has been read, or None."""
        return self._mount_of(frame)

    def _mount_of(self, frame: str) -> Pose2D | None:
        found = self._mount.get(frame_name(frame), self)  # self: not computed yet
        if found is not self:
            return found  # type: ignore[return-value]
        self._update()
        assert self._tree is not None
        return self._tree.mount(frame)

    def ready(self, stamp_ns: int, frame_id: str) -> bool:
        """Whether the pose at ``stamp_ns`` is final: odometry after it, a known mount."""
        if not self._samples or self._samples[-1][0] <= ns_seconds(stamp_ns):
            return False
        return self._mount_of(frame_id) is not None

    def pose(self, stamp: float, frame: str) -> Pose2D | None:
        """Pose of ``frame`` at ``stamp`` from what has been read (as :meth:`PoseTrack.pose`;
        None before the samples kept once some were forgotten)."""
        if not self._samples:
            return None
        self._update()
        mount = self._mount_of(frame)
        times = self._t
        if mount is None or not times:
            return None
        if stamp < times[0] - POSE_TOLERANCE_S or stamp > times[-1] + POSE_TOLERANCE_S:
            return None
        if self._forgotten and stamp < times[0]:
            return None  # the samples before it are forgotten
        j = bisect.bisect_right(times, stamp) - 1
        base = (
            interp_at(stamp, times, self._x, j),
            interp_at(stamp, times, self._y, j),
            interp_at(stamp, times, self._yaw, j),
        )
        return compose(base, mount)


Edge = tuple[str, str]
"""A tf edge: parent frame, child frame."""


def stamped_transforms(msg: Any) -> list[tuple[Edge, OdomSample]]:
    """``((parent, child), (stamp, x, y, yaw))`` of each transform of a ``TFMessage``."""
    found = []
    for transform in msg.transforms:
        stamp = transform.header.stamp.sec + 1e-9 * transform.header.stamp.nanosec
        t, q = transform.transform.translation, transform.transform.rotation
        edge = (frame_name(transform.header.frame_id), frame_name(transform.child_frame_id))
        found.append((edge, (stamp, t.x, t.y, yaw_from_quaternion(q.x, q.y, q.z, q.w))))
    return found


def tf_odometry(
    laser: str,
    static: dict[str, str],
    moving: dict[Edge, list[OdomSample]],
    where: Path,
) -> tuple[Edge, list[OdomSample]] | None:
    """The odometry edge of a bag's ``/tf`` and its samples (sorted), or None.

    Parameters
    ----------
    laser : str
        The scan frame.
    static : dict of str to str
        Child -> parent of every transform (``/tf_static`` first, then ``/tf``).
    moving : dict of Edge to list of OdomSample
        Samples of every ``/tf`` edge (not in ``/tf_static``).
    where : Path
        The bag (for the error).

    Returns
    -------
    tuple or None
        Of the edges whose value changes, the one nearest above ``laser`` in the tree (the
        robot's ``odom -> base``, not a ``map -> odom`` above it); with none above the
        laser, the only one; None when no edge changes.

    Raises
    ------
    InputError
        Several changing edges and none above the laser frame.
    """
    dynamic = {
        edge: samples
        for edge, samples in moving.items()
        if len({s[1:] for s in samples}) > 1  # the transform changes: a moving robot
    }
    if not dynamic:
        return None
    chain, frame = [], frame_name(laser)
    while frame in static and frame not in chain:
        chain.append(frame)
        frame = static[frame]
    for child in chain:
        found = [edge for edge in dynamic if edge[1] == child]
        if found:
            return found[0], sorted(dynamic[found[0]])
    if len(dynamic) == 1:
        edge = next(iter(dynamic))
        return edge, sorted(dynamic[edge])
    listed = ", ".join(f"{p} -> {c}" for p, c in sorted(dynamic))
    raise InputError(
        f"{where}: odometry from /tf, which has several moving transforms ({listed}) "
        f"none of which is above the scan frame {laser!r}: add the missing /tf_static link "
        "or an Odometry topic"
    )
