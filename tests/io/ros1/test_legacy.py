"""Bags recorded before ROS Electric: ``roslib/Header`` (and ``roslib/Clock``) in their types.

The bags are written here the way such bags look: the LaserScan connection's message
definition says ``Header header`` and holds a ``MSG: roslib/Header`` section, a ``/clock``
connection has the type ``roslib/Clock``; the MD5 sums are today's (the definitions did not
change, only their package).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from rosbags.highlevel import AnyReader
from rosbags.rosbag1 import Writer
from rosbags.typesys import Stores, get_typestore

from laser_corners import CornerDetector
from laser_corners.io import open_keypoint_writer, open_scans
from laser_corners.io.ros1.legacy import modern_names
from laser_corners.io.rosbag import BagSource
from laser_corners.pipeline import detect_recording

N_SCANS = 30
STORE = get_typestore(Stores.ROS1_NOETIC)


def _old_definition(msgtype: str) -> tuple[str, str]:
    """The definition and MD5 of ``msgtype`` as a pre-Electric recorder wrote them."""
    text, md5 = STORE.generate_msgdef(msgtype)
    text = text.replace("std_msgs/Header header", "Header header")
    return text.replace("MSG: std_msgs/Header", "MSG: roslib/Header"), md5


def _write_old_bag(path: Path) -> list[int]:
    """A bag of ``N_SCANS`` LaserScans (a corner in view) and ``/clock``; the scan stamps."""
    types = STORE.types
    scan_def, scan_md5 = _old_definition("sensor_msgs/msg/LaserScan")
    assert "MSG: roslib/Header" in scan_def and "std_msgs" not in scan_def
    clock_def, clock_md5 = STORE.generate_msgdef("rosgraph_msgs/msg/Clock")
    angles = np.linspace(-1.5, 1.5, 301)
    stamps = []
    with Writer(path) as writer:
        scan = writer.add_connection(
            "/scan", "sensor_msgs/msg/LaserScan", msgdef=scan_def, md5sum=scan_md5
        )
        clock = writer.add_connection(
            "/clock", "roslib/msg/Clock", msgdef=clock_def, md5sum=clock_md5
        )
        for i in range(N_SCANS):
            ns = (1_000 + i) * 10**9 // 10
            stamps.append(ns)
            ranges = np.minimum(
                3.0 / np.abs(np.cos(angles)), 2.0 / np.maximum(np.abs(np.sin(angles)), 1e-9) + i
            )
            time = types["builtin_interfaces/msg/Time"](sec=ns // 10**9, nanosec=ns % 10**9)
            msg = types["sensor_msgs/msg/LaserScan"](
                header=types["std_msgs/msg/Header"](seq=i, stamp=time, frame_id="laser"),
                angle_min=-1.5,
                angle_max=1.5,
                angle_increment=0.01,
                time_increment=0.0,
                scan_time=0.0,
                range_min=0.1,
                range_max=30.0,
                ranges=ranges.astype(np.float32),
                intensities=np.zeros(0, np.float32),
            )
            writer.write(scan, ns, STORE.serialize_ros1(msg, "sensor_msgs/msg/LaserScan"))
            tick = types["rosgraph_msgs/msg/Clock"](clock=time)
            writer.write(clock, ns, STORE.serialize_ros1(tick, "rosgraph_msgs/msg/Clock"))
    return stamps


def _without_index(bag: Path) -> Path:
    """A copy of ``bag`` whose header says no index was written (a killed recorder)."""
    data = bytearray(bag.read_bytes())
    at = data.index(b"index_pos=") + len(b"index_pos=")
    data[at : at + 8] = bytes(8)
    out = bag.with_name(f"unindexed_{bag.name}")
    out.write_bytes(bytes(data))
    return out


def test_names_are_mapped() -> None:
    assert modern_names("Header header\nMSG: roslib/Header\n") == (
        "Header header\nMSG: std_msgs/Header\n"
    )
    assert modern_names("roslib/Clock") == "rosgraph_msgs/Clock"
    assert modern_names("myroslib/Header") == "myroslib/Header"


@pytest.mark.parametrize("lean", [True, False])
def test_a_pre_electric_bag_is_read(tmp_path: Path, lean: bool, monkeypatch) -> None:
    monkeypatch.setattr(BagSource, "lean", lean)
    bag = tmp_path / "old.bag"
    stamps = _write_old_bag(bag)
    for path in (bag, _without_index(bag)):  # by rosbags' index, and from the chunks
        source = open_scans(path)
        assert source.topics["/clock"] == ("rosgraph_msgs/msg/Clock", N_SCANS)
        scans = list(source)
        assert len(scans) == N_SCANS and source.skipped == {}
        assert source.stamps_ns == stamps
        assert {s.frame_id for s in scans} == {"laser"}


def test_a_pre_electric_bag_is_copied_with_its_keypoints(tmp_path: Path) -> None:
    bag = tmp_path / "old.bag"
    _write_old_bag(bag)
    source = open_scans(bag)
    out = tmp_path / "corners.bag"
    summary = detect_recording(
        source, CornerDetector(), open_keypoint_writer(out, source, with_map=False)
    )
    assert summary.n_scans == N_SCANS and summary.n_keypoints > 0
    with AnyReader([out]) as reader:
        counts = {c.topic: c.msgcount for c in reader.connections}
    assert counts == {
        "/scan": N_SCANS,
        "/clock": N_SCANS,
        "/scan_corners": N_SCANS,
        "/scan_corner_markers": N_SCANS,
    }
