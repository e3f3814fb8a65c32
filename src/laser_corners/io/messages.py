"""Keypoints -> the field values of ROS messages, as plain Python/numpy data (no ROS import).

The bag writer (:mod:`laser_corners.io.bagwriter`) and the ROS nodes build their
``geometry_msgs/PoseArray`` and ``visualization_msgs/MarkerArray`` from these values, so both
publish the same thing. Headers are not handled here: copy the scan's header (stamp and frame).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from laser_corners.keypoints import Keypoints

__all__ = [
    "MARKER_ADD",
    "MARKER_ARROW",
    "MARKER_DELETEALL",
    "keypoints_to_marker_fields",
    "keypoints_to_pose_array_fields",
    "yaw_quaternions",
]

MARKER_ARROW = 0
"""``visualization_msgs/Marker.ARROW``."""
MARKER_ADD = 0
"""``visualization_msgs/Marker.ADD``."""
MARKER_DELETEALL = 3
"""``visualization_msgs/Marker.DELETEALL``."""

KEYPOINT_COLOR = (0.9, 0.1, 0.1, 1.0)
"""RGBA of keypoint markers."""
ARROW_SCALE = (0.3, 0.04, 0.04)
"""Arrow length, shaft and head diameters of keypoint markers, metres."""


def yaw_quaternions(yaw: NDArray[np.float64]) -> NDArray[np.float64]:
    """Quaternions ``(x, y, z, w)`` of rotations by ``yaw`` (radians) about z, shape (M, 4)."""
    yaw = np.asarray(yaw, dtype=np.float64).reshape(-1)
    q = np.zeros((yaw.shape[0], 4))
    q[:, 2] = np.sin(yaw / 2.0)
    q[:, 3] = np.cos(yaw / 2.0)
    return q


def keypoints_to_pose_array_fields(kps: Keypoints) -> dict[str, NDArray[np.float64]]:
    """Field values of a ``geometry_msgs/PoseArray`` holding the keypoints.

    Parameters
    ----------
    kps : Keypoints
        Keypoints in the frame of the header the message will carry.

    Returns
    -------
    dict
        ``positions``: (M, 3) x, y, z (z = 0); ``orientations``: (M, 4) quaternions x, y, z, w
        of the keypoint orientation (bisector direction) as a yaw.
    """
    positions = np.zeros((len(kps), 3))
    positions[:, :2] = kps.xy
    return {"positions": positions, "orientations": yaw_quaternions(kps.orientation)}


def keypoints_to_marker_fields(
    kps: Keypoints, ns: str = "corners", lifetime: float = 0.0
) -> list[dict[str, Any]]:
    """Field values of the markers of a ``visualization_msgs/MarkerArray`` for the keypoints.

    The first marker is a ``DELETEALL`` (clears the previous scan's arrows), then one red
    ``ARROW`` per keypoint at its position, pointing along its orientation (ids 0..M-1).

    Parameters
    ----------
    kps : Keypoints
        Keypoints in the frame of the header the message will carry.
    ns : str
        Marker namespace.
    lifetime : float
        Marker lifetime in seconds (0: forever).

    Returns
    -------
    list of dict
        One dict per marker with keys ``ns, id, type, action, position (x, y, z),
        orientation (x, y, z, w), scale (x, y, z), color (r, g, b, a), lifetime`` (seconds).
    """
    markers: list[dict[str, Any]] = [
        {
            "ns": ns,
            "id": 0,
            "type": MARKER_ARROW,
            "action": MARKER_DELETEALL,
            "position": (0.0, 0.0, 0.0),
            "orientation": (0.0, 0.0, 0.0, 1.0),
            "scale": (0.0, 0.0, 0.0),
            "color": (0.0, 0.0, 0.0, 0.0),
            "lifetime": 0.0,
        }
    ]
    quaternions = yaw_quaternions(kps.orientation)
    for i in range(len(kps)):
        markers.append(
            {
                "ns": ns,
                "id": i,
                "type": MARKER_ARROW,
                "action": MARKER_ADD,
                "position": (float(kps.xy[i, 0]), float(kps.xy[i, 1]), 0.0),
                "orientation": tuple(float(v) for v in quaternions[i]),
                "scale": ARROW_SCALE,
                "color": KEYPOINT_COLOR,
                "lifetime": float(lifetime),
            }
        )
    return markers
