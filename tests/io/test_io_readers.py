"""Readers: real recordings checked against the files themselves, and every kind of bad input.

Real files come from ``../shared/data/real`` (skipped when absent); damaged copies are made in
``tmp_path`` by truncating them or flipping bytes.
"""

from __future__ import annotations

import gzip
import itertools
import math
import re
from pathlib import Path

import numpy as np
import pytest
from rosbags.highlevel import AnyReader

from conftest import real_file
from laser_corners import InputError, LaserScan
from laser_corners.io import TopicChoiceError, detect_kind, open_scans
from laser_corners.io.arrays import write_scans_csv, write_scans_npz
from laser_corners.io.carmen import parse_carmen_line
from laser_corners.io.poses import PoseTrack, StreamingTrack, yaw_from_quaternion
from laser_corners.io.ros1_decode import (
    decode_ros1_laserscan,
    decode_ros1_odometry,
    decode_ros1_tf,
)

pytestmark = pytest.mark.real


# ----------------------------------------------------------------------------- helpers
def _header_stamps(bag: Path, topic: str) -> np.ndarray:
    """Header stamps (ns) of every message of ``topic``, read with rosbags directly."""
    with AnyReader([bag]) as reader:
        connections = [c for c in reader.connections if c.topic == topic]
        stamps = [
            (m := reader.deserialize(raw, c.msgtype)).header.stamp.sec * 10**9
            + m.header.stamp.nanosec
            for c, _, raw in reader.messages(connections=connections)
        ]
    return np.array(stamps, dtype=np.int64)


def _odometry(bag: Path) -> np.ndarray:
    """Rows ``t, x, y, yaw`` of /odom, read with rosbags directly."""
    with AnyReader([bag]) as reader:
        connections = [c for c in reader.connections if c.topic == "/odom"]
        rows = []
        for c, _, raw in reader.messages(connections=connections):
            m = reader.deserialize(raw, c.msgtype)
            q = m.pose.pose.orientation
            rows.append(
                (
                    m.header.stamp.sec + 1e-9 * m.header.stamp.nanosec,
                    m.pose.pose.position.x,
                    m.pose.pose.position.y,
                    yaw_from_quaternion(q.x, q.y, q.z, q.w),
                )
            )
    return np.array(rows)


def _robotlaser_lines(path: Path) -> list[list[str]]:
    with gzip.open(path, "rt") as handle:
        return [line.split() for line in handle if line.startswith("ROBOTLASER1")]


def _damaged_copy(src: Path, dst: Path, *, keep: int | None = None, flip: slice | None = None):
    data = bytearray(src.read_bytes())
    if keep is not None:
        data = data[:keep]
    if flip is not None:
        for i in range(*flip.indices(len(data))):
            data[i] ^= 0xA5
    dst.write_bytes(bytes(data))
    return dst


# ----------------------------------------------------------------------------- real files
@pytest.fixture(scope="module")
def fr079_scans() -> tuple[Path, list[LaserScan], object]:
    bag = real_file("fr079.bag")
    source = open_scans(bag)
    return bag, list(source), source


def test_fr079_counts_and_stamps_match_the_bag(fr079_scans) -> None:
    bag, scans, source = fr079_scans
    assert source.kind == "ros1" and source.topic == "/scan"
    assert source.n_scans == len(scans) == 4934
    assert source.skipped == {}
    truth = _header_stamps(bag, "/scan")
    assert np.array_equal(np.array(source.stamps_ns), truth)
    stamps = np.array([s.stamp for s in scans])
    np.testing.assert_allclose(stamps, truth * 1e-9, rtol=0, atol=1e-6)
    assert {s.frame_id for s in scans} == {"laser"}
    assert {s.n_beams for s in scans} == {360}


