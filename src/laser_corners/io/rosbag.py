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

Speed: the bag is read in one pass (scans, odometry and tf in log-time order, each chunk
decompressed once); a scan waits in a small look-ahead buffer until an odometry sample stamped
after it has been read, which gives the pose the whole-bag track (:meth:`BagSource.pose_track`)
gives. ROS 1 LaserScan, Odometry and TFMessage bytes are decoded with ``struct``/numpy
(:func:`decode_ros1_laserscan`, :func:`decode_ros1_odometry`, :func:`decode_ros1_tf`); a
message whose lengths do not add up, and every ROS 2/MCAP message, goes through rosbags'
deserializer.
"""

from __future__ import annotations

import bisect
import math
import struct
import zlib
from collections import deque
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

__all__ = [
    "LASERSCAN",
    "POSE_TOLERANCE_S",
    "BagSource",
    "decode_ros1_laserscan",
    "decode_ros1_odometry",
    "decode_ros1_tf",
    "yaw_from_quaternion",
]

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
        """One pass over the bag: scans, odometry and tf in log-time order.

        A scan waits in a small look-ahead buffer until the odometry has a sample stamped
        after it (so the interpolation brackets it) and its frame's mount is known; what is
        still waiting at the end of the bag is released with everything read.
        """
        self.stamps_ns = []
        self.log_times_ns = []
        with self.reader() as reader:
            # ROS 1 connections of the standard definitions: decode their bytes with numpy
            fast = {
                c.id for c in reader.connections
                if not reader.is2 and _ROS1_DIGESTS.get(c.msgtype) == c.digest
            }  # fmt: skip
            track = _StreamingTrack() if self.odom_topic is not None else None
            tf_topics = [
                t for t in ("/tf_static", "/tf") if self.topics.get(t, ("",))[0] == TFMESSAGE
            ]
            topics = [self.topic, *([self.odom_topic, *tf_topics] if track else [])]
            waiting: deque[_RawScan] = deque()
            odometry_position = f"reading {self.odom_topic} and tf"
            index = 0
            for connection, log_time, raw in self._messages(reader, topics):  # type: ignore[arg-type]
                if connection.topic != self.topic:
                    assert track is not None
                    if index == 0:  # later, the last scan message read says where we are
                        self.position = odometry_position
                    is_odometry = connection.msgtype == ODOMETRY
                    decoded = (
                        (decode_ros1_odometry(raw) if is_odometry else decode_ros1_tf(raw))
                        if connection.id in fast
                        else None
                    )
                    if decoded is None:
                        try:
                            msg = reader.deserialize(raw, connection.msgtype)
                        except _corrupt_errors():
                            self._skip(
                                f"undecodable {connection.msgtype} message", connection.topic
                            )
                            continue
                        decoded = _odometry_of(msg) if is_odometry else _transforms_of(msg)
                    if is_odometry:
                        track.add_odometry(*decoded)  # type: ignore[arg-type]
                    else:
                        track.add_transforms(decoded, connection.topic == "/tf_static")  # type: ignore[arg-type]
                    while waiting and track.ready(waiting[0]):
                        yield from self._release(waiting.popleft(), track)
                    continue
                where = f"message {index} of {self.topic}"
                index += 1
                self.position = where
                fields = decode_ros1_laserscan(raw) if connection.id in fast else None
                if fields is None:
                    try:
                        fields = _fields_of(reader.deserialize(raw, connection.msgtype))
                    except _corrupt_errors() as exc:
                        self._skip("undecodable LaserScan message", where, _first_line(exc))
                        continue
                item = _RawScan(where, int(log_time), *fields)
                if track is None or (not waiting and track.ready(item)):
                    yield from self._release(item, track)
                else:
                    waiting.append(item)
            while waiting:
                yield from self._release(waiting.popleft(), track)

    def _release(self, item: _RawScan, track: _StreamingTrack | None) -> Iterator[LaserScan]:
        """The LaserScan of a decoded message (nothing, counted as skipped, when invalid)."""
        self.position = item.where
        stamp = item.stamp_ns * 1e-9
        try:
            scan = LaserScan(
                item.ranges.astype(np.float64), item.angle_min, item.angle_increment,
                item.range_min, item.range_max, stamp, item.frame_id,
                track.pose(stamp, item.frame_id) if track is not None else None,
            )  # fmt: skip
        except InvalidScanError as exc:
            self._skip("invalid LaserScan fields", item.where, str(exc))
            return
        self.stamps_ns.append(item.stamp_ns)
        self.log_times_ns.append(item.log_time_ns)
        yield scan

    def describe(self) -> dict[str, object]:
        """Kind, path, every topic with type and count, the scan topic, time span."""
        info = super().describe()
        info["topic"] = self.topic
        info["topics"] = {t: {"type": m, "count": n} for t, (m, n) in sorted(self.topics.items())}
        info["duration_s"] = round((self.end_ns - self.start_ns) * 1e-9, 3)
        info["odometry"] = self.odom_topic
        return info


# ------------------------------------------------------------------ one-pass reading
_ROS1_HEADER = struct.Struct("<IiII")  # seq, stamp sec, stamp nsec, frame_id length
_ROS1_SCAN_FIELDS = struct.Struct("<7fI")  # angle_min .. range_max, ranges count
_ROS1_U32 = struct.Struct("<I")
_ROS1_DIGESTS = {
    LASERSCAN: "90c7ef2dc6895d81024acba2ac42f369",
    ODOMETRY: "cd5e73d190d741a2f92e81eda573aca7",
    TFMESSAGE: "94810edda583a504dfda3829e70d7eec",
}
"""MD5 sums of the ROS 1 definitions the fast decoders read (others go through rosbags)."""


def decode_ros1_laserscan(
    raw: bytes | memoryview,
) -> tuple[int, str, float, float, float, float, NDArray[np.float32]] | None:
    """The fields of a ROS 1 serialized ``sensor_msgs/LaserScan``, decoded with numpy.

    Parameters
    ----------
    raw : bytes
        The message bytes as stored in a ROS 1 bag.

    Returns
    -------
    tuple or None
        ``(stamp_ns, frame_id, angle_min, angle_increment, range_min, range_max, ranges)``
        (``ranges`` float32, read-only view of ``raw``); None when the bytes are not exactly
        one LaserScan (lengths that do not add up, a frame_id that is not UTF-8): the caller
        then uses the rosbags deserializer, which says what is wrong.
    """
    size = len(raw)
    if size < _ROS1_HEADER.size:
        return None
    _, sec, nsec, name_length = _ROS1_HEADER.unpack_from(raw, 0)
    offset = _ROS1_HEADER.size + name_length
    if offset + _ROS1_SCAN_FIELDS.size > size:
        return None
    angle_min, _, angle_increment, _, _, range_min, range_max, n_ranges = (
        _ROS1_SCAN_FIELDS.unpack_from(raw, offset)
    )
    ranges_at = offset + _ROS1_SCAN_FIELDS.size
    intensities_at = ranges_at + 4 * n_ranges
    if intensities_at + 4 > size:
        return None
    (n_intensities,) = _ROS1_U32.unpack_from(raw, intensities_at)
    if intensities_at + 4 + 4 * n_intensities != size:
        return None
    try:
        frame_id = bytes(raw[_ROS1_HEADER.size : _ROS1_HEADER.size + name_length]).decode()
    except UnicodeDecodeError:
        return None
    ranges = np.frombuffer(raw, dtype="<f4", count=n_ranges, offset=ranges_at)
    stamp_ns = sec * 1_000_000_000 + nsec
    return stamp_ns, frame_id, angle_min, angle_increment, range_min, range_max, ranges


_OdomSample = tuple[float, float, float, float]  # stamp (s), x, y, yaw
_Transform = tuple[str, str, Pose2D]  # parent frame, child frame, planar transform
_ROS1_STAMP_STRING = struct.Struct("<iII")  # stamp sec, stamp nsec, string length
_ROS1_POSE = struct.Struct("<7d")  # position x, y, z; orientation x, y, z, w
_ODOMETRY_TAIL = 8 * 36 + 8 * 6 + 8 * 36  # pose covariance, twist, twist covariance


def _ros1_string(raw: bytes | memoryview, offset: int) -> tuple[str, int] | None:
    """A u32-length-prefixed UTF-8 string at ``offset`` and the offset after it, or None."""
    if offset + 4 > len(raw):
        return None
    (length,) = _ROS1_U32.unpack_from(raw, offset)
    end = offset + 4 + length
    if end > len(raw):
        return None
    try:
        return bytes(raw[offset + 4 : end]).decode(), end
    except UnicodeDecodeError:
        return None


def _ros1_stamped_pose(
    raw: bytes | memoryview, offset: int
) -> tuple[float, str, str, tuple[float, ...], int] | None:
    """Header (stamp, frame_id), child_frame_id and 7 doubles from ``offset``, or None."""
    if offset + _ROS1_STAMP_STRING.size > len(raw):
        return None
    sec, nsec, _ = _ROS1_STAMP_STRING.unpack_from(raw, offset)
    frame = _ros1_string(raw, offset + 8)
    if frame is None:
        return None
    child = _ros1_string(raw, frame[1])
    if child is None or child[1] + _ROS1_POSE.size > len(raw):
        return None
    values = _ROS1_POSE.unpack_from(raw, child[1])
    return sec + 1e-9 * nsec, frame[0], child[0], values, child[1] + _ROS1_POSE.size


def decode_ros1_odometry(raw: bytes | memoryview) -> tuple[str, str, _OdomSample] | None:
    """``(frame_id, child_frame_id, (stamp, x, y, yaw))`` of a ROS 1 ``nav_msgs/Odometry``.

    None when the bytes are not exactly one Odometry message (the caller then falls back to
    the rosbags deserializer).
    """
    decoded = _ros1_stamped_pose(raw, 4)  # after header.seq
    if decoded is None or decoded[4] + _ODOMETRY_TAIL != len(raw):
        return None
    stamp, frame, child, (x, y, _, qx, qy, qz, qw), _ = decoded
    return frame, child, (stamp, x, y, yaw_from_quaternion(qx, qy, qz, qw))


def decode_ros1_tf(raw: bytes | memoryview) -> list[_Transform] | None:
    """``[(parent, child, (x, y, yaw)), ...]`` of a ROS 1 ``tf2_msgs/TFMessage``, or None."""
    if len(raw) < 4:
        return None
    (count,) = _ROS1_U32.unpack_from(raw, 0)
    offset = 4
    transforms: list[_Transform] = []
    for _ in range(count):
        decoded = _ros1_stamped_pose(raw, offset + 4)  # after header.seq
        if decoded is None:
            return None
        _, parent, child, (x, y, _, qx, qy, qz, qw), offset = decoded
        transforms.append((parent, child, (x, y, yaw_from_quaternion(qx, qy, qz, qw))))
    return transforms if offset == len(raw) else None


def _odometry_of(msg: Any) -> tuple[str, str, _OdomSample]:
    """What :func:`decode_ros1_odometry` gives, from a deserialized message."""
    stamp = msg.header.stamp.sec + 1e-9 * msg.header.stamp.nanosec
    q = msg.pose.pose.orientation
    p = msg.pose.pose.position
    return msg.header.frame_id, msg.child_frame_id, (
        stamp, p.x, p.y, yaw_from_quaternion(q.x, q.y, q.z, q.w)
    )  # fmt: skip


def _transforms_of(msg: Any) -> list[_Transform]:
    """What :func:`decode_ros1_tf` gives, from a deserialized message."""
    found = []
    for transform in msg.transforms:
        t, q = transform.transform.translation, transform.transform.rotation
        found.append((
            transform.header.frame_id, transform.child_frame_id,
            (t.x, t.y, yaw_from_quaternion(q.x, q.y, q.z, q.w)),
        ))  # fmt: skip
    return found


def _fields_of(msg: Any) -> tuple[int, str, float, float, float, float, NDArray[np.float32]]:
    """The fields :func:`decode_ros1_laserscan` gives, from a deserialized message."""
    stamp_ns = int(msg.header.stamp.sec) * 1_000_000_000 + int(msg.header.stamp.nanosec)
    return (
        stamp_ns, msg.header.frame_id, msg.angle_min, msg.angle_increment, msg.range_min,
        msg.range_max, np.asarray(msg.ranges, dtype=np.float32),
    )  # fmt: skip


@dataclass
class _RawScan:
    """A decoded LaserScan message waiting for its pose."""

    where: str
    log_time_ns: int
    stamp_ns: int
    frame_id: str
    angle_min: float
    angle_increment: float
    range_min: float
    range_max: float
    ranges: NDArray[np.float32]


class _StreamingTrack:
    """The pose track of :meth:`BagSource.pose_track`, built while the bag is read once.

    Odometry samples are kept sorted as ``sorted()`` sorts them there and the yaw is unwrapped
    step by step exactly as ``np.unwrap`` does, so the pose of a scan asked for once the
    samples around its stamp are in equals the one of the two-pass track.
    """

    def __init__(self) -> None:
        self.odom_frame = self.base_frame = ""
        self._samples: list[tuple[float, float, float, float]] = []
        self._data = np.empty((4, 64), dtype=np.float64)  # rows t, x, y, unwrapped yaw
        self._correction = 0.0  # the running sum of np.unwrap's corrections
        self._rebuild = False
        self._candidates: dict[str, tuple[str, Pose2D, bool]] = {}
        self._mount: dict[str, Pose2D | None] = {}
        self._track: _PoseTrack | None = None

    def add_odometry(self, frame_id: str, child_frame_id: str, sample: _OdomSample) -> None:
        """Add one ``nav_msgs/Odometry`` sample (from :func:`decode_ros1_odometry`)."""
        self.odom_frame = self.odom_frame or _frame(frame_id)
        self.base_frame = self.base_frame or _frame(child_frame_id)
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

    def add_transforms(self, transforms: list[_Transform], is_static: bool) -> None:
        """Add the transforms of one ``tf2_msgs/TFMessage`` (first value wins; static wins)."""
        for parent, child, pose in transforms:
            child = _frame(child)
            known = self._candidates.get(child)
            if known is not None and (known[2] or not is_static):
                continue
            self._candidates[child] = (_frame(parent), pose, is_static)
            self._mount = {}  # the tree changed
            self._track = None

    def _current(self) -> _PoseTrack | None:
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
            self._track = _PoseTrack(
                self.odom_frame, self.base_frame, t, x, y, yaw, parents, self._mount,
            )  # fmt: skip
        return self._track

    def ready(self, item: _RawScan) -> bool:
        """Whether the pose of ``item`` is final: odometry after its stamp, a known mount."""
        if not self._samples or self._samples[-1][0] <= item.stamp_ns * 1e-9:
            return False
        track = self._current()
        return track is not None and track.mount(item.frame_id) is not None

    def pose(self, stamp: float, frame: str) -> Pose2D | None:
        """Pose of ``frame`` at ``stamp`` from what has been read (as :meth:`_PoseTrack.pose`)."""
        track = self._current()
        return track.pose(stamp, frame) if track is not None else None


def _first_line(exc: BaseException) -> str:
    text = str(exc).strip()
    return text.splitlines()[0] if text else type(exc).__name__
