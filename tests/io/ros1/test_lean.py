"""The lean ROS 1 path (``io.ros1.index``, ``io.ros1.lean``, ``io.ros1.runs``) yields exactly
what the per-message path through rosbags yields: scans, stamps, poses, skips and errors."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from rosbags.rosbag1 import Writer
from rosbags.typesys import Stores, get_typestore

from conftest import damaged_copy, real_file
from laser_corners import InputError, LaserScan
from laser_corners.io import open_scans
from laser_corners.io.rosbag import BagSource

FIELDS = ("angle_min", "angle_increment", "range_min", "range_max", "stamp", "frame_id", "pose")


def _read(bag: Path, topic: str | None, lean: bool, monkeypatch: pytest.MonkeyPatch) -> dict:
    """Everything a source gives, read with the lean path on or off; which path ran."""
    monkeypatch.setattr(BagSource, "lean", lean)
    source = open_scans(bag, topic)
    scans: list[LaserScan] = []
    error = None
    try:
        for scan in source:
            scans.append(scan)
    except InputError as exc:
        error = str(exc)
    return {
        "scans": scans,
        "error": error,
        "lean_runs": int(source.read_lean),
        "skipped": source.skipped,
        "stamps_ns": list(source.stamps_ns),
        "log_times_ns": list(source.log_times_ns),
    }


def _assert_same(old: dict, new: dict) -> None:
    assert new["error"] == old["error"]
    assert new["skipped"] == old["skipped"]
    assert new["stamps_ns"] == old["stamps_ns"]
    assert new["log_times_ns"] == old["log_times_ns"]
    assert len(new["scans"]) == len(old["scans"])
    for a, b in zip(old["scans"], new["scans"], strict=True):
        assert b.ranges.dtype == np.float64 and not b.ranges.flags.writeable
        assert np.array_equal(a.ranges, b.ranges, equal_nan=True)
        for name in FIELDS:
            x, y = getattr(a, name), getattr(b, name)
            assert x == y and type(x) is type(y), (name, x, y)


@pytest.mark.real
@pytest.mark.parametrize(
    ("name", "topic"),
    [
        ("fr079.bag", None),
        ("aces.bag", None),
        ("intel.bag", None),
        ("hokuyo270_rooms.bag", "/left_scan"),
        ("hokuyo270_rooms.bag", "/rear_scan"),
        ("hokuyo270_rooms.bag", "/right_scan"),
    ],
)
def test_lean_path_equals_the_per_message_path_on_real_bags(
    name: str, topic: str | None, monkeypatch: pytest.MonkeyPatch
) -> None:
    bag = real_file(name)
    old = _read(bag, topic, False, monkeypatch)
    new = _read(bag, topic, True, monkeypatch)
    assert old["lean_runs"] == 0 and new["lean_runs"] == 1
    assert len(new["scans"]) == open_scans(bag, topic).n_scans
    _assert_same(old, new)
    if name != "hokuyo270_rooms.bag":  # odometry and tf: every scan has a pose
        assert all(scan.pose is not None for scan in new["scans"])


@pytest.mark.real
def test_lean_path_reads_on_after_a_damaged_chunk(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The per-message path stops at a damaged chunk; the lean path gives the same scans up
    to it, counts the chunk and its scans as skipped, and reads the chunks after it."""
    bag = damaged_copy(
        real_file("fr079.bag"), tmp_path / "flip.bag", flip=slice(1_200_000, 1_200_064)
    )
    old = _read(bag, None, False, monkeypatch)
    new = _read(bag, None, True, monkeypatch)
    assert new["lean_runs"] == 1
    assert old["error"] is not None and "flip.bag: damaged bag data" in old["error"]
    assert new["error"] is None
    lost = new["skipped"].pop("scans in damaged chunks or records")
    assert new["skipped"].pop("damaged bag chunk") == 1 and new["skipped"] == old["skipped"]
    assert 0 < lost < 500 and len(new["scans"]) == 4934 - lost
    n = len(old["scans"])
    assert n < len(new["scans"]) - 1000  # most of the bag comes after the damaged chunk
    prefix = {k: v[:n] if isinstance(v, list) else v for k, v in new.items()}
    _assert_same(old, {**prefix, "error": old["error"], "skipped": old["skipped"]})


def _mixed_bag(path: Path) -> None:
    """Scans whose beam count, frame name and validity change from message to message, and a
    String topic between them, a few per chunk."""
    store = get_typestore(Stores.ROS1_NOETIC)
    scan_type = store.types["sensor_msgs/msg/LaserScan"]
    header_type = store.types["std_msgs/msg/Header"]
    time_type = store.types["builtin_interfaces/msg/Time"]
    string_type = store.types["std_msgs/msg/String"]
    writer = Writer(path)
    writer.set_compression(Writer.CompressionFormat.BZ2)
    writer.chunk_threshold = 3000
    with writer:
        scans = writer.add_connection("/scan", scan_type.__msgtype__, typestore=store)
        text = writer.add_connection("/chatter", string_type.__msgtype__, typestore=store)
        for i in range(60):
            ns = 1_700_000_000 * 10**9 + i * 50_000_000
            beams = 90 if i % 7 else 120
            header = header_type(
                seq=i,
                stamp=time_type(sec=ns // 10**9, nanosec=ns % 10**9),
                frame_id="laser" if i % 11 else "laser_b",
            )
            ranges = (1.0 + 0.01 * i + np.sin(np.arange(beams) / 5.0)).astype(np.float32)
            ranges[i % beams] = np.nan
            msg = scan_type(
                header=header,
                angle_min=-1.5,
                angle_max=1.5,
                angle_increment=3.0 / beams,
                time_increment=0.0,
                scan_time=0.1,
                range_min=0.05,
                range_max=0.01 if i == 17 else 30.0,  # i == 17: invalid, a counted skip
                ranges=ranges,
                intensities=np.zeros(beams if i % 5 == 0 else 0, np.float32),
            )
            writer.write(scans, ns, store.serialize_ros1(msg, scan_type.__msgtype__))
            word = string_type(data=f"note {i}")
            writer.write(text, ns, store.serialize_ros1(word, string_type.__msgtype__))


def test_lean_path_equals_the_per_message_path_on_mixed_layouts(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    bag = tmp_path / "mixed.bag"
    _mixed_bag(bag)
    old = _read(bag, "/scan", False, monkeypatch)
    new = _read(bag, "/scan", True, monkeypatch)
    assert new["lean_runs"] == 1 and new["error"] is None
    assert len(new["scans"]) == 59 and new["skipped"] == {"invalid LaserScan fields": 1}
    assert {scan.n_beams for scan in new["scans"]} == {90, 120}
    assert {scan.frame_id for scan in new["scans"]} == {"laser", "laser_b"}
    _assert_same(old, new)
