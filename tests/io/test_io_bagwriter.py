"""Keypoint bags (ROS 1 .bag, ROS 2 .mcap) read back with rosbags; ROS 2 bags as input."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from rosbags.highlevel import AnyReader
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.typesys import Stores, get_typestore

from conftest import real_file
from laser_corners import CornerDetector, InputError, LaserScan
from laser_corners.errors import OutputError
from laser_corners.io import open_keypoint_writer, open_scans
from laser_corners.io.messages import (
    MARKER_DELETEALL,
)
from laser_corners.io.run import detect_recording


def test_fr079_keypoint_bag_reads_back_with_the_scan_stamps(tmp_path: Path) -> None:
    bag = real_file("fr079.bag")
    source = open_scans(bag)
    out = tmp_path / "fr079_corners.bag"
    detector = CornerDetector()
    writer = open_keypoint_writer(out, source, with_map=True)
    summary = detect_recording(source, detector, writer)
    assert summary.n_scans == 4934 and not summary.interrupted
    with pytest.raises(OutputError, match="exists already"):
        open_keypoint_writer(out, source, with_map=True)

    with AnyReader([bag]) as original:
        counts = {c.topic: c.msgcount for c in original.connections}
        scan_conn = [c for c in original.connections if c.topic == "/scan"]
        scan_headers = [
            (m := original.deserialize(raw, c.msgtype)).header.stamp.sec * 10**9
            + m.header.stamp.nanosec
            for c, _, raw in original.messages(connections=scan_conn)
        ]
    with AnyReader([out]) as reader:
        got = {c.topic: c.msgcount for c in reader.connections}
        assert got == {**counts, "/scan_corners": 4934, "/scan_corner_markers": 4934}
        types = {c.topic: c.msgtype for c in reader.connections}
        assert types["/scan_corners"] == "geometry_msgs/msg/PoseArray"
        assert types["/scan_corner_markers"] == "visualization_msgs/msg/MarkerArray"
        stamps, frames, n_poses, n_markers = [], set(), 0, 0
        conns = [c for c in reader.connections if c.topic.startswith("/scan_corner")]
        for c, _, raw in reader.messages(connections=conns):
            msg = reader.deserialize(raw, c.msgtype)
            if c.topic == "/scan_corners":
                stamps.append(msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec)
                frames.add(msg.header.frame_id)
                n_poses += len(msg.poses)
            else:
                n_markers += len(msg.markers) - 1  # minus the DELETEALL
                assert msg.markers[0].action == MARKER_DELETEALL
    assert stamps == scan_headers
    assert frames == {"laser"}
    assert n_poses == n_markers == summary.n_keypoints > 0


def _write_ros2_mcap(
    path: Path, scans: list[LaserScan], storage: StoragePlugin = StoragePlugin.MCAP
) -> None:
    """A tiny ROS 2 bag with a LaserScan topic and a non-scan topic (as evo does)."""
    store = get_typestore(Stores.ROS2_HUMBLE)
    scan_type = store.types["sensor_msgs/msg/LaserScan"]
    header_type = store.types["std_msgs/msg/Header"]
    time_type = store.types["builtin_interfaces/msg/Time"]
    string_type = store.types["std_msgs/msg/String"]
    with Writer(path, version=9, storage_plugin=storage) as writer:
        scan_conn = writer.add_connection("/base_scan", scan_type.__msgtype__, typestore=store)
        text_conn = writer.add_connection("/chatter", string_type.__msgtype__, typestore=store)
        for scan in scans:
            ns = round(scan.stamp * 1e9)
            header = header_type(
                stamp=time_type(sec=ns // 10**9, nanosec=ns % 10**9), frame_id="base_laser"
            )
            msg = scan_type(
                header=header, angle_min=scan.angle_min,
                angle_max=scan.angle_min + scan.angle_increment * (scan.n_beams - 1),
                angle_increment=scan.angle_increment, time_increment=0.0, scan_time=0.0,
                range_min=scan.range_min, range_max=scan.range_max,
                ranges=scan.ranges.astype(np.float32), intensities=np.zeros(0, np.float32),
            )  # fmt: skip
            writer.write(scan_conn, ns, store.serialize_cdr(msg, scan_type.__msgtype__))
            text = string_type(data="hello")
            writer.write(text_conn, ns, store.serialize_cdr(text, string_type.__msgtype__))


def test_ros2_mcap_in_and_keypoint_mcap_out(tmp_path: Path) -> None:
    scans = list(open_scans(real_file("fr079-corrected.clf.gz")))[:40]
    bag = tmp_path / "ros2bag"
    _write_ros2_mcap(bag, scans)
    source = open_scans(bag)
    assert source.kind == "mcap" and source.topic == "/base_scan"
    with pytest.raises(InputError, match="std_msgs/msg/String, not a sensor_msgs/msg/LaserScan"):
        open_scans(bag, topic="/chatter")
    back = list(source)
    assert len(back) == source.n_scans == 40
    for a, b in zip(scans, back, strict=True):
        np.testing.assert_allclose(b.ranges, a.ranges.astype(np.float32))
        assert b.stamp == pytest.approx(a.stamp, abs=1e-6) and b.frame_id == "base_laser"
        assert b.pose is None
    bare = next(bag.glob("*.mcap"))
    assert open_scans(bare).kind == "mcap" and len(list(open_scans(bare))) == 40
    out = tmp_path / "corners.mcap"
    with pytest.raises(InputError, match=r"copied to a \.mcap output"):
        open_keypoint_writer(tmp_path / "corners.bag", source, with_map=False)
    summary = detect_recording(
        source, CornerDetector(), open_keypoint_writer(out, source, with_map=False)
    )
    with AnyReader([out]) as reader:
        counts = {c.topic: c.msgcount for c in reader.connections}
        assert counts == {
            "/base_scan": 40, "/chatter": 40, "/base_scan_corners": 40,
            "/base_scan_corner_markers": 40,
        }  # fmt: skip
        conns = [c for c in reader.connections if c.topic == "/base_scan_corners"]
        poses = [
            reader.deserialize(raw, c.msgtype) for c, _, raw in reader.messages(connections=conns)
        ]
    assert [m.header.stamp.sec * 10**9 + m.header.stamp.nanosec for m in poses] == source.stamps_ns
    assert sum(len(m.poses) for m in poses) == summary.n_keypoints


def test_ros2_sqlite_bag_is_read(tmp_path: Path) -> None:
    scans = list(open_scans(real_file("fr079-corrected.clf.gz")))[:10]
    bag = tmp_path / "sqlite_bag"
    _write_ros2_mcap(bag, scans, StoragePlugin.SQLITE3)
    source = open_scans(bag)
    assert source.kind == "ros2" and source.n_scans == 10
    back = list(source)
    assert [round(s.stamp, 6) for s in back] == [round(s.stamp, 6) for s in scans]
    np.testing.assert_allclose(back[3].ranges, scans[3].ranges.astype(np.float32))
