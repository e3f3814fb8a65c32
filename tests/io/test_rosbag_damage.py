"""Damage in the middle of a recording: what is skipped is counted, the rest is read, and the
output says what it keeps (issue 21, item 4)."""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
import pytest
from rosbags.highlevel import AnyReader
from rosbags.rosbag1 import Reader, Writer
from rosbags.typesys import Stores, get_typestore
from typer.testing import CliRunner

from conftest import damaged_copy, real_file
from laser_corners.cli import app
from laser_corners.errors import InputError
from laser_corners.io import open_scans
from laser_corners.pipeline import detect_file

pytestmark = pytest.mark.real
runner = CliRunner()
FLIPPED = 1989337  # a byte inside a bz2 chunk in the middle of intel.bag


def _chunk_around(bag: Path, offset: int) -> tuple[int, set[int]]:
    """The position of the chunk of ``bag`` whose data holds byte ``offset``, and the log
    times (ns) of the /scan messages in it (from the intact bag's index)."""
    with Reader(bag) as reader:
        pos = next(
            p for p, c in reader.chunks.items() if c.datapos <= offset < c.datapos + c.datasize
        )
        scan = next(c for c in reader.connections if c.topic == "/scan")
        times = {entry.time for entry in reader.indexes[scan.id] if entry.chunk_pos == pos}
    return pos, times


def test_a_damaged_chunk_is_skipped_counted_and_the_chunks_after_it_are_read(
    tmp_path: Path,
) -> None:
    intact = real_file("intel.bag")
    bag = damaged_copy(intact, tmp_path / "intel.bag", flip=slice(FLIPPED, FLIPPED + 1))
    pos, lost = _chunk_around(intact, FLIPPED)
    assert 0 < len(lost) < 1000

    source = open_scans(bag)
    scans = list(source)
    good = list(open_scans(intact))
    assert source.n_scans == len(good) == 13631
    assert len(scans) == len(good) - len(lost)
    assert source.skipped == {
        "damaged bag chunk": 1,
        "scans in damaged chunks or records": len(lost),
    }
    assert source.skip_examples[0].startswith(f"chunk at byte {pos}: damaged bag chunk")
    expected = [s for s, t in zip(good, _log_times(intact), strict=True) if t not in lost]
    assert [s.stamp for s in scans] == [s.stamp for s in expected]
    for a, b in zip(scans[::500], expected[::500], strict=True):
        np.testing.assert_array_equal(a.ranges, b.ranges)

    out = tmp_path / "o.csv"
    result = runner.invoke(app, ["detect", str(bag), "-o", str(out)], terminal_width=200)
    assert result.exit_code == 0, result.output
    assert f"{len(scans)} of {len(good)}" in result.stdout
    assert "1 damaged bag chunk" in result.stdout
    with out.open() as handle:
        indices = {int(row["scan_index"]) for row in csv.DictReader(handle)}
    assert max(indices) > 13000  # the chunks after the damaged one were read


def _log_times(bag: Path) -> list[int]:
    source = open_scans(bag)
    list(source)
    return list(source.log_times_ns)


def test_a_truncated_log_keeps_its_partial_output_and_says_so(tmp_path: Path) -> None:
    """Half of a gzipped CARMEN log: exit 2, the output keeps what was written under its final
    name, and the error line says how many scans it holds."""
    data = real_file("intel-corrected.clf.gz").read_bytes()
    log = tmp_path / "half.clf.gz"
    log.write_bytes(data[: len(data) // 2])
    out = tmp_path / "h.csv"
    result = runner.invoke(app, ["detect", str(log), "-o", str(out)], terminal_width=200)
    assert result.exit_code == 2, result.output
    line = result.stderr.strip().splitlines()[-1]
    assert "truncated" in line and f"{out} is incomplete" in line
    with out.open() as handle:
        rows = list(csv.DictReader(handle))
    n_scans = len(list(_scans_before_damage(log)))
    assert f"it keeps the {len(rows)} keypoints of the {n_scans} scans read before" in line
    assert max(int(r["scan_index"]) for r in rows) < n_scans


def _scans_before_damage(log: Path) -> list[object]:
    scans: list[object] = []
    with pytest.raises(InputError, match="truncated"):
        scans.extend(open_scans(log))
    return scans


def test_a_bag_copy_of_a_damaged_bag_leaves_out_only_the_damaged_chunk(tmp_path: Path) -> None:
    """``-o out.bag`` of the damaged intel.bag: the copy holds every message of the intact
    chunks (the damaged one left out) and the keypoints of every scan read."""
    intact = real_file("intel.bag")
    bag = damaged_copy(intact, tmp_path / "intel.bag", flip=slice(FLIPPED, FLIPPED + 1))
    pos, lost = _chunk_around(intact, FLIPPED)
    with Reader(intact) as reader:
        kept = {
            c.topic: sum(1 for e in reader.indexes[c.id] if e.chunk_pos != pos)
            for c in reader.connections
        }
    run = detect_file(bag, tmp_path / "out.bag")
    assert run.summary.n_scans == kept["/scan"] == 13631 - len(lost)
    with AnyReader([tmp_path / "out.bag"]) as reader:
        counts = {c.topic: c.msgcount for c in reader.connections}
    scans = kept["/scan"]
    assert counts == {**kept, "/scan_corners": scans, "/scan_corner_markers": scans}


def test_a_damaged_message_record_is_skipped_and_the_rest_of_its_chunk_read(
    tmp_path: Path,
) -> None:
    """An uncompressed bag whose 8th MESSAGE_DATA record header says op 9: that scan is a
    counted skip, the other scans of the chunk (before and after it) are read."""
    store = get_typestore(Stores.ROS1_NOETIC)
    types = store.types
    bag = tmp_path / "scans.bag"
    angles = np.linspace(-1.5, 1.5, 301)
    with Writer(bag) as writer:
        scan = writer.add_connection("/scan", "sensor_msgs/msg/LaserScan", typestore=store)
        for i in range(20):
            time = types["builtin_interfaces/msg/Time"](sec=100 + i, nanosec=0)
            msg = types["sensor_msgs/msg/LaserScan"](
                header=types["std_msgs/msg/Header"](seq=i, stamp=time, frame_id="laser"),
                angle_min=-1.5,
                angle_max=1.5,
                angle_increment=0.01,
                time_increment=0.0,
                scan_time=0.0,
                range_min=0.1,
                range_max=30.0,
                ranges=(2.0 + 0.1 * np.cos(angles + i)).astype(np.float32),
                intensities=np.zeros(0, np.float32),
            )
            writer.write(scan, (100 + i) * 10**9, store.serialize_ros1(msg, scan.msgtype))
    data = bytearray(bag.read_bytes())
    at, records = 0, []
    while (at := data.find(b"op=\x02", at + 1)) > 0:
        records.append(at)
    assert len(records) == 20
    data[records[7] + 3] = 9
    bag.write_bytes(bytes(data))

    source = open_scans(bag)
    scans = list(source)
    assert source.skipped == {
        "damaged message record": 1,
        "scans in damaged chunks or records": 1,
    }
    assert [round(s.stamp) for s in scans] == [100 + i for i in range(20) if i != 7]
    assert source.skip_examples[0].startswith("chunk at byte ")
