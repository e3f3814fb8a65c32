"""ROS 1 ``LaserScan``, ``Odometry`` and ``TFMessage`` bytes decoded with ``struct``/numpy.

These three message types make up nearly all the bytes a scan bag holds; decoding them
straight from the ROS 1 serialization is several times faster than rosbags' generic
deserializer. Each decoder returns None when the bytes are not exactly one message of its type
(lengths that do not add up, a frame name that is not UTF-8): the caller then uses rosbags'
deserializer, which says what is wrong. :func:`laserscan_fields`, :func:`odometry_of` and
:func:`transforms_of` give the same values from a deserialized message (ROS 2 and MCAP bags,
and the fallback).
"""

from __future__ import annotations

import struct
from typing import Any

import numpy as np
from numpy.typing import NDArray

from laser_corners.io.poses import OdomSample, Transform, yaw_from_quaternion

__all__ = [
    "LASERSCAN",
    "ODOMETRY",
    "ROS1_DIGESTS",
    "TFMESSAGE",
    "ScanFields",
    "decode_ros1_laserscan",
    "decode_ros1_odometry",
    "decode_ros1_tf",
    "laserscan_fields",
    "odometry_of",
    "transforms_of",
]

LASERSCAN = "sensor_msgs/msg/LaserScan"
ODOMETRY = "nav_msgs/msg/Odometry"
TFMESSAGE = "tf2_msgs/msg/TFMessage"
ROS1_DIGESTS = {
    LASERSCAN: "90c7ef2dc6895d81024acba2ac42f369",
    ODOMETRY: "cd5e73d190d741a2f92e81eda573aca7",
    TFMESSAGE: "94810edda583a504dfda3829e70d7eec",
}
"""MD5 sums of the ROS 1 definitions the fast decoders read (others go through rosbags)."""

ScanFields = tuple[int, str, float, float, float, float, NDArray[np.float32]]
"""``(stamp_ns, frame_id, angle_min, angle_increment, range_min, range_max, ranges)``."""

_HEADER = struct.Struct("<IiII")  # seq, stamp sec, stamp nsec, frame_id length
_SCAN_FIELDS = struct.Struct("<7fI")  # angle_min .. range_max, ranges count
_U32 = struct.Struct("<I")
_STAMP_STRING = struct.Struct("<iII")  # stamp sec, stamp nsec, string length
_POSE = struct.Struct("<7d")  # position x, y, z; orientation x, y, z, w
_ODOMETRY_TAIL = 8 * 36 + 8 * 6 + 8 * 36  # pose covariance, twist, twist covariance


