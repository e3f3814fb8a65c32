"""ROS 1 bags, ROS 2 bags (sqlite3 or MCAP storage) and bare ``.mcap`` files through rosbags.

Messages are matched on the type name ``sensor_msgs/msg/LaserScan`` and deserialized by the
reader's typestore (from the bag's own definitions, else a stock typestore from
``get_typestore``), so no ROS installation is needed. A ROS 1 bag whose index rosbags refuses
is read from its chunk records (:mod:`laser_corners.io.ros1.chunks`).

Sensor pose (:mod:`laser_corners.io.poses`): each scan gets the pose of its frame in the
odometry frame, interpolated at its stamp. The odometry source (``odom_topic``): a
``nav_msgs/msg/Odometry`` topic by name, or :data:`TF_ODOMETRY_CHOICE` (``"tf"``) for ``/tf``;
by default the only Odometry topic, ``/tf`` when there is none, and with several of them
a :class:`~laser_corners.io.base.TopicChoiceError` for ``--odom-topic`` (the reader does not
choose).
From ``/tf`` (:func:`~laser_corners.io.poses.tf_odometry`), the odometry is the transform that
changes over the bag nearest above the scan frame in the tf tree (``odom -> base_link`` under
a ``map -> odom``), whose parent is the odometry frame.

Speed: the bag is read in one pass (scans, odometry and tf in log-time order, each chunk
decompressed once); a scan waits in a small look-ahead buffer until an odometry sample stamped
after it has been read, which gives the pose the whole-bag track (:meth:`BagSource.pose_track`)
gives. ROS 1 LaserScan, Odometry and TFMessage bytes are decoded with ``struct``/numpy
(:mod:`laser_corners.io.ros1.decode`); a message whose lengths do not add up, and every
ROS 2/MCAP message, goes through rosbags' deserializer. ROS 1 bags of standard definitions are
read by the lean path (:meth:`BagSource._lean_scans`: the messages of each chunk located and
decoded in blocks, :mod:`laser_corners.io.ros1.lean`), which yields exactly what the
per-message path yields; ``BagSource.lean = False`` turns it off.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from laser_corners.errors import InputError, InvalidScanError, first_line
from laser_corners.io.bagfile import (
    CORRUPT_ERRORS,
    iter_messages,
    lean_pieces,
    open_bag_reader,
    read_from_chunks,
)
from laser_corners.io.base import BAD_POSE, ScanSource, SourceKind, TopicChoiceError
from laser_corners.io.poses import (
    Edge,
    OdomSample,
    PoseTrack,
    StreamingTrack,
    add_transforms,
    frame_name,
    ns_seconds,
    stamped_transforms,
    tf_odometry,
    track_from,
)
from laser_corners.io.ros1.decode import (
    LASERSCAN,
    ODOMETRY,
    ROS1_DIGESTS,
    TFMESSAGE,
    decode_ros1_laserscan,
    decode_ros1_odometry,
    decode_ros1_tf,
    laserscan_fields,
    odometry_of,
    transforms_of,
)
from laser_corners.io.ros1.index import LeanPlan
from laser_corners.io.ros1.lean import finite_pose
from laser_corners.io.ros1.runs import (
    LOST_SCANS,
    SCAN,
    ChunkRun,
    RawScan,
    kind_of,
    lean_readable,
)
from laser_corners.pose import pose_problem
from laser_corners.scan import LaserScan, Pose2D

__all__ = ["TF_ODOMETRY", "TF_ODOMETRY_CHOICE", "BagSource", "tf_odometry"]

TF_ODOMETRY = "/tf"
"""``BagSource.odom_topic`` when the odometry is read from ``/tf``."""
TF_ODOMETRY_CHOICE = "tf"
"""The ``odom_topic`` value (``--odom-topic tf``) that takes the odometry from ``/tf``."""


class _TopicChoice:
    """The topic-choice part of :class:`BagSource`: the bag's topics from its index, the scan
    topic and the odometry (a topic, ``/tf``, or none) among them, and ``describe``."""

    path: Path
    topic: str | None
    topics: dict[str, tuple[str, int]]
    laser_topics: list[str]
    odom_topics: list[str]
    tf_topics: list[str]
    start_ns: int
    end_ns: int
    from_chunks: bool
    odom_topic: str | None
    tf_odometry: Edge | None
    _tf_asked: bool

    def _index_topics(self, reader: Any) -> None:
        """Every topic of the open bag with its type and count, the time span, and the
        LaserScan, Odometry and tf topics among them."""
        self.topics = {}
        for connection in reader.connections:
            msgtype, count = self.topics.get(connection.topic, (connection.msgtype, 0))
            self.topics[connection.topic] = (msgtype, count + connection.msgcount)
        self.start_ns = int(reader.start_time) if reader.connections else 0
        self.end_ns = int(reader.end_time) if reader.connections else 0
        self.from_chunks = read_from_chunks(reader)
        self.laser_topics = sorted(t for t, (m, _) in self.topics.items() if m == LASERSCAN)
        self.odom_topics = sorted(t for t, (m, _) in self.topics.items() if m == ODOMETRY)
        self.tf_topics = [
            t for t in ("/tf_static", "/tf") if self.topics.get(t, ("",))[0] == TFMESSAGE
        ]

    def _choose_topic(self, topic: str | None) -> str:
        if topic is not None:
            found = f"LaserScan topics: {', '.join(self.laser_topics) or 'none'}"
            return self._named_topic(topic, LASERSCAN, "topic", found)
        if not self.laser_topics:
            listed = ", ".join(f"{t} ({m})" for t, (m, _) in sorted(self.topics.items()))
            raise InputError(f"{self.path}: no {LASERSCAN} topic; topics: {listed or 'none'}")
        if len(self.laser_topics) > 1:
            raise TopicChoiceError(self.path, self.laser_topics)
        return self.laser_topics[0]

    def _choose_odometry(self, asked: str | None, strict: bool) -> str | None:
        """The odometry topic (:data:`TF_ODOMETRY` for ``/tf``) for ``odom_topic=asked``."""
        has_tf = TF_ODOMETRY in self.tf_topics
        if asked is None:
            if len(self.odom_topics) > 1:
                if strict:
                    also = f" (or {TF_ODOMETRY_CHOICE} for the odometry on /tf)"
                    raise TopicChoiceError(
                        self.path, self.odom_topics, ODOMETRY, "--odom-topic", also
                    )
                return None  # a listing: no odometry is read
            if self.odom_topics:
                return self.odom_topics[0]
            return TF_ODOMETRY if has_tf else None
        found = f"{ODOMETRY} topics: {', '.join(self.odom_topics) or 'none'}"
        found += f"; /tf: {'yes' if has_tf else 'none'}"
        if self._tf_asked:
            if not has_tf:
                raise InputError(f"{self.path}: odometry {asked!r}: no /tf topic; {found}")
            return TF_ODOMETRY
        return self._named_topic(asked, ODOMETRY, "odometry topic", found)

    def _named_topic(self, topic: str, wanted: str, label: str, found: str) -> str:
        """``topic`` when the bag has it with messages of type ``wanted``, else one line
        naming it (as ``label``) and ending with ``found`` (what the bag has instead)."""
        if topic not in self.topics:
            raise InputError(f"{self.path}: no {label} {topic!r} in the bag; {found}")
        msgtype = self.topics[topic][0]
        if msgtype != wanted:
            raise InputError(
                f"{self.path}: {label} {topic} is a {msgtype}, not a {wanted}; {found}"
            )
        return topic

    @property
    def n_scans(self) -> int:
        """Number of messages on the scan topic (from the bag's index)."""
        return self.topics[self.topic][1]  # type: ignore[index]

    def describe(self) -> dict[str, object]:
        """Kind, path, every topic with type and count, the scan topic, time span."""
        info = super().describe()
        info["topic"] = self.topic
        info["topics"] = {t: {"type": m, "count": n} for t, (m, n) in sorted(self.topics.items())}
        info["duration_s"] = round((self.end_ns - self.start_ns) * 1e-9, 3)
        info["odometry"] = self.odom_topic
        if self.odom_topic is None and len(self.odom_topics) > 1:
            info["odometry"] = f"not chosen: {', '.join(self.odom_topics)} (--odom-topic)"
        if self.tf_odometry is not None:
            info["odometry"] = f"/tf {self.tf_odometry[0]} -> {self.tf_odometry[1]}"
        info["index"] = "unreadable; read from its chunks" if self.from_chunks else "ok"
        return info


class _PoseReading:
    """The pose part of :class:`BagSource`: the odometry edge of ``/tf``, the whole-bag pose
    track, and one odometry or tf message into a streaming track."""

    path: Path
    topic: str | None
    tf_topics: list[str]
    odom_topic: str | None
    tf_odometry: Edge | None
    position: str
    _tf_samples: list[OdomSample] | None
    _tf_asked: bool

    def _read_tf_odometry(self, reader: Any) -> None:
        """With the odometry from ``/tf``: read the tf topics once for :func:`tf_odometry`
        (the scan frame from the first scan message); no moving transform: no odometry."""
        if self.odom_topic != TF_ODOMETRY or self._tf_samples is not None:
            return
        laser = ""
        self.position = f"reading {self.topic} for its frame"
        for connection, _, raw in self.messages(reader, [self.topic]):  # type: ignore[list-item]
            fields = decode_ros1_laserscan(raw) if not reader.is2 else None
            if fields is None:
                try:
                    fields = laserscan_fields(reader.deserialize(raw, connection.msgtype))
                except CORRUPT_ERRORS:
                    continue
            laser = fields[1]
            break
        static: dict[str, str] = {}
        moving: dict[Edge, list[OdomSample]] = {}
        fixed: set[str] = set()  # children of /tf_static transforms
        self.position = "reading /tf for odometry"
        for connection, _, raw in self.messages(reader, self.tf_topics):
            try:
                msg = reader.deserialize(raw, connection.msgtype)
            except CORRUPT_ERRORS:
                continue  # counted when the scans are read
            is_static = connection.topic == "/tf_static"
            for (parent, child), sample in stamped_transforms(msg):
                if is_static:
                    static[child] = parent
                    fixed.add(child)
                else:
                    static.setdefault(child, parent)
                    moving.setdefault((parent, child), []).append(sample)
        moving = {edge: samples for edge, samples in moving.items() if edge[1] not in fixed}
        chosen = tf_odometry(laser, static, moving, self.path)
        if chosen is None and self._tf_asked:
            raise InputError(f"{self.path}: odometry 'tf': no /tf transform changes over the bag")
        if chosen is None:
            self.odom_topic = None
            self._tf_samples = []
            return
        self.tf_odometry, self._tf_samples = chosen

    def pose_track(self, reader: Any) -> PoseTrack | None:
        """Read odometry and tf (one pass over those topics) into a pose track, or None."""
        self._read_tf_odometry(reader)
        if self.odom_topic is None:
            return None
        samples = list(self._tf_samples or [])
        odom_frame, base_frame = self.tf_odometry or ("", "")
        transforms: dict[str, tuple[str, Pose2D, bool]] = {}
        self.position = f"reading {self.odom_topic} and tf"
        for connection, _, raw in self.messages(reader, [self.odom_topic, *self.tf_topics]):
            try:
                msg = reader.deserialize(raw, connection.msgtype)
            except CORRUPT_ERRORS:
                self._skip(f"undecodable {connection.msgtype} message", connection.topic)
                continue
            if connection.msgtype == ODOMETRY:
                frame, child, sample = odometry_of(msg)
                odom_frame = odom_frame or frame_name(frame)
                base_frame = base_frame or frame_name(child)
                samples.append(sample)
            else:
                add_transforms(transforms, transforms_of(msg), connection.topic == "/tf_static")
        return track_from(samples, transforms, odom_frame, base_frame)

    def _pose_message(
        self, reader: Any, connection: Any, raw: bytes, fast: bool, track: StreamingTrack
    ) -> None:
        """Add one odometry or tf message to ``track`` (undecodable: a counted skip)."""
        is_odometry = connection.msgtype == ODOMETRY
        decoder = decode_ros1_odometry if is_odometry else decode_ros1_tf
        decoded: Any = decoder(raw) if fast else None
        if decoded is None:
            try:
                msg = reader.deserialize(raw, connection.msgtype)
            except CORRUPT_ERRORS:
                self._skip(f"undecodable {connection.msgtype} message", connection.topic)
                return
            decoded = odometry_of(msg) if is_odometry else transforms_of(msg)
        if is_odometry:
            track.add_odometry(*decoded)
        else:
            track.add_transforms(decoded, connection.topic == "/tf_static")


class _LeanReading:
    """The lean part of :class:`BagSource` (ROS 1 bags of standard definitions): the messages
    of each chunk run located and decoded in blocks (:mod:`laser_corners.io.ros1.lean`)."""

    topic: str | None
    odom_topic: str | None
    position: str
    skipped: dict[str, int]
    _lean_index: int

    def _lean_scans(
        self, reader: Any, topics: list[str], track: StreamingTrack | None
    ) -> Iterator[LaserScan]:
        """What the per-message loop of :meth:`_scans` yields, chunk run by chunk run
        (:mod:`laser_corners.io.ros1.lean`); an undecompressable chunk or a damaged record is
        a counted skip (with its scans), and reading goes on after it."""
        connections = [c for c in reader.connections if c.topic in topics]
        plan = LeanPlan.of(connections)
        kinds = [kind_of(c, self.topic) for c in connections]
        waiting: deque[RawScan] = deque()
        self._lean_index = 0

        def damage(rows: slice, reason: str | None, where: str, detail: str) -> None:
            if reason is not None:
                self._skip(reason, where, detail)
            self._lost_scans(plan.ranks[rows], kinds)

        for piece in lean_pieces(plan, damage):
            rows = slice(piece.first, piece.first + piece.starts.size)
            times, ranks = plan.times[rows], plan.ranks[rows]
            run = ChunkRun(piece.data, piece.starts, piece.lengths, [kinds[r] for r in ranks])
            run.decode()
            yield from self._lean_run(reader, run, times, connections, ranks, track, waiting)
        while waiting:
            yield from self._release(waiting.popleft(), track)

    def _lost_scans(self, ranks: NDArray[np.int64], kinds: list[int]) -> None:
        """Count the scans among the messages of ``ranks`` lost to damage."""
        if lost := sum(1 for r in ranks.tolist() if kinds[r] == SCAN):
            self.skipped[LOST_SCANS] = self.skipped.get(LOST_SCANS, 0) + lost
            self._lean_index += lost

    def _lean_run(
        self,
        reader: Any,
        run: ChunkRun,
        times: NDArray[np.int64],
        connections: list[Any],
        ranks: NDArray[np.int64],
        track: StreamingTrack | None,
        waiting: deque[RawScan],
    ) -> Iterator[LaserScan]:
        """The messages of one chunk run, in order (see :meth:`_scans`)."""
        log_times = times.tolist()
        for j, kind in enumerate(run.kinds):
            if kind == SCAN:
                where = f"message {self._lean_index} of {self.topic}"
                self._lean_index += 1
                self.position = where
                item = run.scan(j, where, log_times[j])
                if item is None:
                    item = self._raw_scan(
                        reader, connections[ranks[j]], run.raw(j), where, log_times[j]
                    )
                    if item is None:
                        continue
                if track is None or (not waiting and track.ready(item.stamp_ns, item.frame_id)):
                    yield from self._release(item, track)
                else:
                    waiting.append(item)
                continue
            assert track is not None
            if self._lean_index == 0:
                self.position = f"reading {self.odom_topic} and tf"
            if run.repeat[j]:
                continue  # a tf message that changes nothing (see ChunkRun.decode)
            sample = run.odometry.get(j)
            if sample is not None:
                track.add_odometry(*sample)
            else:
                connection = connections[ranks[j]]
                self._pose_message(reader, connection, run.raw(j), True, track)
            while waiting and track.ready(waiting[0].stamp_ns, waiting[0].frame_id):
                yield from self._release(waiting.popleft(), track)

    def _raw_scan(
        self, reader: Any, connection: Any, raw: bytes, where: str, log_time: int
    ) -> RawScan | None:
        """A scan message decoded on its own (None: undecodable, counted as skipped)."""
        fields = decode_ros1_laserscan(raw)
        if fields is None:
            try:
                fields = laserscan_fields(reader.deserialize(raw, connection.msgtype))
            except CORRUPT_ERRORS as exc:
                self._skip("undecodable LaserScan message", where, first_line(exc))
                return None
        return RawScan(where, log_time, *fields)


class BagSource(_TopicChoice, _PoseReading, _LeanReading, ScanSource):
    """The LaserScan messages of one topic of a ROS 1/ROS 2/MCAP bag.

    Split by concern: :class:`_TopicChoice` (the topics, the scan topic and the odometry),
    :class:`_PoseReading` (``/tf`` odometry, pose tracks), :class:`_LeanReading` (the ROS 1
    lean path); this class opens the bag and reads it in one pass (:meth:`_scans`).

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
        raising, and several Odometry topics and no ``odom_topic`` read no odometry (for
        listings such as ``laser-corners info``).
    odom_topic : str, optional
        The odometry: a ``nav_msgs/msg/Odometry`` topic, or ``"tf"`` for ``/tf``. Default:
        the only Odometry topic, ``/tf`` when there is none; several raise a
        :class:`~laser_corners.io.base.TopicChoiceError` (``option="--odom-topic"``).

    Attributes
    ----------
    topics : dict of str to tuple of (str, int)
        Every topic of the bag: message type and message count.
    laser_topics : list of str
        The ``sensor_msgs/msg/LaserScan`` topics.
    odom_topics : list of str
        The ``nav_msgs/msg/Odometry`` topics.
    odom_topic : str or None
        The odometry topic used for poses; :data:`TF_ODOMETRY` when the odometry comes from
        ``/tf`` (set to None on the first read when ``/tf`` has no moving transform, unless
        it was asked for: then that read raises :class:`InputError`).
    tf_odometry : tuple of (str, str) or None
        ``(odometry frame, base frame)`` of the ``/tf`` odometry, once read.
    mounts : dict of str to Pose2D or None
        Base -> laser transform of each scan frame read so far (what scan poses composed).
    stamps_ns : list of int
        Header stamps (ns) of the scans yielded so far, by scan index (exact, for writers).
    log_times_ns : list of int
        Bag log times (ns) of the scans yielded so far.
    start_ns, end_ns : int
        Bag time span.
    from_chunks : bool
        rosbags refused the bag's index; it is read from its chunk records.
    """

    lean: bool = True
    """Read ROS 1 bags with :mod:`laser_corners.io.ros1.lean` where it applies (False: the
    per-message path through rosbags, e.g. to compare them)."""

    def __init__(
        self,
        path: Path,
        kind: SourceKind,
        topic: str | None = None,
        strict: bool = True,
        *,
        odom_topic: str | None = None,
    ) -> None:
        super().__init__(path, topic)
        self.kind = kind
        self.read_lean = False
        """Whether the scans were read by the lean path (set once reading starts)."""
        self.stamps_ns: list[int] = []
        self.log_times_ns: list[int] = []
        self.mounts: dict[str, Pose2D | None] = {}
        self._lean_index = 0
        with self.reader() as reader:
            self._index_topics(reader)
        if not strict and topic is None and len(self.laser_topics) > 1:
            self.topic = self.laser_topics[0]  # ``strict=False``: listing, not reading
        else:
            self.topic = self._choose_topic(topic)
        self.tf_odometry: Edge | None = None
        self._tf_samples: list[OdomSample] | None = None
        self._tf_asked = odom_topic in (TF_ODOMETRY_CHOICE, TF_ODOMETRY)
        # a TF_ODOMETRY choice is resolved (or dropped) by _read_tf_odometry
        self.odom_topic: str | None = self._choose_odometry(odom_topic, strict)

    @contextmanager
    def reader(self) -> Iterator[Any]:
        """An open rosbags ``AnyReader``; damaged bags raise :class:`InputError`."""
        with open_bag_reader(self.path, self.kind, lean=self.lean) as reader:
            yield reader

    def messages(self, reader: Any, topics: list[str]) -> Iterator[tuple[Any, int, bytes]]:
        """``(connection, log_time_ns, raw)`` of ``topics``; damage raises :class:`InputError`."""
        return iter_messages(reader, topics, self.error)

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
                c.id
                for c in reader.connections
                if not reader.is2 and ROS1_DIGESTS.get(c.msgtype) == c.digest
            }
            self._read_tf_odometry(reader)
            track = StreamingTrack() if self.odom_topic is not None else None
            topics = [self.topic, *([self.odom_topic, *self.tf_topics] if track else [])]
            topics = list(dict.fromkeys(topics))  # /tf once when it is the odometry
            if track is not None and self.tf_odometry is not None:
                for sample in self._tf_samples or []:  # the odometry from /tf, read first
                    track.add_odometry(*self.tf_odometry, sample)
            if self.lean and lean_readable(reader, topics, fast):
                self.read_lean = True
                yield from self._lean_scans(reader, topics, track)
                return
            waiting: deque[RawScan] = deque()
            index = 0
            for connection, log_time, raw in self.messages(reader, topics):  # type: ignore[arg-type]
                if connection.topic != self.topic:
                    assert track is not None
                    if index == 0:  # later, the last scan message read says where we are
                        self.position = f"reading {self.odom_topic} and tf"
                    self._pose_message(reader, connection, raw, connection.id in fast, track)
                    while waiting and track.ready(waiting[0].stamp_ns, waiting[0].frame_id):
                        yield from self._release(waiting.popleft(), track)
                    continue
                where = f"message {index} of {self.topic}"
                index += 1
                self.position = where
                fields = decode_ros1_laserscan(raw) if connection.id in fast else None
                if fields is None:
                    try:
                        fields = laserscan_fields(reader.deserialize(raw, connection.msgtype))
                    except CORRUPT_ERRORS as exc:
                        self._skip("undecodable LaserScan message", where, first_line(exc))
                        continue
                item = RawScan(where, int(log_time), *fields)
                if track is None or (not waiting and track.ready(item.stamp_ns, item.frame_id)):
                    yield from self._release(item, track)
                else:
                    waiting.append(item)
            while waiting:
                yield from self._release(waiting.popleft(), track)

    def _release(self, item: RawScan, track: StreamingTrack | None) -> Iterator[LaserScan]:
        """The LaserScan of a decoded message (nothing, counted as skipped, when invalid)."""
        self.position = item.where
        stamp = ns_seconds(item.stamp_ns)
        pose = track.pose(stamp, item.frame_id) if track is not None else None
        if track is not None and item.frame_id not in self.mounts:
            self.mounts[item.frame_id] = track.mount_of(item.frame_id)
        geometry = (item.angle_min, item.angle_increment, item.range_min, item.range_max)
        fields = (*geometry, stamp, item.frame_id, pose)
        problem = None if pose is None else pose_problem(pose)
        if problem is not None and finite_pose(pose):  # odometry thousands of km away
            self._skip(BAD_POSE, item.where, problem)  # here: stamps_ns keeps to the scans
            return
        if item.checked and finite_pose(pose):  # the lean path checked the geometry
            self.stamps_ns.append(item.stamp_ns)
            self.log_times_ns.append(item.log_time_ns)
            yield LaserScan.from_checked(item.ranges, *fields)
            return
        try:
            scan = LaserScan(item.ranges.astype(np.float64), *fields)
        except InvalidScanError as exc:
            self._skip("invalid LaserScan fields", item.where, str(exc))
            return
        self.stamps_ns.append(item.stamp_ns)
        self.log_times_ns.append(item.log_time_ns)
        yield scan
