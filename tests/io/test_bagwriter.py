"""Keypoint bags (ROS 1 .bag, ROS 2 .mcap) read back with rosbags; ROS 2 bags as input."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
from rosbags.highlevel import AnyReader
from rosbags.rosbag2 import StoragePlugin, Writer

from conftest import real_file, run_until_killed
from laser_corners import CornerDetector, InputError, LaserScan
from laser_corners.errors import OutputError
from laser_corners.io import BagSource, WriterSummary, open_keypoint_writer, open_scans
from laser_corners.io.messages import (
    MARKER_DELETEALL,
)
from laser_corners.pipeline import detect_file, detect_recording
from sim_drives import SCAN_TYPE, BagMessages


def test_fr079_keypoint_bag_reads_back_with_the_scan_stamps(tmp_path: Path) -> None:
    bag = real_file("fr079.bag")
    source = open_scans(bag)
    out = tmp_path / "fr079_corners.bag"
    detector = CornerDetector()
    writer = open_keypoint_writer(out, source, with_map=True)
    summary = detect_recording(source, detector, writer)
    assert summary.n_scans == 4934 and not summary.interrupted
    with pytest.raises(OutputError, match="the output is the input"):
        open_keypoint_writer(bag, source, with_map=True)

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
    bag = BagMessages(ros2=True)
    string_type = bag.t["std_msgs/msg/String"]
    with Writer(path, version=9, storage_plugin=storage) as writer:
        scan_conn = writer.add_connection("/base_scan", SCAN_TYPE, typestore=bag.store)
        text_conn = writer.add_connection("/chatter", string_type.__msgtype__, typestore=bag.store)
        for scan in scans:
            ns = round(scan.stamp * 1e9)
            writer.write(
                scan_conn, ns, bag.ser(bag.scan(scan.stamp, scan, "base_laser"), SCAN_TYPE)
            )
            text = bag.ser(string_type(data="hello"), string_type.__msgtype__)
            writer.write(text_conn, ns, text)


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
    with pytest.raises(OutputError, match=r"copied to a \.mcap output"):
        open_keypoint_writer(tmp_path / "corners.bag", source, with_map=False)
    summary = detect_recording(
        source, CornerDetector(), open_keypoint_writer(out, source, with_map=False)
    )
    with AnyReader([out]) as reader:
        counts = {c.topic: c.msgcount for c in reader.connections}
        assert counts == {
            "/base_scan": 40,
            "/chatter": 40,
            "/base_scan_corners": 40,
            "/base_scan_corner_markers": 40,
        }
        conns = [c for c in reader.connections if c.topic == "/base_scan_corners"]
        poses = [
            reader.deserialize(raw, c.msgtype) for c, _, raw in reader.messages(connections=conns)
        ]
    assert [m.header.stamp.sec * 10**9 + m.header.stamp.nanosec for m in poses] == source.stamps_ns
    assert sum(len(m.poses) for m in poses) == summary.n_keypoints
    # written in a temporary folder, its .mcap file moved out when complete
    assert out.is_file() and open_scans(out).kind == "mcap"
    assert not list(tmp_path.glob("*.partial*"))


def test_mcap_output_is_one_file_and_a_second_run_replaces_it(tmp_path: Path) -> None:
    """``-o r.mcap`` writes the file r.mcap (not a folder r.mcap/ holding r.mcap.mcap), and
    the same command again replaces it, as the table outputs are replaced."""
    scans = list(open_scans(real_file("fr079-corrected.clf.gz")))[:30]
    bag = tmp_path / "in.mcap"
    _write_ros2_mcap(tmp_path / "ros2bag", scans)
    next((tmp_path / "ros2bag").glob("*.mcap")).rename(bag)
    out = tmp_path / "r.mcap"
    for run in range(2):
        result = detect_file(bag, out)
        assert result.summary.n_scans == 30
        assert out.is_file(), f"run {run}: {out} is not a file"
        assert sorted(p.name for p in tmp_path.iterdir()) == [
            "in.mcap",
            "r.mcap",
            "r.mcap.params.yaml",
            "ros2bag",
        ]
        with AnyReader([out]) as reader:
            counts = {c.topic: c.msgcount for c in reader.connections}
        assert counts == {
            "/base_scan": 30,
            "/chatter": 30,
            "/base_scan_corners": 30,
            "/base_scan_corner_markers": 30,
        }
        assert len(list(open_scans(out))) == 30


def test_ros2_sqlite_bag_is_read(tmp_path: Path) -> None:
    scans = list(open_scans(real_file("fr079-corrected.clf.gz")))[:10]
    bag = tmp_path / "sqlite_bag"
    _write_ros2_mcap(bag, scans, StoragePlugin.SQLITE3)
    source = open_scans(bag)
    assert source.kind == "ros2" and source.n_scans == 10
    back = list(source)
    assert [round(s.stamp, 6) for s in back] == [round(s.stamp, 6) for s in scans]
    np.testing.assert_allclose(back[3].ranges, scans[3].ranges.astype(np.float32))


def test_interrupted_run_keeps_a_complete_bag_with_the_keypoints_so_far(tmp_path: Path) -> None:
    """Ctrl-C after 250 scans: the bag is finished (rest of the input copied, index written),
    renamed, and holds the keypoint messages of the 250 scans processed."""

    class Interrupting(BagSource):
        def _scans(self) -> Iterator[LaserScan]:
            for index, scan in enumerate(super()._scans()):
                if index == 250:
                    raise KeyboardInterrupt
                yield scan

    bag = real_file("fr079.bag")
    source = Interrupting(bag, "ros1")
    out = tmp_path / "k.bag"
    writer = open_keypoint_writer(out, source, with_map=True)
    summary = detect_recording(source, CornerDetector(), writer)
    assert summary.interrupted and summary.n_scans == 250
    assert writer.summary() == WriterSummary(out, 250, summary.n_keypoints, True)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["k.bag"]
    with AnyReader([bag]) as original:
        counts = {c.topic: c.msgcount for c in original.connections}
    with AnyReader([out]) as reader:
        got = {c.topic: c.msgcount for c in reader.connections}
        conns = [c for c in reader.connections if c.topic == "/scan_corners"]
        n_poses = sum(
            len(reader.deserialize(raw, c.msgtype).poses)
            for c, _, raw in reader.messages(connections=conns)
        )
    assert got == {**counts, "/scan_corners": 250, "/scan_corner_markers": 250}
    assert n_poses == summary.n_keypoints > 0


_KILLED_BAG_WRITER = """
import sys, time
from pathlib import Path
sys.path.insert(0, sys.argv[3])
from conftest import random_keypoints
from laser_corners.io import BagSource, WriterSummary, open_keypoint_writer, open_scans
source = open_scans(sys.argv[1])
writer = open_keypoint_writer(Path(sys.argv[2]), source, with_map=True, flush_every=10)
for index, scan in enumerate(source):
    writer.write(index, scan, random_keypoints(2, index))
    if index == 99:
        break
print(writer.summary().path, flush=True)
time.sleep(120)
"""


def test_a_killed_bag_writer_leaves_a_readable_temporary_bag(tmp_path: Path) -> None:
    """SIGKILL after 100 scans: no bag under the final name; the temporary bag has no index,
    but its chunks (written every 10 scans) hold the 100 scans' keypoint messages."""
    out = tmp_path / "k.bag"
    args = (str(real_file("fr079.bag")), str(out), str(Path(__file__).parents[1]))
    temporary = Path(run_until_killed(_KILLED_BAG_WRITER, *args))
    assert not out.exists()
    assert [p.name for p in tmp_path.iterdir()] == [temporary.name]
    assert temporary.name.startswith("k.") and temporary.name.endswith(".partial.bag")
    source = open_scans(temporary)  # read from its chunks
    assert source.from_chunks  # type: ignore[attr-defined]
    assert source.topics["/scan_corners"] == ("geometry_msgs/msg/PoseArray", 100)  # type: ignore[attr-defined]
    assert source.topics["/scan_corner_markers"][1] == 100  # type: ignore[attr-defined]
    assert len(list(source)) == source.n_scans >= 100
