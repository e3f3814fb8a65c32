"""ROS-free message conversions of the ROS nodes (:mod:`laser_corners.ros.convert`), and the
ROS 1/ROS 2 package files (the node parameters and per-scan core: test_node_core.py).

Messages are plain ``SimpleNamespace`` objects with the ROS fields (ROS 1 ``secs/nsecs`` and
ROS 2 ``sec/nanosec`` stamps); where Debian's ROS 1 message classes are importable, the filled
messages are also serialized and read back with genpy to check the field types.
"""

from __future__ import annotations

import io
import math
import os
import stat
import sys
import xml.etree.ElementTree as ET
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from ros_helpers import isolated_message_packages, scan_msg, skip_or_fail, stamped_corner_scan
from typer.testing import CliRunner

from laser_corners import LaserScan
from laser_corners.cli import app
from laser_corners.errors import InvalidScanError, LaserCornersError
from laser_corners.io.messages import keypoints_to_marker_fields
from laser_corners.keypoints import Keypoints
from laser_corners.ros.convert import (
    fill_marker_array,
    fill_pose_array,
    scan_from_msg,
    seconds_to_sec_nanosec,
    stamp_to_sec,
)

REPO_ROOT = Path(__file__).resolve().parents[2]
ROS_DIR = REPO_ROOT / "src" / "laser_corners" / "ros"


# ------------------------------------------------------------------ fake ROS messages
def _vec(*names: str) -> SimpleNamespace:
    return SimpleNamespace(**dict.fromkeys(names, 0.0))


def _pose() -> SimpleNamespace:
    return SimpleNamespace(position=_vec("x", "y", "z"), orientation=_vec("x", "y", "z", "w"))


def _marker() -> SimpleNamespace:
    return SimpleNamespace(
        header=None,
        ns="",
        id=0,
        type=0,
        action=0,
        pose=_pose(),
        scale=_vec("x", "y", "z"),
        color=_vec("r", "g", "b", "a"),
        points=[],
        lifetime=None,
    )


@pytest.fixture(scope="module")
def sim_scan() -> LaserScan:
    return stamped_corner_scan()


# ------------------------------------------------------------------ message -> scan
@pytest.mark.parametrize("ros2", [False, True])
def test_scan_from_msg_copies_fields_and_ignores_angle_max(sim_scan: LaserScan, ros2: bool) -> None:
    msg = scan_msg(sim_scan, ros2=ros2, angle_max=99.0)  # a wrong angle_max must not matter
    scan = scan_from_msg(msg)
    assert scan.n_beams == sim_scan.n_beams
    np.testing.assert_array_equal(scan.ranges, sim_scan.ranges)
    np.testing.assert_allclose(scan.angles, sim_scan.angles, rtol=0, atol=1e-12)
    assert scan.stamp == pytest.approx(1234.5, abs=1e-9)
    assert scan.frame_id == "laser"


def test_scan_from_msg_rejects_malformed_messages(sim_scan: LaserScan) -> None:
    bad_increment = scan_msg(sim_scan)
    bad_increment.angle_increment = 0.0
    with pytest.raises(InvalidScanError, match="angle_increment"):
        scan_from_msg(bad_increment)
    no_ranges = scan_msg(sim_scan)
    del no_ranges.ranges
    with pytest.raises(InvalidScanError, match="ranges"):
        scan_from_msg(no_ranges)
    text_ranges = scan_msg(sim_scan)
    text_ranges.ranges = ["a", "b"]
    with pytest.raises(InvalidScanError, match="ranges"):
        scan_from_msg(text_ranges)
    with pytest.raises(InvalidScanError, match="stamp"):
        stamp_to_sec(object())


def test_stamp_to_sec_variants() -> None:
    assert stamp_to_sec(SimpleNamespace(secs=3, nsecs=500_000_000)) == pytest.approx(3.5)
    assert stamp_to_sec(SimpleNamespace(sec=3, nanosec=250_000_000)) == pytest.approx(3.25)
    assert stamp_to_sec(SimpleNamespace(to_sec=lambda: 7.0)) == 7.0
    assert stamp_to_sec(2) == 2.0