def decode_ros1_laserscan(raw: bytes | memoryview) -> ScanFields | None:
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
        one LaserScan.
    """
    size = len(raw)
    if size < _HEADER.size:
        return None
    _, sec, nsec, name_length = _HEADER.unpack_from(raw, 0)
    offset = _HEADER.size + name_length
    if offset + _SCAN_FIELDS.size > size:
        return None
    angle_min, _, angle_increment, _, _, range_min, range_max, n_ranges = _SCAN_FIELDS.unpack_from(
        raw, offset
    )
    ranges_at = offset + _SCAN_FIELDS.size
    intensities_at = ranges_at + 4 * n_ranges
    if intensities_at + 4 > size:
        return None
    (n_intensities,) = _U32.unpack_from(raw, intensities_at)
    if intensities_at + 4 + 4 * n_intensities != size:
        return None
    try:
        frame_id = bytes(raw[_HEADER.size : _HEADER.size + name_length]).decode()
    except UnicodeDecodeError:
        return None
    ranges = np.frombuffer(raw, dtype="<f4", count=n_ranges, offset=ranges_at)
    stamp_ns = sec * 1_000_000_000 + nsec
    return stamp_ns, frame_id, angle_min, angle_increment, range_min, range_max, ranges


def _string(raw: bytes | memoryview, offset: int) -> tuple[str, int] | None:
    """A u32-length-prefixed UTF-8 string at ``offset`` and the offset after it, or None."""
    if offset + 4 > len(raw):
        return None
    (length,) = _U32.unpack_from(raw, offset)
    end = offset + 4 + length
    if end > len(raw):
        return None
    try:
        return bytes(raw[offset + 4 : end]).decode(), end
    except UnicodeDecodeError:
        return None


def _stamped_pose(
    raw: bytes | memoryview, offset: int
) -> tuple[float, str, str, tuple[float, ...], int] | None:
    """Header (stamp, frame_id), child_frame_id and 7 doubles from ``offset``, or None."""
    if offset + _STAMP_STRING.size > len(raw):
        return None
    sec, nsec, _ = _STAMP_STRING.unpack_from(raw, offset)
    frame = _string(raw, offset + 8)
    if frame is None:
        return None
    child = _string(raw, frame[1])
    if child is None or child[1] + _POSE.size > len(raw):
        return None
    values = _POSE.unpack_from(raw, child[1])
    return sec + 1e-9 * nsec, frame[0], child[0], values, child[1] + _POSE.size


def decode_ros1_odometry(raw: bytes | memoryview) -> tuple[str, str, OdomSample] | None:
    """``(frame_id, child_frame_id, (stamp, x, y, yaw))`` of a ROS 1 ``nav_msgs/Odometry``.

    None when the bytes are not exactly one Odometry message.
    """
    decoded = _stamped_pose(raw, 4)  # after header.seq
    if decoded is None or decoded[4] + _ODOMETRY_TAIL != len(raw):
        return None
    stamp, frame, child, (x, y, _, qx, qy, qz, qw), _ = decoded
    return frame, child, (stamp, x, y, yaw_from_quaternion(qx, qy, qz, qw))


def decode_ros1_tf(raw: bytes | memoryview) -> list[Transform] | None:
    """``[(parent, child, (x, y, yaw)), ...]`` of a ROS 1 ``tf2_msgs/TFMessage``, or None."""
    if len(raw) < 4:
        return None
    (count,) = _U32.unpack_from(raw, 0)
    offset = 4
    transforms: list[Transform] = []
    for _ in range(count):
        decoded = _stamped_pose(raw, offset + 4)  # after header.seq
        if decoded is None:
            return None
        _, parent, child, (x, y, _, qx, qy, qz, qw), offset = decoded
        transforms.append((parent, child, (x, y, yaw_from_quaternion(qx, qy, qz, qw))))
    return transforms if offset == len(raw) else None


def odometry_of(msg: Any) -> tuple[str, str, OdomSample]:
    """What :func:`decode_ros1_odometry` gives, from a deserialized message."""
    stamp = msg.header.stamp.sec + 1e-9 * msg.header.stamp.nanosec
    q = msg.pose.pose.orientation
    p = msg.pose.pose.position
    return (
        msg.header.frame_id,
        msg.child_frame_id,
        (stamp, p.x, p.y, yaw_from_quaternion(q.x, q.y, q.z, q.w)),
    )


def transforms_of(msg: Any) -> list[Transform]:
    """What :func:`decode_ros1_tf` gives, from a deserialized message."""
    found = []
    for transform in msg.transforms:
        t, q = transform.transform.translation, transform.transform.rotation
        found.append(
            (
                transform.header.frame_id,
                transform.child_frame_id,
                (t.x, t.y, yaw_from_quaternion(q.x, q.y, q.z, q.w)),
            )
        )
    return found


def laserscan_fields(msg: Any) -> ScanFields:
    """What :func:`decode_ros1_laserscan` gives, from a deserialized message."""
    stamp_ns = int(msg.header.stamp.sec) * 1_000_000_000 + int(msg.header.stamp.nanosec)
    return (
        stamp_ns,
        msg.header.frame_id,
        msg.angle_min,
        msg.angle_increment,
        msg.range_min,
        msg.range_max,
        np.asarray(msg.ranges, dtype=np.float32),
    )
