"""ROS 1 bags whose index rosbags refuses are read from their chunk records.

Every bag here is written by the test: a small LaserScan bag (rosbags' ``Writer``, several
chunks), then its INDEX_DATA records are rewritten with their header fields in another order
(valid: a record header is a set of ``name=value`` fields, https://wiki.ros.org/Bags/Format/2.0)
so that rosbags' reader, which takes the field layout of the first INDEX_DATA record for all of
them, fails with the bare ``AssertionError`` (``size == count * 12``) the issue reports for
CCNYRoboticsLab's demo.bag. Debian's ``rosbag`` (when installed) confirms the bag is valid.
"""

from __future__ import annotations

import json
import struct
import subprocess
from pathlib import Path

import numpy as np
import pytest
from rosbags.highlevel import AnyReader
from rosbags.rosbag1 import Writer
from rosbags.typesys import Stores, get_typestore

from laser_corners import InputError
from laser_corners.io import open_scans

N_SCANS = 60
N_BEAMS = 181


def _ranges(i: int) -> np.ndarray:
    return (2.0 + 0.01 * i + 0.5 * np.sin(np.arange(N_BEAMS) / 7.0)).astype(np.float32)


def _write_bag(path: Path, compression: str = "none", increment: float = 0.0174533) -> None:
    """A ROS 1 bag of ``N_SCANS`` LaserScans on /scan plus a String topic, 1 chunk per 10 scans."""
    store = get_typestore(Stores.ROS1_NOETIC)
    scan_type = store.types["sensor_msgs/msg/LaserScan"]
    header_type = store.types["std_msgs/msg/Header"]
    time_type = store.types["builtin_interfaces/msg/Time"]
    string_type = store.types["std_msgs/msg/String"]
    writer = Writer(path)
    if compression != "none":
        writer.set_compression(Writer.CompressionFormat[compression.upper()])
    writer.chunk_threshold = 10 * (N_BEAMS * 4 + 100)
    with writer:
        scans = writer.add_connection("/scan", scan_type.__msgtype__, typestore=store)
        text = writer.add_connection("/chatter", string_type.__msgtype__, typestore=store)
        for i in range(N_SCANS):
            ns = 1_700_000_000 * 10**9 + i * 100_000_000
            header = header_type(
                seq=i, stamp=time_type(sec=ns // 10**9, nanosec=ns % 10**9), frame_id="laser"
            )
            msg = scan_type(
                header=header,
                angle_min=-1.5707964,
                angle_max=1.5707964,
                angle_increment=increment,
                time_increment=0.0,
                scan_time=0.1,
                range_min=0.05,
                range_max=30.0,
                ranges=_ranges(i),
                intensities=np.zeros(0, np.float32),
            )
            writer.write(scans, ns, store.serialize_ros1(msg, scan_type.__msgtype__))
            if i % 3 == 0:
                word = string_type(data=f"note {i}")
                writer.write(text, ns + 1, store.serialize_ros1(word, string_type.__msgtype__))


def _records(data: bytes) -> list[tuple[int, int, dict[bytes, bytes], int, int]]:
    """Top-level records: (start, op, header fields, header length, data length)."""
    records = []
    pos = data.index(b"\n") + 1
    while pos < len(data):
        hlen = struct.unpack_from("<I", data, pos)[0]
        fields, at = {}, pos + 4
        while at < pos + 4 + hlen:
            flen = struct.unpack_from("<I", data, at)[0]
            name, _, value = data[at + 4 : at + 4 + flen].partition(b"=")
            fields[name] = value
            at += 4 + flen
        dlen = struct.unpack_from("<I", data, pos + 4 + hlen)[0]
        records.append((pos, fields[b"op"][0], fields, hlen, dlen))
        pos += 8 + hlen + dlen
    return records


def _reorder_index_headers(path: Path) -> int:
    """Rewrite every INDEX_DATA header but the first with its fields in reverse order (same
    bytes, same length); returns how many were rewritten."""
    data = bytearray(path.read_bytes())
    index_records = [r for r in _records(bytes(data)) if r[1] == 0x04]
    for start, _, fields, hlen, _ in index_records[1:]:
        body = b"".join(
            struct.pack("<I", len(name) + 1 + len(value)) + name + b"=" + value
            for name, value in reversed(list(fields.items()))
        )
        assert len(body) == hlen
        data[start + 4 : start + 4 + hlen] = body
    path.write_bytes(bytes(data))
    return len(index_records) - 1


def _debian_rosbag(path: Path) -> dict[str, object] | None:
    """What Debian's rosbag reads from ``path`` (topic counts, /scan stamps), or None."""
    script = (
        "import json, sys, rosbag\n"
        "bag = rosbag.Bag(sys.argv[1])\n"
        "counts = {t: i.message_count for t, i in bag.get_type_and_topic_info().topics.items()}\n"
        "stamps = [t.to_nsec() for _, _, t in bag.read_messages(topics=['/scan'], raw=True)]\n"
        "print(json.dumps({'counts': counts, 'stamps': stamps}))\n"
    )
    try:
        done = subprocess.run(
            ["/usr/bin/python3", "-c", script, str(path)],
            capture_output=True,
            text=True,
            timeout=60,
            check=False,
        )
    except (OSError, subprocess.TimeoutExpired):
        return None
    if done.returncode != 0:
        if "No module named 'rosbag'" in done.stderr:
            return None
        raise AssertionError(f"Debian rosbag refuses the bag: {done.stderr.strip()[-300:]}")
    return json.loads(done.stdout)


@pytest.mark.parametrize("compression", ["none", "bz2", "lz4"])
def test_a_valid_bag_rosbags_refuses_is_read_from_its_chunks(
    tmp_path: Path, compression: str
) -> None:
    bag = tmp_path / "reordered.bag"
    _write_bag(bag, compression)
    assert _reorder_index_headers(bag) >= 5  # several chunks
    with pytest.raises(AssertionError):  # rosbags' own reader: the issue's bare assertion
        AnyReader([bag]).open()
    # ROS's own reader finds the bag valid (its roslz4 does not read rosbags' LZ4 frames)
    debian = _debian_rosbag(bag) if compression != "lz4" else None
    if debian is not None:
        assert debian["counts"] == {"/scan": N_SCANS, "/chatter": N_SCANS // 3}
    source = open_scans(bag)
    assert source.from_chunks and source.n_scans == N_SCANS  # type: ignore[attr-defined]
    assert source.topics == {  # type: ignore[attr-defined]
        "/scan": ("sensor_msgs/msg/LaserScan", N_SCANS),
        "/chatter": ("std_msgs/msg/String", N_SCANS // 3),
    }
    scans = list(source)
    assert len(scans) == N_SCANS and not source.skipped
    stamps = [1_700_000_000 * 10**9 + i * 100_000_000 for i in range(N_SCANS)]
    assert source.stamps_ns == source.log_times_ns == stamps  # type: ignore[attr-defined]
    if debian is not None:
        assert debian["stamps"] == stamps
    for i, scan in enumerate(scans):
        np.testing.assert_array_equal(scan.ranges, _ranges(i).astype(np.float64))
        assert scan.angle_min == pytest.approx(-1.5707964)
        assert scan.angle_increment == pytest.approx(0.0174533)
        assert (scan.range_min, scan.frame_id) == (pytest.approx(0.05), "laser")


def test_a_bag_without_index_is_read_from_its_chunks(tmp_path: Path) -> None:
    """A recorder killed before writing the index leaves ``index_pos`` 0 and no index."""
    bag = tmp_path / "unindexed.bag"
    _write_bag(bag)
    data = bytearray(bag.read_bytes())
    records = _records(bytes(data))
    index_pos = struct.unpack("<Q", records[0][2][b"index_pos"])[0]
    header_start = records[0][0]
    field = data.index(b"index_pos=", header_start) + len(b"index_pos=")
    data[field : field + 8] = struct.pack("<Q", 0)
    bag.write_bytes(bytes(data[:index_pos]))  # no connection and chunk-info records
    with pytest.raises(Exception, match="not indexed"):
        AnyReader([bag]).open()
    source = open_scans(bag)
    scans = list(source)
    assert source.from_chunks and len(scans) == N_SCANS  # type: ignore[attr-defined]
    np.testing.assert_array_equal(scans[-1].ranges, _ranges(N_SCANS - 1).astype(np.float64))


def test_a_bag_cut_inside_a_chunk_is_still_one_clear_error(tmp_path: Path) -> None:
    bag = tmp_path / "cut.bag"
    _write_bag(bag)
    _reorder_index_headers(bag)
    chunks = [r for r in _records(bag.read_bytes()) if r[1] == 0x05]
    cut_at = chunks[3][0] + 100  # inside the 4th chunk
    bag.write_bytes(bag.read_bytes()[:cut_at])
    with pytest.raises(InputError) as info:
        open_scans(bag)
    message = str(info.value)
    assert "\n" not in message and message.startswith(f"{bag}: cannot open the ros1 bag")
    assert f"chunk at byte {chunks[3][0]} ends at byte" in message
    assert f"after the end of the file ({cut_at} bytes): truncated" in message


def test_a_chunk_with_garbage_records_is_one_clear_error(tmp_path: Path) -> None:
    bag = tmp_path / "garbage.bag"
    _write_bag(bag)
    _reorder_index_headers(bag)
    data = bytearray(bag.read_bytes())
    chunk = [r for r in _records(bytes(data)) if r[1] == 0x05][2]
    inside = chunk[0] + 8 + chunk[3]  # the chunk's first record
    data[inside : inside + 4] = struct.pack("<I", 10**6)  # a record header longer than the chunk
    bag.write_bytes(bytes(data))
    with pytest.raises(InputError, match=r"garbage\.bag: cannot open the ros1 bag") as info:
        open_scans(bag)
    assert "\n" not in str(info.value)