@given(st.floats(min_value=0.0, max_value=1e6, allow_nan=False))
def test_seconds_to_sec_nanosec_splits_exactly(seconds: float) -> None:
    sec, nanosec = seconds_to_sec_nanosec(seconds)
    assert 0 <= nanosec < 1_000_000_000
    assert abs(sec + nanosec * 1e-9 - seconds) <= 1e-9 * max(1.0, seconds)


# ------------------------------------------------------------------ keypoints -> messages
def _keypoints() -> Keypoints:
    xy = np.array([[1.0, 2.0], [-0.5, 3.25], [4.0, -1.0]])
    orientation = np.array([0.3, -2.5, math.pi])
    m = len(xy)
    return Keypoints(
        xy,
        np.arange(m),
        np.full(m, 90.0),
        orientation,
        np.full(m, 3),
        np.full(m, 0.001),
        np.ones(m, dtype=np.int64),
        stamp=5.0,
        frame_id="laser",
    )


def test_fill_pose_array_positions_and_yaw() -> None:
    kps = _keypoints()
    msg = fill_pose_array(SimpleNamespace(header=None, poses=None), _pose, kps)
    assert len(msg.poses) == len(kps)
    for pose, (x, y), theta in zip(msg.poses, kps.xy, kps.orientation, strict=True):
        assert (pose.position.x, pose.position.y, pose.position.z) == (x, y, 0.0)
        q = pose.orientation
        assert q.x == 0.0 and q.y == 0.0
        assert q.z**2 + q.w**2 == pytest.approx(1.0)
        yaw = 2.0 * math.atan2(q.z, q.w)
        assert math.cos(yaw - theta) == pytest.approx(1.0)
    empty = fill_pose_array(SimpleNamespace(poses=None), _pose, Keypoints.empty())
    assert empty.poses == []


def test_fill_marker_array_copies_header_and_fields() -> None:
    kps = _keypoints()
    header = SimpleNamespace(stamp=SimpleNamespace(secs=5, nsecs=0), frame_id="laser")
    fields = keypoints_to_marker_fields(kps, ns="test_ns", lifetime=0.5)
    fields[-1]["points"] = [(1.0, 2.0, 0.0)]
    out = fill_marker_array(
        SimpleNamespace(markers=None),
        _marker,
        lambda: _vec("x", "y", "z"),
        lambda s: ("duration", s),
        header,
        fields,
    )
    assert len(out.markers) == len(fields)
    for marker, f in zip(out.markers, fields, strict=True):
        assert marker.header is header
        assert (marker.ns, marker.id, marker.type, marker.action) == (
            f["ns"],
            f["id"],
            f["type"],
            f["action"],
        )
        assert (marker.pose.position.x, marker.pose.position.y) == f["position"][:2]
        assert (marker.color.r, marker.color.a) == (f["color"][0], f["color"][3])
        assert marker.lifetime == ("duration", f["lifetime"])
    assert [(p.x, p.y) for p in out.markers[-1].points] == [(1.0, 2.0)]
    assert out.markers[0].points == []


def test_filled_messages_serialize_with_ros1_classes() -> None:
    """genpy type-checks every field when serializing: floats, ints, strings, durations."""
    with isolated_message_packages():
        _check_ros1_serialization()


def _check_ros1_serialization() -> None:
    from laser_corners.ros.ros1_node import import_rospy

    try:
        rospy = import_rospy()
    except LaserCornersError as exc:
        pytest.skip(str(exc))
    from geometry_msgs.msg import Point, Pose, PoseArray
    from visualization_msgs.msg import Marker, MarkerArray

    kps = _keypoints()
    poses = fill_pose_array(PoseArray(), Pose, kps)
    poses.header.stamp = rospy.Time(5, 7)
    poses.header.frame_id = "laser"
    buf = io.BytesIO()
    poses.serialize(buf)
    back = PoseArray().deserialize(buf.getvalue())
    got = np.array([[p.position.x, p.position.y] for p in back.poses])
    np.testing.assert_array_equal(got, kps.xy)
    assert back.header.frame_id == "laser" and back.header.stamp == rospy.Time(5, 7)

    markers = fill_marker_array(
        MarkerArray(),
        Marker,
        Point,
        rospy.Duration.from_sec,
        poses.header,
        keypoints_to_marker_fields(kps, "c", 0.25),
    )
    buf = io.BytesIO()
    markers.serialize(buf)
    back_markers = MarkerArray().deserialize(buf.getvalue())
    assert len(back_markers.markers) == len(markers.markers)
    assert back_markers.markers[1].lifetime.to_sec() == pytest.approx(0.25)
    assert all(m.header.frame_id == "laser" for m in back_markers.markers)