def test_fr079_poses_are_interpolated_odometry_plus_the_laser_mount(fr079_scans) -> None:
    bag, scans, _ = fr079_scans
    odom = _odometry(bag)
    assert all(s.pose is not None for s in scans)
    # /tf_static of fr079: base_link -> laser is x = 0.04 m, no rotation
    for index in (0, 1000, 2500, len(scans) - 1):
        scan = scans[index]
        t = scan.stamp
        k = int(np.clip(np.searchsorted(odom[:, 0], t), 1, len(odom) - 1))
        (t0, x0, y0, a0), (t1, x1, y1, a1) = odom[k - 1], odom[k]
        w = float(np.clip((t - t0) / (t1 - t0), 0.0, 1.0))
        da = math.atan2(math.sin(a1 - a0), math.cos(a1 - a0))
        yaw = a0 + w * da
        expected = (
            x0 + w * (x1 - x0) + 0.04 * math.cos(yaw),
            y0 + w * (y1 - y0) + 0.04 * math.sin(yaw),
        )
        assert scan.pose[:2] == pytest.approx(expected, abs=1e-6)
        assert math.cos(scan.pose[2] - yaw) == pytest.approx(1.0, abs=1e-9)


def test_intel_corrected_log_matches_its_robotlaser_lines() -> None:
    log = real_file("intel-corrected.clf.gz")
    lines = _robotlaser_lines(log)
    source = open_scans(log)
    assert source.kind == "carmen" and source.n_scans is None
    scans = list(source)
    assert len(scans) == len(lines) == 2672
    assert source.skipped == {}
    for index in (0, 1337, len(lines) - 1):
        tokens, scan = lines[index], scans[index]
        n = int(tokens[8])
        n_rem = int(tokens[9 + n])
        after = 10 + n + n_rem
        assert scan.stamp == pytest.approx(float(tokens[after + 11]), abs=1e-6)
        assert scan.pose == pytest.approx(tuple(float(v) for v in tokens[after : after + 3]))
        ranges = np.array(tokens[9 : 9 + n], dtype=float)
        assert scan.range_max == float(tokens[5]) == 50.0
        # max-range readings (81.83 m here) are no-return gaps
        assert scan.n_gaps == int(np.count_nonzero(ranges >= 50.0))
        assert index != 0 or scan.n_gaps > 0  # the first scan has 81.83 m readings
        assert scan.angle_increment == pytest.approx(math.radians(1.0), rel=1e-4)


def test_hokuyo_bag_needs_a_topic_and_reads_the_left_scan() -> None:
    bag = real_file("hokuyo270_rooms.bag")
    with pytest.raises(TopicChoiceError) as info:
        open_scans(bag)
    message = str(info.value)
    assert message.splitlines()[0] == f"{bag}: 3 LaserScan topics; choose one of:"
    assert info.value.topics == ["/left_scan", "/rear_scan", "/right_scan"]
    for topic in info.value.topics:
        assert f"\n  {topic}" in message
    assert "--" not in message  # the library names no command-line flag
    source = open_scans(bag, topic="/left_scan")
    scans = list(source)
    assert len(scans) == source.n_scans == 435
    assert np.array_equal(np.array(source.stamps_ns), _header_stamps(bag, "/left_scan"))
    assert all(s.frame_id == "left_laser" and s.pose is None for s in scans)
    assert scans[0].n_beams == 768


def test_a_topic_that_is_not_a_laserscan_is_refused() -> None:
    bag = real_file("fr079.bag")
    with pytest.raises(
        InputError, match=r"/odom is a nav_msgs/msg/Odometry.*LaserScan topics: /scan"
    ):
        open_scans(bag, topic="/odom")
    with pytest.raises(InputError, match="no topic '/nope'"):
        open_scans(bag, topic="/nope")


# ----------------------------------------------------------------------------- bad input
def test_missing_and_empty_files(tmp_path: Path) -> None:
    with pytest.raises(InputError, match="no such file"):
        open_scans(tmp_path / "absent.bag")
    for name in ("empty.bag", "empty.clf.gz", "empty.npz", "empty.csv"):
        (tmp_path / name).write_bytes(b"")
        with pytest.raises(InputError, match=re.escape(f"{tmp_path / name}: file is empty")):
            open_scans(tmp_path / name)


