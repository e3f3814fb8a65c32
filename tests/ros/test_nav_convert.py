"""ROS-free conversions of the slam and localise node modes (:mod:`laser_corners.ros.nav_convert`)
on plain objects with the message fields: what is filled reads back the same, grids are
trinary as map_server's, bad messages are one line."""

from __future__ import annotations

import math
from types import SimpleNamespace as NS

import numpy as np
import pytest

from laser_corners.errors import InvalidScanError
from laser_corners.io.occupancy import OccupancyGrid
from laser_corners.ros.nav_convert import (
    COVARIANCE_INDEX,
    fill_occupancy_grid,
    fill_pose_with_covariance,
    fill_transform,
    landmark_marker_fields,
    odometry_of,
    pose_with_covariance_of,
    transform_of,
    trinary,
)


def vec(*names: str) -> NS:
    return NS(**dict.fromkeys(names, 0.0))


def pose_msg() -> NS:
    return NS(position=vec("x", "y", "z"), orientation=vec("x", "y", "z", "w"))


def header(stamp: float = 0.0, frame: str = "") -> NS:
    sec = int(stamp)
    return NS(stamp=NS(sec=sec, nanosec=round((stamp - sec) * 1e9)), frame_id=frame)


def test_a_filled_transform_reads_back() -> None:
    ts = NS(
        header=header(12.25),
        child_frame_id="",
        transform=NS(translation=vec("x", "y", "z"), rotation=vec("x", "y", "z", "w")),
    )
    fill_transform(ts, "map", "odom", (1.5, -2.0, 3.0))
    parent, child, stamp, pose = transform_of(ts)
    assert (parent, child, stamp) == ("map", "odom", 12.25)
    assert pose == pytest.approx((1.5, -2.0, 3.0))
    assert ts.transform.translation.z == 0.0 and ts.transform.rotation.x == 0.0


def test_odometry_of_reads_a_planar_pose() -> None:
    msg = NS(header=header(3.5, "odom"), child_frame_id="base_link", pose=NS(pose=pose_msg()))
    msg.pose.pose.position.x = 2.0
    msg.pose.pose.orientation.z, msg.pose.pose.orientation.w = math.sin(0.4), math.cos(0.4)
    assert odometry_of(msg) == ("odom", "base_link", 3.5, pytest.approx((2.0, 0.0, 0.8)))
    msg.pose.pose.position.y = math.nan
    with pytest.raises(InvalidScanError, match="odometry odom -> base_link: pose not finite"):
        odometry_of(msg)
    with pytest.raises(InvalidScanError, match="not a nav_msgs/Odometry"):
        odometry_of(NS(header=header()))


def test_pose_with_covariance_round_trip() -> None:
    msg = NS(header=header(0.0, "map"), pose=NS(pose=pose_msg(), covariance=[0.0] * 36))
    cov = np.array([[0.25, 0.01, 0.0], [0.01, 0.36, 0.02], [0.0, 0.02, 0.07]])
    fill_pose_with_covariance(msg, (4.0, 5.0, -1.0), cov)
    frame, pose, read = pose_with_covariance_of(msg)
    assert frame == "map"
    np.testing.assert_allclose(pose, (4.0, 5.0, -1.0))
    np.testing.assert_allclose(read, cov)
    full = np.array(msg.pose.covariance).reshape(6, 6)
    assert full[5, 5] == 0.07 and full[2, 2] == 0.0 and COVARIANCE_INDEX == (0, 1, 5)
    msg.pose.covariance = [0.0] * 9
    with pytest.raises(InvalidScanError, match="9 values, expected 36"):
        pose_with_covariance_of(msg)


def test_trinary_follows_map_servers_thresholds() -> None:
    cells = np.array([-1, 0, 19, 20, 50, 65, 66, 100])
    assert trinary(cells).tolist() == [-1, 0, 0, -1, -1, -1, 100, 100]
    assert trinary(cells).dtype == np.int8


def test_fill_occupancy_grid_keeps_rows_and_the_origin() -> None:
    occupancy = np.array([[0, 100, -1], [70, 10, 50]], dtype=np.int8)
    grid = OccupancyGrid(occupancy, 0.05, (-1.0, 2.0, 0.0))
    msg = NS(info=NS(resolution=0.0, width=0, height=0, origin=pose_msg()), data=None)
    fill_occupancy_grid(msg, grid)
    assert (msg.info.width, msg.info.height, msg.info.resolution) == (3, 2, 0.05)
    assert (msg.info.origin.position.x, msg.info.origin.position.y) == (-1.0, 2.0)
    assert list(msg.data) == [0, 100, -1, 100, 0, -1]  # row 0 first, as the grid


def test_landmark_markers() -> None:
    assert landmark_marker_fields(np.zeros((0, 2))) == []
    clear, spheres = landmark_marker_fields([[1.0, 2.0], [3.0, 4.0]], diameter=0.2)
    assert (clear["action"], spheres["action"], spheres["type"]) == (3, 0, 7)
    assert spheres["points"] == [(1.0, 2.0, 0.0), (3.0, 4.0, 0.0)]
    assert spheres["scale"] == (0.2, 0.2, 0.2)
