"""ROS 1 bags, ROS 2 bags (sqlite3 or MCAP storage) and bare ``.mcap`` files through rosbags.

Messages are matched on the type name ``sensor_msgs/msg/LaserScan`` and deserialized by the
reader's typestore (from the bag's own definitions, else a stock typestore from
``get_typestore``), so no ROS installation is needed.

Sensor pose: when the bag has a ``nav_msgs/msg/Odometry`` topic, each scan gets the pose of its
``header.frame_id`` in the odometry frame: the odometry is interpolated linearly (x, y and the
unwrapped yaw) at the scan stamp, then composed with the transform from the odometry's
``child_frame_id`` to the laser frame found in ``/tf_static`` (and in ``/tf`` for transforms
other than odometry -> base, first value kept). No odometry, no transform chain, or a stamp
more than :data:`POSE_TOLERANCE_S` outside the odometry's time span: ``pose`` is ``None``.
"""

from __future__ import annotations

import math
import struct
import zlib
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from laser_corners.errors import InputError, InvalidScanError
from laser_corners.io.source import ScanSource, SourceKind
from laser_corners.scan import LaserScan, Pose2D

__all__ = ["LASERSCAN", "POSE_TOLERANCE_S", "BagSource", "yaw_from_quaternion"]

LASERSCAN = "sensor_msgs/msg/LaserScan"
ODOMETRY = "nav_msgs/msg/Odometry"
TFMESSAGE = "tf2_msgs/msg/TFMessage"
POSE_TOLERANCE_S = 0.5
"""How far (s) a scan stamp may lie outside the odometry's time span and still get a pose."""


def _corrupt_errors() -> tuple[type[BaseException], ...]:
    """Exceptions rosbags lets through on damaged bags (it asserts on some real ones)."""
    from rosbags.highlevel import AnyReaderError
    from rosbags.rosbag1 import ReaderError as Reader1Error
    from rosbags.rosbag2 import ReaderError as Reader2Error

    return (
        AnyReaderError, Reader1Error, Reader2Error, AssertionError, OSError, EOFError,
        struct.error, zlib.error, UnicodeDecodeError, ValueError, IndexError, KeyError,
    )  # fmt: skip


def yaw_from_quaternion(x: float, y: float, z: float, w: float) -> float:
    """Yaw (rotation about z) of a unit quaternion, radians."""
    return math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))


def _compose(a: Pose2D, b: Pose2D) -> Pose2D:
    """The planar transform ``a`` followed by ``b`` (``b`` expressed in ``a``'s frame)."""
    c, s = math.cos(a[2]), math.sin(a[2])
    theta = math.atan2(math.sin(a[2] + b[2]), math.cos(a[2] + b[2]))
    return (a[0] + c * b[0] - s * b[1], a[1] + s * b[0] + c * b[1], theta)


def _frame(name: str) -> str:
    return name.lstrip("/")


@dataclass
class _PoseTrack:
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
        frame = _frame(frame)
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
                chain = _compose(transform, chain)  # type: ignore[arg-type]
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
        return _compose(base, mount)