def test_truncated_bag_is_one_clear_error(tmp_path: Path) -> None:
    bag = _damaged_copy(real_file("fr079.bag"), tmp_path / "cut.bag", keep=1_000_000)
    with pytest.raises(
        InputError, match=r"cut\.bag: cannot open the ros1 bag, damaged or truncated"
    ) as info:
        open_scans(bag)
    message = str(info.value)
    assert "\n" not in message
    assert re.search(
        r"(chunk|record) at byte \d+ ends at byte \d+, after the end of the file "
        r"\(1000000 bytes\): truncated",
        message,
    )


def test_bag_with_a_damaged_index_record_is_read_from_its_chunks(tmp_path: Path) -> None:
    """rosbags raises a bare AssertionError when an index record header is damaged; the
    chunks are intact, so every scan is read, as from the undamaged bag."""
    data = bytearray(real_file("fr079.bag").read_bytes())
    # an IDXDATA record header: 47 bytes holding op=\x04, ver, conn, count
    first = next(
        m.start()
        for m in re.finditer(re.escape(b"/\x00\x00\x00"), data)
        if b"op=\x04" in data[m.start() + 4 : m.start() + 51]
    )
    data[first] = 46
    bag = tmp_path / "index.bag"
    bag.write_bytes(bytes(data))
    with pytest.raises(AssertionError):  # what rosbags itself does with it
        AnyReader([bag]).open()
    source = open_scans(bag)
    assert source.from_chunks and source.describe()["index"].startswith("unreadable")
    scans = list(source)
    original = open_scans(real_file("fr079.bag"))
    expected = list(original)
    assert not original.from_chunks and len(scans) == len(expected) == 4934
    assert source.stamps_ns == original.stamps_ns
    assert source.log_times_ns == original.log_times_ns
    for got, want in zip(scans, expected, strict=True):
        np.testing.assert_array_equal(got.ranges, want.ranges)
        assert got.pose == want.pose


def test_byte_flipped_bag_chunk_names_the_message(tmp_path: Path) -> None:
    bag = _damaged_copy(
        real_file("fr079.bag"), tmp_path / "flip.bag", flip=slice(1_200_000, 1_200_064)
    )
    source = open_scans(bag)  # the index is intact
    with pytest.raises(InputError) as info:
        for _ in source:
            pass
    message = str(info.value)
    assert "flip.bag: damaged bag data" in message
    assert re.search(r"at (message \d+ of /scan|reading /odom and tf)", message)