# ------------------------------------------------------------------ node parameters


# ------------------------------------------------------------------ per-scan core


# ------------------------------------------------------------------ ROS 2 adapter, packaging


def test_filled_messages_serialize_with_ros2_classes() -> None:
    """rclpy's message classes check every field's type; CDR serialization round trip."""
    with isolated_message_packages():
        _check_ros2_serialization()


def _check_ros2_serialization() -> None:
    from laser_corners.ros.ros2_node import import_rclpy

    try:
        import_rclpy()
    except LaserCornersError as exc:
        skip_or_fail(str(exc))
    from builtin_interfaces.msg import Duration
    from geometry_msgs.msg import Point, Pose, PoseArray
    from rclpy.serialization import deserialize_message, serialize_message
    from visualization_msgs.msg import Marker, MarkerArray

    kps = _keypoints()
    poses = fill_pose_array(PoseArray(), Pose, kps)
    poses.header.stamp.sec, poses.header.stamp.nanosec = 5, 7
    poses.header.frame_id = "laser"
    back = deserialize_message(serialize_message(poses), PoseArray)
    np.testing.assert_array_equal([[p.position.x, p.position.y] for p in back.poses], kps.xy)
    assert back.header == poses.header

    def duration(seconds: float) -> Duration:
        sec, nanosec = seconds_to_sec_nanosec(seconds)
        return Duration(sec=sec, nanosec=nanosec)

    fields = keypoints_to_marker_fields(kps, "c", 0.25)
    markers = fill_marker_array(MarkerArray(), Marker, Point, duration, poses.header, fields)
    back_markers = deserialize_message(serialize_message(markers), MarkerArray)
    assert len(back_markers.markers) == len(fields)
    assert back_markers.markers[1].lifetime == Duration(sec=0, nanosec=250_000_000)
    assert all(m.header.frame_id == "laser" for m in back_markers.markers)


def test_ros2_main_without_rclpy_exits_with_hint(
    capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """rclpy missing (None in sys.modules makes its import fail): one line, exit code 2."""
    from laser_corners.ros.ros2_node import main

    for name in ("rclpy", "geometry_msgs", "sensor_msgs", "visualization_msgs"):
        monkeypatch.setitem(sys.modules, name, None)
    assert main(["--ros-args", "-r", "scan:=/front/scan"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "pip install 'laser-corners[ros2]'" in err[0], err


def test_ros2_package_points_at_the_node() -> None:
    tree = ET.parse(REPO_ROOT / "ros2" / "package.xml")
    assert tree.findtext("name") == "laser_corners_ros"
    assert tree.findtext("export/build_type") == "ament_python"
    setup = (REPO_ROOT / "ros2" / "setup.py").read_text()
    assert "laser_corners_node = laser_corners.ros.ros2_node:main" in setup
    assert (REPO_ROOT / "ros2" / "resource" / "laser_corners_ros").is_file()


def test_ros1_launch_file_and_package_folder() -> None:
    result = CliRunner().invoke(app, ["ros1", "--package-path"])
    assert result.exit_code == 0, result.output
    folder = Path(result.output.strip())
    assert folder.resolve() == ROS_DIR.resolve()
    assert ET.parse(folder / "package.xml").findtext("name") == "laser_corners"
    launch = ET.parse(folder / "launch" / "laser_corners.launch").getroot()
    (node,) = launch.iter("node")
    assert node.get("pkg") == "laser_corners"
    script = folder / "nodes" / node.get("type", "")
    assert script.is_file()
    assert os.stat(script).st_mode & stat.S_IXUSR, "roslaunch runs only executable nodes"
