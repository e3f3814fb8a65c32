"""A copy of the input bag with keypoint topics, for RViz and Foxglove.

The output holds every message of the input and, for each scan, two messages with the scan's
header (stamp and frame) and the scan's log time:

* ``<scan_topic>_corners``: ``geometry_msgs/msg/PoseArray`` (orientation = keypoint
  orientation as a yaw quaternion);
* ``<scan_topic>_corner_markers``: ``visualization_msgs/msg/MarkerArray`` (a DELETEALL then one
  arrow per keypoint).

A ROS 1 input gives a ``.bag`` (:class:`~laser_corners.io.ros1.writer.RosbagWriter`: rosbags'
writer with rosbag's header layout, chunks compressed with ``lz4`` by default, or ``bz2`` or
``none``); a ROS 2 or MCAP input gives one ``.mcap`` file (rosbags' ROS 2 MCAP storage, every
message type's definition inside; rosbags and ``open_scans`` read it alone). The input is
copied as the scans are processed, with their keypoint messages; ``close()`` copies the rest,
writes the bag's index and renames the bag from its temporary name (``STEM.XXXXXXXX.partial.bag``
beside it; an ``.mcap`` is written as rosbags' ROS 2 bag folder inside
``STEM.XXXXXXXX.partial/`` and its ``.mcap`` file moved out) to the final one, replacing an
older file of that name as the table outputs are replaced, so an interrupted run (Ctrl-C)
still leaves a complete bag with the keypoints
of the scans processed. A ROS 1 output's chunks are written every ``flush_every`` scans: after a
kill, the temporary bag (no index) holds them and :func:`~laser_corners.io.open_scans` reads it.
"""

from __future__ import annotations

from contextlib import ExitStack
from pathlib import Path
from typing import Any

import numpy as np
from rosbags.rosbag2 import StoragePlugin
from rosbags.rosbag2 import Writer as Writer2
from rosbags.typesys import Stores, get_typestore
from rosbags.typesys.base import Nodetype

from laser_corners.errors import InputError, OutputError
from laser_corners.io.bagfile import BagInput, iter_messages, open_bag_reader, stock_typestore
from laser_corners.io.base import KeypointWriter, PartialOutput
from laser_corners.io.messages import keypoints_to_marker_fields, keypoints_to_pose_array_fields
from laser_corners.io.ros1.writer import COMPRESSIONS, RosbagWriter
from laser_corners.keypoints import Keypoints
from laser_corners.scan import LaserScan

__all__ = ["BAG_COMPRESSION", "BagKeypointWriter", "default_message"]

POSE_ARRAY = "geometry_msgs/msg/PoseArray"
MARKER_ARRAY = "visualization_msgs/msg/MarkerArray"
BAG_COMPRESSION = "lz4"
"""Default chunk compression of a ``.bag`` output. On fr079.bag's copy lz4 gives 6.9 MB, bz2
4.1 MB, none 24.0 MB (the input is 2.2 MB, bz2); lz4 costs no measurable time where bz2 costs
some, and rosbag reads both (lz4 through ``roslz4``, a dependency of Debian's rosbag)."""


def default_message(typestore: Any, typename: str) -> Any:
    """An instance of ``typename`` with every field zero, empty or default-constructed."""

    def value(nodetype: int, detail: Any) -> Any:
        if nodetype == Nodetype.BASE:
            name = detail[0]
            if name == "string":
                return ""
            if name == "bool":
                return False
            return 0.0 if name.startswith("float") else 0
        if nodetype == Nodetype.NAME:
            return default_message(typestore, detail)
        (sub_type, sub_detail), length = detail
        if sub_type == Nodetype.BASE and sub_detail[0] not in ("string", "bool"):
            dtype = {"char": np.uint8, "byte": np.uint8, "octet": np.uint8}.get(
                sub_detail[0], sub_detail[0]
            )
            return np.zeros(length if nodetype == Nodetype.ARRAY else 0, dtype=dtype)
        if nodetype == Nodetype.ARRAY:
            return [value(sub_type, sub_detail) for _ in range(length)]
        return []

    _, fields = typestore.fielddefs[typename]
    return typestore.types[typename](**{name: value(nt, d) for name, (nt, d) in fields})


def _closure(store: Any, names: list[str]) -> dict[str, Any]:
    """The field definitions of ``names`` and every type they use, from ``store``."""
    out: dict[str, Any] = {}
    todo = list(names)
    while todo:
        name = todo.pop()
        if name in out:
            continue
        out[name] = store.fielddefs[name]
        for _, (nodetype, detail) in out[name][1]:
            if nodetype == Nodetype.NAME:
                todo.append(detail)
            elif nodetype in (Nodetype.ARRAY, Nodetype.SEQUENCE) and detail[0][0] == Nodetype.NAME:
                todo.append(detail[0][1])
    return out


