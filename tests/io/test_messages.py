"""Keypoints -> ROS message field values (shared by the bag writer and the ROS nodes)."""

from __future__ import annotations

import numpy as np

from conftest import random_keypoints
from laser_corners import Keypoints
from laser_corners.io.messages import (
    MARKER_ADD,
    MARKER_ARROW,
    MARKER_DELETEALL,
    keypoints_to_marker_fields,
    keypoints_to_pose_array_fields,
)
from laser_corners.io.poses import yaw_from_quaternion


def test_pose_array_fields_carry_position_and_yaw() -> None:
    kps = random_keypoints(7)
    fields = keypoints_to_pose_array_fields(kps)
    assert fields["positions"].shape == (7, 3) and fields["orientations"].shape == (7, 4)
    np.testing.assert_array_equal(fields["positions"][:, :2], kps.xy)
    assert not fields["positions"][:, 2].any()
    q = fields["orientations"]
    np.testing.assert_allclose(np.linalg.norm(q, axis=1), 1.0)
    yaws = [yaw_from_quaternion(*row) for row in q]
    np.testing.assert_allclose(np.cos(np.subtract(yaws, kps.orientation)), 1.0, atol=1e-12)


def test_marker_fields_clear_then_one_arrow_per_keypoint() -> None:
    kps = random_keypoints(4)
    markers = keypoints_to_marker_fields(kps, ns="c", lifetime=0.5)
    assert markers[0]["action"] == MARKER_DELETEALL
    arrows = markers[1:]
    assert [m["id"] for m in arrows] == [0, 1, 2, 3]
    assert all(m["type"] == MARKER_ARROW and m["action"] == MARKER_ADD for m in arrows)
    assert all(m["ns"] == "c" and m["lifetime"] == 0.5 for m in arrows)
    np.testing.assert_allclose([m["position"][:2] for m in arrows], kps.xy)
    assert keypoints_to_marker_fields(Keypoints.empty())[0]["action"] == MARKER_DELETEALL
    assert len(keypoints_to_marker_fields(Keypoints.empty())) == 1