def test_truncated_gzip_log_names_the_line(tmp_path: Path) -> None:
    log = real_file("intel-corrected.clf.gz")
    cut = _damaged_copy(log, tmp_path / "cut.clf.gz", keep=log.stat().st_size // 2)
    source = open_scans(cut)
    read = 0
    with pytest.raises(
        InputError, match=r"cut\.clf\.gz: truncated gzip stream: the file ends after line \d+"
    ):
        for _ in source:
            read += 1
    assert 0 < read < 2672  # what came before the cut was read


def test_byte_flipped_gzip_log_is_one_clear_error(tmp_path: Path) -> None:
    log = real_file("fr079-corrected.clf.gz")
    flipped = _damaged_copy(log, tmp_path / "flip.clf.gz", flip=slice(300_000, 300_016))
    with pytest.raises(InputError, match=r"flip\.clf\.gz: corrupt gzip data.*\(at line \d+\)"):
        list(open_scans(flipped))


def test_malformed_carmen_lines_are_counted_skips(tmp_path: Path) -> None:
    with gzip.open(real_file("fr079-corrected.clf.gz"), "rt") as handle:
        lines = [next(handle) for _ in range(40)]
    laser_rows = [i for i, line in enumerate(lines) if line.startswith("ROBOTLASER1")]
    bad_number, bad_count = laser_rows[2], laser_rows[5]
    tokens = lines[bad_number].split()
    tokens[20] = "1.2.3"
    lines[bad_number] = " ".join(tokens) + "\n"
    lines[bad_count] = " ".join(lines[bad_count].split()[:100]) + "\n"  # cut inside readings
    lines.insert(0, "# a comment\n")
    lines.append("FLASER 3 1.0 2.0\n")
    lines.append("NOTAWORD 1 2 3\n")
    log = tmp_path / "bad.clf"
    log.write_text("".join(lines))
    source = open_scans(log)
    scans = list(source)
    assert len(scans) == len(laser_rows) - 2
    assert source.skipped == {
        "malformed ROBOTLASER1 line": 2,
        "malformed FLASER line": 1,
        "unknown record type": 1,
    }
    # line numbers are 1-based and count the inserted comment
    assert source.skip_examples[0].startswith(f"line {bad_number + 2}: malformed ROBOTLASER1")
    assert source.skip_examples[1].startswith(f"line {bad_count + 2}: malformed ROBOTLASER1")


def test_carmen_flaser_and_rawlaser_layouts() -> None:
    ranges = ["1.0"] * 180 + ["80.0"]
    flaser = parse_carmen_line(
        ["FLASER", "181", *ranges, "1", "2", "0.5", "0", "0", "0", "7.25", "h", "7.3"]
    )
    assert flaser.n_beams == 181 and flaser.pose == (1.0, 2.0, 0.5) and flaser.stamp == 7.25
    assert flaser.angles[-1] == pytest.approx(math.pi / 2)
    assert flaser.n_gaps == 1  # the 80 m reading
    raw = parse_carmen_line(
        [
            "RAWLASER2",
            "0",
            "-1.0",
            "2.0",
            "0.5",
            "30",
            "0.01",
            "0",
            "5",
            *["2"] * 5,
            "0",
            "3.5",
            "h",
            "3.6",
        ]
    )
    assert raw.pose is None and raw.frame_id == "laser2" and raw.n_beams == 5
    assert raw.angles[-1] == pytest.approx(1.0) and raw.stamp == 3.5


def test_unknown_kind_and_topic_on_a_log(tmp_path: Path) -> None:
    odd = tmp_path / "scan.xyz"
    odd.write_bytes(b"\x00\x01binary")
    with pytest.raises(InputError, match="unknown kind of recording"):
        open_scans(odd)
    with pytest.raises(InputError, match="a carmen file has no topics; a topic applies to bags"):
        open_scans(real_file("intel-corrected.clf.gz"), topic="/scan")


# ----------------------------------------------------------------------------- arrays
def test_npz_and_csv_round_trip_the_intel_log(tmp_path: Path) -> None:
    scans = list(open_scans(real_file("intel-corrected.clf.gz")))[:50]
    write_scans_npz(tmp_path / "s.npz", scans)
    write_scans_csv(tmp_path / "s.csv", scans)
    for name, kind in (("s.npz", "npz"), ("s.csv", "csv")):
        assert detect_kind(tmp_path / name) == kind
        source = open_scans(tmp_path / name)
        back = list(source)
        assert source.n_scans == len(back) == 50
        for a, b in zip(scans, back, strict=True):
            np.testing.assert_array_equal(a.ranges, b.ranges)
            assert (b.stamp, b.pose, b.frame_id) == (a.stamp, a.pose, a.frame_id)
            assert (b.angle_min, b.angle_increment, b.range_max) == (
                a.angle_min, a.angle_increment, a.range_max,
            )  # fmt: skip


def test_csv_bad_rows_are_counted_and_missing_geometry_is_an_error(tmp_path: Path) -> None:
    good = tmp_path / "good.csv"
    good.write_text(
        "# angle_min: -1.0\n# angle_increment: 0.5\n# range_max: 10\n"
        "stamp,r0,r1,r2,r3,r4\n1.0,1,1,1,,nan\n2.0,1,x,1,1,1\n3.0,1,1\n4.0,2,2,2,2,2\n"
    )
    source = open_scans(good)
    scans = list(source)
    assert [s.stamp for s in scans] == [1.0, 4.0]
    assert scans[0].n_gaps == 2
    assert source.skipped == {"malformed row": 1, "wrong number of cells": 1}
    assert source.skip_examples[0].startswith("line 6:")
    bad = tmp_path / "bad.csv"
    bad.write_text("# angle_min: -1.0\nr0,r1,r2\n1,1,1\n")
    with pytest.raises(InputError, match=r"bad\.csv: missing '# angle_increment: value'"):
        open_scans(bad)


def test_npz_without_ranges_or_corrupt_is_an_error(tmp_path: Path) -> None:
    np.savez(tmp_path / "x.npz", angle_min=0.0)
    with pytest.raises(InputError, match="missing array 'ranges'"):
        open_scans(tmp_path / "x.npz")
    scans = list(open_scans(real_file("intel-corrected.clf.gz")))[:5]
    write_scans_npz(tmp_path / "ok.npz", scans)
    _damaged_copy(tmp_path / "ok.npz", tmp_path / "cut.npz", keep=200)
    with pytest.raises(InputError, match=r"cut\.npz: not a readable \.npz"):
        open_scans(tmp_path / "cut.npz")


# ----------------------------------------------------------------------------- fast ROS 1 path
def _first_messages(bag: Path, topic: str, count: int) -> list[tuple[bytes, object]]:
    """Raw bytes and rosbags' deserialized message of the first ``count`` of ``topic``."""
    with AnyReader([bag]) as reader:
        connections = [c for c in reader.connections if c.topic == topic]
        found = []
        for c, _, raw in reader.messages(connections=connections):
            found.append((bytes(raw), reader.deserialize(raw, c.msgtype)))
            if len(found) == count:
                break
    return found


@pytest.mark.parametrize("name", ["fr079.bag", "intel.bag"])
def test_fast_ros1_decoders_equal_rosbags_deserialize(name: str) -> None:
    bag = real_file(name)
    scans = _first_messages(bag, "/scan", 300)
    assert len(scans) == 300
    for raw, msg in scans:
        stamp_ns, frame_id, angle_min, angle_increment, range_min, range_max, ranges = (
            decode_ros1_laserscan(raw)  # type: ignore[misc]
        )
        assert stamp_ns == msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec
        assert frame_id == msg.header.frame_id
        assert (angle_min, angle_increment, range_min, range_max) == (
            msg.angle_min, msg.angle_increment, msg.range_min, msg.range_max,
        )  # fmt: skip
        assert ranges.dtype == np.float32
        np.testing.assert_array_equal(ranges, msg.ranges)
    odometry = _first_messages(bag, "/odom", 300)
    assert len(odometry) == 300
    for raw, msg in odometry:
        q = msg.pose.pose.orientation
        expected = (
            msg.header.stamp.sec + 1e-9 * msg.header.stamp.nanosec,
            msg.pose.pose.position.x,
            msg.pose.pose.position.y,
            yaw_from_quaternion(q.x, q.y, q.z, q.w),
        )
        assert decode_ros1_odometry(raw) == (msg.header.frame_id, msg.child_frame_id, expected)
    transforms = _first_messages(bag, "/tf", 300)
    assert transforms
    for raw, msg in transforms:
        expected = [
            (
                t.header.frame_id,
                t.child_frame_id,
                (
                    t.transform.translation.x,
                    t.transform.translation.y,
                    yaw_from_quaternion(
                        t.transform.rotation.x,
                        t.transform.rotation.y,
                        t.transform.rotation.z,
                        t.transform.rotation.w,
                    ),
                ),
            )
            for t in msg.transforms
        ]
        assert decode_ros1_tf(raw) == expected


def test_fast_ros1_decoders_refuse_bytes_that_do_not_add_up() -> None:
    ((raw, _),) = _first_messages(real_file("fr079.bag"), "/scan", 1)
    ((odom, _),) = _first_messages(real_file("fr079.bag"), "/odom", 1)
    ((tf, _),) = _first_messages(real_file("fr079.bag"), "/tf", 1)
    assert decode_ros1_laserscan(raw) is not None
    for bad in (raw[:-1], raw + b"\0", raw[:20], b""):
        assert decode_ros1_laserscan(bad) is None
    for bad in (odom[:-1], odom + b"\0", b"\0\0"):
        assert decode_ros1_odometry(bad) is None
    for bad in (tf[:-1], tf + b"\0", b"\x05\0\0\0"):
        assert decode_ros1_tf(bad) is None
    frame_length = int(np.frombuffer(raw, "<u4", 1, 12)[0])
    not_utf8 = bytearray(raw)
    not_utf8[16 : 16 + frame_length] = b"\xff" * frame_length
    assert frame_length > 0 and decode_ros1_laserscan(bytes(not_utf8)) is None


@pytest.mark.parametrize("name", ["fr079.bag", "intel.bag"])
def test_one_pass_poses_equal_the_two_pass_track(name: str) -> None:
    """The first 500 scans: same poses as a pose track built from a full pass over /odom+tf."""
    source = open_scans(real_file(name))
    scans = list(itertools.islice(iter(source), 500))
    with source.reader() as reader:  # type: ignore[attr-defined]
        track = source.pose_track(reader)  # type: ignore[attr-defined]
    assert track is not None and len(scans) == 500
    for scan in scans:
        assert scan.pose is not None
        assert scan.pose == track.pose(scan.stamp, scan.frame_id)  # exactly


def test_streaming_track_unwraps_yaw_exactly_as_np_unwrap() -> None:
    rng = np.random.default_rng(3)
    yaw = np.angle(np.exp(1j * np.cumsum(rng.uniform(-1.5, 1.5, 400))))  # many wraps
    samples = [(0.1 * i, float(np.cos(i)), float(np.sin(i)), float(y)) for i, y in enumerate(yaw)]
    late = samples.pop(200)  # one sample arrives out of order
    track = StreamingTrack()
    for sample in samples[:300]:
        track.add_odometry("odom", "base", sample)
    track.add_odometry("odom", "base", late)
    for sample in samples[300:]:
        track.add_odometry("odom", "base", sample)
    track.add_transforms([("base", "laser", (0.1, 0.0, 0.5))], is_static=True)
    ordered = np.array(sorted([*samples, late]))
    reference = PoseTrack(
        "odom", "base", ordered[:, 0], ordered[:, 1], ordered[:, 2], np.unwrap(ordered[:, 3]),
        {"laser": ("base", (0.1, 0.0, 0.5))},
    )  # fmt: skip
    for stamp in np.linspace(-0.2, 40.3, 97):
        expected = reference.pose(float(stamp), "laser")
        got = track.pose(float(stamp), "laser")
        assert got == pytest.approx(expected, abs=1e-12) if expected else got is None
    in_order = StreamingTrack()
    for sample in sorted([*samples, late]):
        in_order.add_odometry("odom", "base", sample)
    in_order.pose(0.0, "base")
    np.testing.assert_array_equal(in_order._current().yaw, np.unwrap(ordered[:, 3]))  # type: ignore[union-attr]


def test_bag_read_through_the_rosbags_fallback_gives_the_same_scans(monkeypatch) -> None:
    """Messages the fast decoders refuse go through rosbags' deserializer, same result."""
    bag = real_file("fr079.bag")
    fast = list(itertools.islice(iter(open_scans(bag)), 300))
    import laser_corners.io.rosbag as rosbag_module

    for name in ("decode_ros1_laserscan", "decode_ros1_odometry", "decode_ros1_tf"):
        monkeypatch.setattr(rosbag_module, name, lambda raw: None)
    fallback = list(itertools.islice(iter(open_scans(bag)), 300))
    assert len(fast) == len(fallback) == 300
    for a, b in zip(fast, fallback, strict=True):
        np.testing.assert_array_equal(a.ranges, b.ranges)
        assert (a.stamp, a.frame_id, a.pose, a.angle_min, a.angle_increment) == (
            b.stamp, b.frame_id, b.pose, b.angle_min, b.angle_increment,
        )  # fmt: skip
