"""ROS-free conversions of the slam / localise node modes: transforms, odometry, poses, grids.

Like :mod:`laser_corners.ros.convert`, these work on any object with the message's fields
(rclpy classes, rosbags dataclasses, ``types.SimpleNamespace``), so they are tested without
ROS. Planar poses are ``(x, y, yaw)``; a 3x3 covariance over ``(x, y, yaw)`` sits in the
6x6 ``PoseWithCovariance.covariance`` at rows/columns ``(0, 1, 5)`` (x, y, rotation about z).
"""

from __future__ import annotations

import math
from array import array
from collections.abc import Mapping
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from laser_corners.errors import InvalidScanError
from laser_corners.io.occupancy import FREE_THRESH, OCCUPIED_THRESH, OccupancyGrid
from laser_corners.io.poses import yaw_from_quaternion
from laser_corners.ros.convert import stamp_to_sec

__all__ = [
    "COVARIANCE_INDEX",
    "fill_occupancy_grid",
    "fill_pose",
    "fill_pose_with_covariance",
    "fill_transform",
    "landmark_marker_fields",
    "odometry_of",
    "pose_with_covariance_of",
    "transform_of",
    "trinary",
]

COVARIANCE_INDEX = (0, 1, 5)
"""Rows/columns of x, y, yaw in a row-major 6x6 ROS pose covariance."""

Planar = tuple[float, float, float]


def _planar(position: Any, orientation: Any) -> Planar:
    yaw = yaw_from_quaternion(
        float(orientation.x), float(orientation.y), float(orientation.z), float(orientation.w)
    )
    return (float(position.x), float(position.y), yaw)


def transform_of(ts: Any) -> tuple[str, str, float, Planar]:
    """``(parent, child, stamp, (x, y, yaw))`` of a ``geometry_msgs/TransformStamped``.

    Raises
    ------
    InvalidScanError
        If a field is missing or not finite (named in the message).
    """
    try:
        t = ts.transform
        pose = _planar(t.translation, t.rotation)
        out = (str(ts.header.frame_id), str(ts.child_frame_id), stamp_to_sec(ts.header.stamp))
    except AttributeError as exc:
        raise InvalidScanError(f"not a geometry_msgs/TransformStamped: {exc}") from None
    if not all(math.isfinite(v) for v in pose):
        raise InvalidScanError(f"transform {out[0]} -> {out[1]}: not finite: {pose}")
    return (*out, pose)


def odometry_of(msg: Any) -> tuple[str, str, float, Planar]:
    """``(frame_id, child_frame_id, stamp, (x, y, yaw))`` of a ``nav_msgs/Odometry``.

    Raises
    ------
    InvalidScanError
        If a field is missing or the pose is not finite.
    """
    try:
        pose = _planar(msg.pose.pose.position, msg.pose.pose.orientation)
        out = (str(msg.header.frame_id), str(msg.child_frame_id), stamp_to_sec(msg.header.stamp))
    except AttributeError as exc:
        raise InvalidScanError(f"not a nav_msgs/Odometry: {exc}") from None
    if not all(math.isfinite(v) for v in pose):
        raise InvalidScanError(f"odometry {out[0]} -> {out[1]}: pose not finite: {pose}")
    return (*out, pose)


def pose_with_covariance_of(msg: Any) -> tuple[str, NDArray[np.float64], NDArray[np.float64]]:
    """``(frame_id, pose (3,), covariance (3, 3))`` of a ``PoseWithCovarianceStamped``
    (RViz's 2D Pose Estimate on ``/initialpose``).

    Raises
    ------
    InvalidScanError
        If a field is missing, the pose is not finite or the covariance has not 36 values.
    """
    try:
        pose = np.array(_planar(msg.pose.pose.position, msg.pose.pose.orientation))
        full = np.asarray(msg.pose.covariance, dtype=np.float64)
        frame = str(msg.header.frame_id)
    except (AttributeError, TypeError, ValueError) as exc:
        raise InvalidScanError(f"not a geometry_msgs/PoseWithCovarianceStamped: {exc}") from None
    if full.size != 36:
        raise InvalidScanError(f"pose covariance has {full.size} values, expected 36")
    if not np.all(np.isfinite(pose)):
        raise InvalidScanError(f"pose not finite: {pose.tolist()}")
    cov = full.reshape(6, 6)[np.ix_(COVARIANCE_INDEX, COVARIANCE_INDEX)]
    return frame, pose, cov