class BagSource(ScanSource):
    """The LaserScan messages of one topic of a ROS 1/ROS 2/MCAP bag.

    Parameters
    ----------
    path : Path
        The bag (file or ROS 2 bag directory).
    kind : {"ros1", "ros2", "mcap"}
        Its kind.
    topic : str, optional
        The LaserScan topic; default: the only one.
    strict : bool
        With False, several LaserScan topics and no ``topic`` pick the first one instead of
        raising (for listings such as ``laser-corners info``).

    Attributes
    ----------
    topics : dict of str to tuple of (str, int)
        Every topic of the bag: message type and message count.
    laser_topics : list of str
        The ``sensor_msgs/msg/LaserScan`` topics.
    odom_topic : str or None
        The odometry topic used for poses.
    stamps_ns : list of int
        Header stamps (ns) of the scans yielded so far, by scan index (exact, for writers).
    log_times_ns : list of int
        Bag log times (ns) of the scans yielded so far.
    start_ns, end_ns : int
        Bag time span.
    """

    def __init__(
        self, path: Path, kind: SourceKind, topic: str | None = None, strict: bool = True
    ) -> None:
        super().__init__(path, topic)
        self.kind = kind
        self.stamps_ns: list[int] = []
        self.log_times_ns: list[int] = []
        with self.reader() as reader:
            self.topics: dict[str, tuple[str, int]] = {}
            for connection in reader.connections:
                msgtype, count = self.topics.get(connection.topic, (connection.msgtype, 0))
                self.topics[connection.topic] = (msgtype, count + connection.msgcount)
            self.start_ns = int(reader.start_time) if reader.connections else 0
            self.end_ns = int(reader.end_time) if reader.connections else 0
        self.laser_topics = sorted(t for t, (m, _) in self.topics.items() if m == LASERSCAN)
        if not strict and topic is None and len(self.laser_topics) > 1:
            self.topic = self.laser_topics[0]  # ``strict=False``: listing, not reading
        else:
            self.topic = self._choose_topic(topic)
        odoms = sorted(t for t, (m, _) in self.topics.items() if m == ODOMETRY)
        self.odom_topic: str | None = "/odom" if "/odom" in odoms else (odoms[0] if odoms else None)

    def _choose_topic(self, topic: str | None) -> str:
        found = ", ".join(self.laser_topics) or "none"
        if topic is not None:
            if topic not in self.topics:
                raise InputError(
                    f"{self.path}: no topic {topic!r} in the bag; LaserScan topics: {found}"
                )
            msgtype = self.topics[topic][0]
            if msgtype != LASERSCAN:
                raise InputError(
                    f"{self.path}: topic {topic} is a {msgtype}, not a {LASERSCAN}; "
                    f"LaserScan topics: {found}"
                )
            return topic
        if not self.laser_topics:
            listed = ", ".join(f"{t} ({m})" for t, (m, _) in sorted(self.topics.items()))
            raise InputError(f"{self.path}: no {LASERSCAN} topic; topics: {listed or 'none'}")
        if len(self.laser_topics) > 1:
            lines = "\n".join(f"  --topic {t}" for t in self.laser_topics)
            raise InputError(
                f"{self.path}: {len(self.laser_topics)} LaserScan topics; choose one by adding "
                f"one of these options:\n{lines}"
            )
        return self.laser_topics[0]

    @contextmanager
    def reader(self) -> Iterator[Any]:
        """An open rosbags ``AnyReader``; damaged bags raise :class:`InputError`."""
        from rosbags.highlevel import AnyReader
        from rosbags.typesys import Stores, get_typestore

        store = Stores.ROS1_NOETIC if self.kind == "ros1" else Stores.ROS2_HUMBLE
        try:
            reader = AnyReader([self.path], default_typestore=get_typestore(store))
            reader.open()
        except _corrupt_errors() as exc:
            raise InputError(
                f"{self.path}: cannot open the {self.kind} bag, damaged or truncated? "
                f"({type(exc).__name__}: {_first_line(exc)})"
            ) from None
        try:
            yield reader
        finally:
            reader.close()

    @property
    def n_scans(self) -> int:
        """Number of messages on the scan topic (from the bag's index)."""
        return self.topics[self.topic][1]  # type: ignore[index]

    def _messages(self, reader: Any, topics: list[str]) -> Iterator[tuple[Any, int, bytes]]:
        connections = [c for c in reader.connections if c.topic in topics]
        iterator = reader.messages(connections=connections)
        while True:
            try:
                item = next(iterator)
            except StopIteration:
                return
            except _corrupt_errors() as exc:
                raise self.error(
                    f"damaged bag data ({type(exc).__name__}: {_first_line(exc)})"
                ) from None
            yield item

    def pose_track(self, reader: Any) -> _PoseTrack | None:
        """Read odometry and tf (one pass over those topics) into a pose track, or None."""
        if self.odom_topic is None:
            return None
        tf_topics = [t for t in ("/tf_static", "/tf") if self.topics.get(t, ("",))[0] == TFMESSAGE]
        samples: list[tuple[float, float, float, float]] = []
        odom_frame = base_frame = ""
        candidates: dict[str, tuple[str, Pose2D, bool]] = {}
        self.position = f"reading {self.odom_topic} and tf"
        for connection, _, raw in self._messages(reader, [self.odom_topic, *tf_topics]):
            try:
                msg = reader.deserialize(raw, connection.msgtype)
            except _corrupt_errors():
                self._skip(f"undecodable {connection.msgtype} message", connection.topic)
                continue
            if connection.msgtype == ODOMETRY:
                odom_frame = odom_frame or _frame(msg.header.frame_id)
                base_frame = base_frame or _frame(msg.child_frame_id)
                stamp = msg.header.stamp.sec + 1e-9 * msg.header.stamp.nanosec
                q = msg.pose.pose.orientation
                yaw = yaw_from_quaternion(q.x, q.y, q.z, q.w)
                p = msg.pose.pose.position
                samples.append((stamp, p.x, p.y, yaw))
                continue
            is_static = connection.topic == "/tf_static"
            for transform in msg.transforms:
                child = _frame(transform.child_frame_id)
                parent = _frame(transform.header.frame_id)
                known = candidates.get(child)
                if known is not None and (known[2] or not is_static):
                    continue  # the first value wins; /tf_static wins over /tf
                t, q = transform.transform.translation, transform.transform.rotation
                candidates[child] = (
                    parent,
                    (t.x, t.y, yaw_from_quaternion(q.x, q.y, q.z, q.w)),
                    is_static,
                )
        if not samples:
            return None
        parents = {
            child: (parent, pose)
            for child, (parent, pose, _) in candidates.items()
            if not (child == base_frame and parent == odom_frame)
        }
        data = np.array(sorted(samples), dtype=np.float64)
        return _PoseTrack(
            odom_frame, base_frame, data[:, 0], data[:, 1], data[:, 2], np.unwrap(data[:, 3]),
            parents,
        )  # fmt: skip

    def _scans(self) -> Iterator[LaserScan]:
        self.stamps_ns = []
        self.log_times_ns = []
        with self.reader() as reader:
            track = self.pose_track(reader)
            for index, (connection, log_time, raw) in enumerate(
                self._messages(reader, [self.topic])  # type: ignore[list-item]
            ):
                where = f"message {index} of {self.topic}"
                self.position = where
                try:
                    msg = reader.deserialize(raw, connection.msgtype)
                except _corrupt_errors() as exc:
                    self._skip("undecodable LaserScan message", where, _first_line(exc))
                    continue
                stamp_ns = int(msg.header.stamp.sec) * 1_000_000_000 + int(msg.header.stamp.nanosec)
                stamp = stamp_ns * 1e-9
                frame_id = msg.header.frame_id
                try:
                    scan = LaserScan(
                        np.asarray(msg.ranges, dtype=np.float64), msg.angle_min,
                        msg.angle_increment, msg.range_min, msg.range_max, stamp, frame_id,
                        track.pose(stamp, frame_id) if track is not None else None,
                    )  # fmt: skip
                except InvalidScanError as exc:
                    self._skip("invalid LaserScan fields", where, str(exc))
                    continue
                self.stamps_ns.append(stamp_ns)
                self.log_times_ns.append(int(log_time))
                yield scan

    def describe(self) -> dict[str, object]:
        """Kind, path, every topic with type and count, the scan topic, time span."""
        info = super().describe()
        info["topic"] = self.topic
        info["topics"] = {t: {"type": m, "count": n} for t, (m, n) in sorted(self.topics.items())}
        info["duration_s"] = round((self.end_ns - self.start_ns) * 1e-9, 3)
        info["odometry"] = self.odom_topic
        return info


def _first_line(exc: BaseException) -> str:
    text = str(exc).strip()
    return text.splitlines()[0] if text else type(exc).__name__