class BagKeypointWriter(KeypointWriter):
    """Copy of a bag plus ``<topic>_corners`` and ``<topic>_corner_markers`` topics.

    The input's messages are copied as the scans are processed (those logged up to each scan,
    then its two keypoint messages), and the rest of the input by :meth:`close`, so the
    output is in log-time order and an interrupted run keeps the keypoints written so far.

    Parameters
    ----------
    path : Path
        ``.bag`` for a ROS 1 input, ``.mcap`` for a ROS 2/MCAP input (replaced if it exists).
    source : BagInput
        The input being processed (a ``BagSource``, :func:`~laser_corners.io.open_scans` of
        a bag).
    ns : str
        Marker namespace.
    lifetime : float
        Marker lifetime, seconds (0: until the next scan's DELETEALL).
    flush_every : int
        Write the ROS 1 chunk being filled to the file every ``flush_every`` scans.
    compression : {"lz4", "bz2", "none"}
        Chunk compression of a ``.bag`` output (:data:`BAG_COMPRESSION` by default); an
        ``.mcap`` output is not compressed.

    Raises
    ------
    InputError
        The input cannot be read.
    OutputError
        ``path`` has the suffix of the other ROS version, an unknown compression, or its
        folder cannot be written.
    """

    def __init__(
        self,
        path: Path,
        source: BagInput,
        ns: str = "corners",
        lifetime: float = 0.0,
        flush_every: int = 100,
        compression: str = BAG_COMPRESSION,
    ) -> None:
        super().__init__()
        if compression not in COMPRESSIONS:
            raise OutputError(
                f"{path}: unknown bag compression {compression!r}; use one of "
                f"{', '.join(COMPRESSIONS)}"
            )
        self.compression = compression
        want = ".bag" if source.kind == "ros1" else ".mcap"
        if path.suffix.lower() != want:
            raise OutputError(
                f"{path}: a {source.kind} input is copied to a {want} output, not "
                f"{path.suffix.lower()}"
            )
        self.path = path
        self.source = source
        self.ns = ns
        self.lifetime = lifetime
        self.flush_every = max(1, flush_every)
        self.corners_topic = f"{source.topic}_corners"
        self.markers_topic = f"{source.topic}_corner_markers"
        self.n_copied = 0
        self.damaged: list[str] = []  # ROS 1: damaged chunks and records left out of the copy
        self._ros1 = source.kind == "ros1"
        self._partial = PartialOutput(path, overwrite=True, create=False, folder=not self._ros1)
        self._member: Path | None = None  # an .mcap output: the file of rosbags' bag folder
        self._writer: Any = None
        self._input = ExitStack()
        self._unflushed = 0
        try:
            self._open()
        except BaseException:
            self._abort()
            raise

    def _open(self) -> None:
        reader = self._input.enter_context(open_bag_reader(self.source.path, self.source.kind))
        bag_types = dict(reader.typestore.fielddefs)
        stock = _closure(stock_typestore(self.source.kind), [POSE_ARRAY, MARKER_ARRAY])
        typestore = get_typestore(Stores.EMPTY)
        typestore.register({**bag_types, **{k: v for k, v in stock.items() if k not in bag_types}})
        self.typestore = typestore
        assert self._partial is not None
        temporary = self._partial.temporary
        if self._ros1:
            self._writer = RosbagWriter(temporary, self.compression)
            self._writer.open()
        else:
            self._writer = Writer2(temporary, version=9, storage_plugin=StoragePlugin.MCAP)
            self._writer.open()
            self._member = Path(self._writer.storage.path)
        self._mapping: dict[int, Any] = {}
        added: dict[tuple[Any, ...], Any] = {}
        for connection in reader.connections:
            key = (connection.topic, connection.msgtype, connection.digest, repr(connection.ext))
            if key not in added:
                added[key] = self._add_copy(connection)
            self._mapping[connection.id] = added[key]
        self._corners = self._add_new(self.corners_topic, POSE_ARRAY)
        self._markers = self._add_new(self.markers_topic, MARKER_ARRAY)

        def error(message: str) -> InputError:
            return InputError(f"{self.source.path}: {message} (copying it to {self.path})")

        def damage(rows: slice, reason: str | None, where: str, detail: str) -> None:
            if reason is not None:  # skipped in the copy too (the source counts its scans)
                self.damaged.append(f"{where}: {reason} ({detail})")

        self._pending = iter_messages(reader, list(self.source.topics), error, damage)
        self._next = next(self._pending, None)

    def _copy_until(self, log_time: int | None) -> None:
        """Copy the input's messages logged up to ``log_time`` (None: all the rest)."""
        while self._next is not None and (log_time is None or self._next[1] <= log_time):
            connection, stamp, raw = self._next
            self._writer.write(self._mapping[connection.id], stamp, raw)
            self.n_copied += 1
            self._next = next(self._pending, None)

    def _add_copy(self, connection: Any) -> Any:
        if self._ros1:
            return self._writer.add_connection(
                connection.topic,
                connection.msgtype,
                msgdef=connection.msgdef.data,
                md5sum=connection.digest,
                callerid=connection.ext.callerid,
                latching=connection.ext.latching,
            )
        return self._writer.add_connection(
            connection.topic,
            connection.msgtype,
            typestore=self.typestore,
            serialization_format=connection.ext.serialization_format,
            offered_qos_profiles=connection.ext.offered_qos_profiles,
        )

    def _add_new(self, topic: str, msgtype: str) -> Any:
        return self._writer.add_connection(topic, msgtype, typestore=self.typestore)

    def _header(self, stamp_ns: int, frame_id: str) -> Any:
        header = default_message(self.typestore, "std_msgs/msg/Header")
        header.stamp.sec, header.stamp.nanosec = divmod(int(stamp_ns), 1_000_000_000)
        header.frame_id = frame_id
        return header

    def pose_array(self, stamp_ns: int, frame_id: str, keypoints: Keypoints) -> Any:
        """The ``PoseArray`` message of ``keypoints`` (a rosbags message object)."""
        fields = keypoints_to_pose_array_fields(keypoints)
        msg = default_message(self.typestore, POSE_ARRAY)
        msg.header = self._header(stamp_ns, frame_id)
        for position, orientation in zip(fields["positions"], fields["orientations"], strict=True):
            pose = default_message(self.typestore, "geometry_msgs/msg/Pose")
            pose.position.x, pose.position.y, pose.position.z = (float(v) for v in position)
            q = pose.orientation
            q.x, q.y, q.z, q.w = (float(v) for v in orientation)
            msg.poses.append(pose)
        return msg

    def marker_array(self, stamp_ns: int, frame_id: str, keypoints: Keypoints) -> Any:
        """The ``MarkerArray`` message of ``keypoints`` (a rosbags message object)."""
        msg = default_message(self.typestore, MARKER_ARRAY)
        for fields in keypoints_to_marker_fields(keypoints, self.ns, self.lifetime):
            marker = default_message(self.typestore, "visualization_msgs/msg/Marker")
            marker.header = self._header(stamp_ns, frame_id)
            marker.ns, marker.id = fields["ns"], fields["id"]
            marker.type, marker.action = fields["type"], fields["action"]
            p, q = marker.pose.position, marker.pose.orientation
            p.x, p.y, p.z = fields["position"]
            q.x, q.y, q.z, q.w = fields["orientation"]
            marker.scale.x, marker.scale.y, marker.scale.z = fields["scale"]
            c = marker.color
            c.r, c.g, c.b, c.a = fields["color"]
            sec, nanosec = divmod(round(fields["lifetime"] * 1e9), 1_000_000_000)
            marker.lifetime.sec, marker.lifetime.nanosec = sec, nanosec
            msg.markers.append(marker)
        return msg

    def _serialize(self, msg: Any, msgtype: str) -> bytes:
        if self._ros1:
            return bytes(self.typestore.serialize_ros1(msg, msgtype))
        return bytes(self.typestore.serialize_cdr(msg, msgtype))

    def write(self, scan_index: int, scan: LaserScan, keypoints: Keypoints) -> None:
        """Copy the input up to scan ``scan_index``, then add its keypoint messages (its
        header, its log time); counted once both are written."""
        stamp_ns = self.source.stamps_ns[scan_index]
        log_time = self.source.log_times_ns[scan_index]
        self._copy_until(log_time)
        poses = self.pose_array(stamp_ns, scan.frame_id, keypoints)
        markers = self.marker_array(stamp_ns, scan.frame_id, keypoints)
        self._writer.write(self._corners, log_time, self._serialize(poses, POSE_ARRAY))
        self._writer.write(self._markers, log_time, self._serialize(markers, MARKER_ARRAY))
        super().write(scan_index, scan, keypoints)
        self._unflushed += 1
        if self._unflushed >= self.flush_every:
            self.flush()

    def flush(self) -> None:
        """Write the ROS 1 chunk being filled to the file (ROS 2: the MCAP writer's own)."""
        self._unflushed = 0
        if self._ros1 and self._writer.bio is not None:
            self._writer.write_chunk(self._writer.chunks[-1])
            self._writer.bio.flush()

    def close(self) -> None:
        """Copy the rest of the input, write the bag's index, give it its final name."""
        if self.closed or self._writer is None:
            return
        try:
            self._copy_until(None)
        finally:
            self._writer.close()
            self._input.close()
            assert self._partial is not None
            self._partial.publish(self._member)
            self.closed = True

    def _abort(self) -> None:
        """Undo a failed open: close what was opened, remove the temporary output."""
        if self._writer is not None:
            self._writer.abort()
        self._writer = None
        self._input.close()
        assert self._partial is not None
        self._partial.discard()