def _quaternion(yaw: float) -> tuple[float, float, float, float]:
    return (0.0, 0.0, math.sin(yaw / 2.0), math.cos(yaw / 2.0))


def fill_pose(pose_msg: Any, pose: ArrayLike) -> Any:
    """Set a ``geometry_msgs/Pose`` to the planar ``pose``."""
    x, y, yaw = (float(v) for v in np.asarray(pose, dtype=np.float64).reshape(3))
    pose_msg.position.x, pose_msg.position.y, pose_msg.position.z = x, y, 0.0
    o = pose_msg.orientation
    o.x, o.y, o.z, o.w = _quaternion(yaw)
    return pose_msg


def fill_transform(ts: Any, parent: str, child: str, pose: ArrayLike) -> Any:
    """Set a ``geometry_msgs/TransformStamped``'s frames and transform (not the stamp)."""
    x, y, yaw = (float(v) for v in np.asarray(pose, dtype=np.float64).reshape(3))
    ts.header.frame_id, ts.child_frame_id = parent, child
    t = ts.transform
    t.translation.x, t.translation.y, t.translation.z = x, y, 0.0
    t.rotation.x, t.rotation.y, t.rotation.z, t.rotation.w = _quaternion(yaw)
    return ts


def fill_pose_with_covariance(msg: Any, pose: ArrayLike, covariance: ArrayLike) -> Any:
    """Set a ``PoseWithCovarianceStamped``'s pose and covariance (not the header).

    The 3x3 ``(x, y, yaw)`` covariance goes to :data:`COVARIANCE_INDEX`; z, roll and pitch
    get zero variance.
    """
    fill_pose(msg.pose.pose, pose)
    full = np.zeros((6, 6))
    full[np.ix_(COVARIANCE_INDEX, COVARIANCE_INDEX)] = np.asarray(
        covariance, dtype=np.float64
    ).reshape(3, 3)
    msg.pose.covariance = full.reshape(36).tolist()
    return msg


def trinary(occupancy: ArrayLike) -> NDArray[np.int8]:
    """Cells ``-1`` / 0..100 as map_server publishes a map in trinary mode: occupied (100)
    above ``occupied_thresh`` 0.65, free (0) below ``free_thresh`` 0.196, else unknown (-1).

    The rule :func:`~laser_corners.io.occupancy.read_map` applies to a ``map.pgm``, so a map
    read from a map folder goes over unchanged and the live SLAM grid (probabilities) follows
    the same convention; planners (nav2's costmap) read only these three values.
    """
    occ = np.asarray(occupancy, dtype=np.int16)
    p = occ / 100.0
    out = np.full(occ.shape, -1, dtype=np.int8)
    out[(occ >= 0) & (p > OCCUPIED_THRESH)] = 100
    out[(occ >= 0) & (p < FREE_THRESH)] = 0
    return out


def fill_occupancy_grid(msg: Any, grid: OccupancyGrid) -> Any:
    """Set a ``nav_msgs/OccupancyGrid``'s ``info`` and ``data`` (not the header); the cells
    :func:`trinary`, as map_server publishes them.

    Both use row 0 = the bottom of the map (``y`` up), so the rows go over as they are.
    ``msg.info`` is the ``nav_msgs/MapMetaData`` to publish on ``map_metadata``.
    """
    rows, cols = grid.shape
    info = msg.info
    info.resolution = float(grid.resolution)
    info.width, info.height = int(cols), int(rows)
    fill_pose(info.origin, grid.origin)
    msg.data = array("b", np.ascontiguousarray(trinary(grid.occupancy)).tobytes())
    return msg


def landmark_marker_fields(
    xy: ArrayLike, ns: str = "landmarks", diameter: float = 0.15
) -> list[Mapping[str, Any]]:
    """One ``SPHERE_LIST`` marker (dict for :func:`~laser_corners.ros.convert.fill_marker_array`)
    with a sphere per landmark, after a ``DELETEALL``; empty when there are no landmarks."""
    points = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
    if not len(points):
        return []
    base = {
        "ns": ns,
        "position": (0.0, 0.0, 0.0),
        "orientation": (0.0, 0.0, 0.0, 1.0),
        "scale": (diameter, diameter, diameter),
        "color": (0.1, 0.8, 0.2, 1.0),
        "lifetime": 0.0,
    }
    return [
        {**base, "id": 0, "type": 7, "action": 3},  # DELETEALL
        {
            **base,
            "id": 0,
            "type": 7,  # SPHERE_LIST
            "action": 0,
            "points": [(float(x), float(y), 0.0) for x, y in points],
        },
    ]
