"""A copy of the input bag with keypoint topics, for RViz and Foxglove.

The output holds every message of the input, then for each scan two messages with the scan's
header (stamp and frame) and the scan's log time:

* ``<scan_topic>_corners``: ``geometry_msgs/msg/PoseArray`` (orientation = keypoint
  orientation as a yaw quaternion);
* ``<scan_topic>_corner_markers``: ``visualization_msgs/msg/MarkerArray`` (a DELETEALL then one
  arrow per keypoint).

A ROS 1 input gives a ``.bag`` (rosbag1 ``Writer``); a ROS 2 or MCAP input gives a ROS 2 bag
directory with MCAP storage (its name ends in ``.mcap``). The input is copied when the writer
opens, keypoint messages are added as scans are processed, and the bag index is written by
``close()``, so an interrupted run still leaves a readable bag.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from laser_corners.errors import InputError
from laser_corners.io.messages import keypoints_to_marker_fields, keypoints_to_pose_array_fields
from laser_corners.io.source import ScanSource
from laser_corners.io.writers import KeypointWriter
from laser_corners.keypoints import Keypoints
from laser_corners.scan import LaserScan

__all__ = ["BagKeypointWriter", "default_message"]

POSE_ARRAY = "geometry_msgs/msg/PoseArray"
MARKER_ARRAY = "visualization_msgs/msg/MarkerArray"


def default_message(typestore: Any, typename: str) -> Any:
    """An instance of ``typename`` with every field zero, empty or default-constructed."""
    from rosbags.typesys.base import Nodetype

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
    from rosbags.typesys.base import Nodetype

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

    Parameters
    ----------
    path : Path
        ``.bag`` for a ROS 1 input, ``.mcap`` for a ROS 2/MCAP input; must not exist.
    source : BagSource
        The input being processed (:func:`~laser_corners.io.open_scans` of a bag).
    ns : str
        Marker namespace.
    lifetime : float
        Marker lifetime, seconds (0: until the next scan's DELETEALL).
    """

    def __init__(
        self, path: Path, source: ScanSource, ns: str = "corners", lifetime: float = 0.0
    ) -> None:
        super().__init__()
        from laser_corners.io.rosbag import BagSource

        if not isinstance(source, BagSource):
            raise InputError(
                f"{path}: a bag output needs a bag input, {source.path} is a {source.kind} "
                "file; write .csv or .parquet"
            )
        want = ".bag" if source.kind == "ros1" else ".mcap"
        if path.suffix.lower() != want:
            raise InputError(
                f"{path}: a {source.kind} input is copied to a {want} output, not "
                f"{path.suffix.lower()}"
            )
        if path.exists():
            raise InputError(f"{path}: exists already; remove it or choose another name")
        self.path = path
        self.source = source
        self.ns = ns
        self.lifetime = lifetime
        self.corners_topic = f"{source.topic}_corners"
        self.markers_topic = f"{source.topic}_corner_markers"
        self.n_copied = 0
        self._ros1 = source.kind == "ros1"
        self._closed = False
        self._writer: Any = None
        try:
            self._open_and_copy()
        except BaseException:
            self.close()
            raise

    def _open_and_copy(self) -> None:
        from rosbags.typesys import Stores, get_typestore

        stock = get_typestore(Stores.ROS1_NOETIC if self._ros1 else Stores.ROS2_HUMBLE)
        typestore = get_typestore(Stores.EMPTY)
        with self.source.reader() as reader:  # type: ignore[attr-defined]
            bag_types = dict(reader.typestore.fielddefs)
            extra = {
                k: v
                for k, v in _closure(stock, [POSE_ARRAY, MARKER_ARRAY]).items()
                if k not in bag_types
            }
            typestore.register({**bag_types, **extra})
            self.typestore = typestore
            if self._ros1:
                from rosbags.rosbag1 import Writer as Writer1

                self._writer = Writer1(self.path)
            else:
                from rosbags.rosbag2 import StoragePlugin
                from rosbags.rosbag2 import Writer as Writer2

                self._writer = Writer2(self.path, version=9, storage_plugin=StoragePlugin.MCAP)
            self._writer.open()
            mapping: dict[int, Any] = {}
            added: dict[tuple[Any, ...], Any] = {}
            for connection in reader.connections:
                key = (
                    connection.topic,
                    connection.msgtype,
                    connection.digest,
                    repr(connection.ext),
                )
                if key not in added:
                    added[key] = self._add_copy(connection)
                mapping[connection.id] = added[key]
            self._corners = self._add_new(self.corners_topic, POSE_ARRAY)
            self._markers = self._add_new(self.markers_topic, MARKER_ARRAY)
            for connection, log_time, raw in self.source._messages(  # type: ignore[attr-defined]
                reader,
                list(self.source.topics),  # type: ignore[attr-defined]
            ):
                self._writer.write(mapping[connection.id], log_time, raw)
                self.n_copied += 1

    def _add_copy(self, connection: Any) -> Any:
        if self._ros1:
            return self._writer.add_connection(
                connection.topic, connection.msgtype, msgdef=connection.msgdef.data,
                md5sum=connection.digest, callerid=connection.ext.callerid,
                latching=connection.ext.latching,
            )  # fmt: skip
        return self._writer.add_connection(
            connection.topic, connection.msgtype, typestore=self.typestore,
            serialization_format=connection.ext.serialization_format,
            offered_qos_profiles=connection.ext.offered_qos_profiles,
        )  # fmt: skip

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
        """Add the keypoint messages of scan ``scan_index`` (its header, its log time)."""
        super().write(scan_index, scan, keypoints)
        stamp_ns = self.source.stamps_ns[scan_index]  # type: ignore[attr-defined]
        log_time = self.source.log_times_ns[scan_index]  # type: ignore[attr-defined]
        poses = self.pose_array(stamp_ns, scan.frame_id, keypoints)
        markers = self.marker_array(stamp_ns, scan.frame_id, keypoints)
        self._writer.write(self._corners, log_time, self._serialize(poses, POSE_ARRAY))
        self._writer.write(self._markers, log_time, self._serialize(markers, MARKER_ARRAY))

    def close(self) -> None:
        """Write the bag's index and close it."""
        if not self._closed:
            self._closed = True
            if self._writer is not None:
                self._writer.close()
