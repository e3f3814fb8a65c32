"""ROS-free conversions between ROS messages and laser-corners types.

Everything here works on *any* object with the fields of the ROS message (ROS 1 genpy classes,
ROS 2 rclpy classes, rosbags dataclasses, ``types.SimpleNamespace``), so it is tested without a
ROS installation and shared by the ROS 1 and ROS 2 nodes.

* ``sensor_msgs/LaserScan`` -> :class:`~laser_corners.LaserScan`: :func:`scan_from_msg`
  (beam angles from ``len(ranges)``; ``angle_max`` is ignored).
* :class:`~laser_corners.Keypoints` -> ``geometry_msgs/PoseArray``: :func:`fill_pose_array`
  puts the values of :func:`laser_corners.io.messages.keypoints_to_pose_array_fields` into
  message objects of either ROS version.
* marker dicts of :func:`laser_corners.io.messages.keypoints_to_marker_fields` ->
  ``visualization_msgs/MarkerArray``: :func:`fill_marker_array`.

The bag writer uses the same :mod:`laser_corners.io.messages` values, so the nodes and the
``*_corners`` topics written to bags carry the same poses and markers.

The input ``header`` (stamp and frame) is copied to every output by the nodes.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np

from laser_corners.errors import InvalidScanError
from laser_corners.io.messages import keypoints_to_pose_array_fields
from laser_corners.keypoints import Keypoints
from laser_corners.scan import LaserScan

__all__ = [
    "fill_marker_array",
    "fill_pose_array",
    "scan_from_msg",
    "seconds_to_sec_nanosec",
    "stamp_to_sec",
]


def stamp_to_sec(stamp: Any) -> float:
    """Seconds of a ROS time stamp.

    Accepts ROS 1 ``(secs, nsecs)``, ROS 2 ``(sec, nanosec)`` stamps, objects with
    ``to_sec()`` and plain numbers.

    Raises
    ------
    InvalidScanError
        If ``stamp`` is none of these.
    """
    if isinstance(stamp, int | float):
        return float(stamp)
    for sec_name, nsec_name in (("secs", "nsecs"), ("sec", "nanosec")):
        if hasattr(stamp, sec_name) and hasattr(stamp, nsec_name):
            return int(getattr(stamp, sec_name)) + int(getattr(stamp, nsec_name)) * 1e-9
    if callable(getattr(stamp, "to_sec", None)):
        return float(stamp.to_sec())
    raise InvalidScanError(f"header.stamp is not a ROS time stamp: {stamp!r}")


def seconds_to_sec_nanosec(seconds: float) -> tuple[int, int]:
    """Split non-negative ``seconds`` into ROS 2 ``(sec, nanosec)`` with ``0 <= nanosec < 1e9``."""
    total_ns = round(float(seconds) * 1e9)
    sec, nanosec = divmod(total_ns, 1_000_000_000)
    return int(sec), int(nanosec)


def scan_from_msg(msg: Any) -> LaserScan:
    """A :class:`~laser_corners.LaserScan` from a ``sensor_msgs/LaserScan`` message.

    Beam ``i`` is at ``angle_min + i * angle_increment`` for ``i < len(ranges)``; the message's
    ``angle_max`` is not used (drivers round it inconsistently). The stamp (seconds) and
    ``frame_id`` come from the message header.

    Parameters
    ----------
    msg : sensor_msgs/LaserScan
        Any object with the message's fields (ROS 1, ROS 2 or rosbags).

    Returns
    -------
    LaserScan

    Raises
    ------
    InvalidScanError
        If a field is missing or invalid (the message names the field).
    """
    try:
        header = msg.header
        fields = {
            name: getattr(msg, name)
            for name in ("ranges", "angle_min", "angle_increment", "range_min", "range_max")
        }
        stamp, frame_id = header.stamp, header.frame_id
    except AttributeError as exc:
        raise InvalidScanError(f"not a sensor_msgs/LaserScan message: {exc}") from None
    try:
        ranges = np.asarray(fields.pop("ranges"), dtype=np.float64)
    except (TypeError, ValueError):
        raise InvalidScanError("LaserScan.ranges must be numeric") from None
    return LaserScan(
        ranges=ranges,
        stamp=stamp_to_sec(stamp),
        frame_id=str(frame_id),
        **fields,
    )


def _set_xyz(target: Any, values: Sequence[float], names: str = "xyz") -> None:
    for name, value in zip(names, values, strict=True):
        setattr(target, name, float(value))


def fill_pose_array(pose_array: Any, pose_factory: Callable[[], Any], kps: Keypoints) -> Any:
    """Fill ``pose_array.poses`` with one pose per keypoint.

    Parameters
    ----------
    pose_array : geometry_msgs/PoseArray
        The message to fill (its header is left as is).
    pose_factory : callable
        Makes an empty ``geometry_msgs/Pose`` (the ``Pose`` class of ROS 1 or ROS 2).
    kps : Keypoints
        The keypoints.

    Returns
    -------
    The filled ``pose_array``.
    """
    fields = keypoints_to_pose_array_fields(kps)
    poses = []
    for position, orientation in zip(fields["positions"], fields["orientations"], strict=True):
        pose = pose_factory()
        _set_xyz(pose.position, position)
        _set_xyz(pose.orientation, orientation, "xyzw")
        poses.append(pose)
    pose_array.poses = poses
    return pose_array


def fill_marker_array(
    marker_array: Any,
    marker_factory: Callable[[], Any],
    point_factory: Callable[[], Any],
    duration_factory: Callable[[float], Any],
    header: Any,
    markers: Sequence[Mapping[str, Any]],
) -> Any:
    """Fill ``marker_array.markers`` from :func:`keypoints_to_marker_fields` dicts.

    Parameters
    ----------
    marker_array : visualization_msgs/MarkerArray
        The message to fill.
    marker_factory, point_factory : callable
        Make an empty ``visualization_msgs/Marker`` / ``geometry_msgs/Point``.
    duration_factory : callable
        Seconds -> the ROS duration type of ``Marker.lifetime``.
    header : std_msgs/Header
        Copied to every marker (the input scan's stamp and frame).
    markers : sequence of dict
        Output of :func:`laser_corners.io.messages.keypoints_to_marker_fields`; an optional
        ``points`` entry (list of ``(x, y, z)``) fills ``Marker.points``.

    Returns
    -------
    The filled ``marker_array``.
    """
    out = []
    for fields in markers:
        msg = marker_factory()
        msg.header = header
        msg.ns = str(fields["ns"])
        msg.id = int(fields["id"])
        msg.type = int(fields["type"])
        msg.action = int(fields["action"])
        _set_xyz(msg.pose.position, fields["position"])
        _set_xyz(msg.pose.orientation, fields["orientation"], "xyzw")
        _set_xyz(msg.scale, fields["scale"])
        _set_xyz(msg.color, fields["color"], "rgba")
        points = []
        for xyz in fields.get("points", ()):
            point = point_factory()
            _set_xyz(point, xyz)
            points.append(point)
        msg.points = points
        msg.lifetime = duration_factory(float(fields["lifetime"]))
        out.append(msg)
    marker_array.markers = out
    return marker_array
