"""Bag reading (ROS 1, ROS 2 sqlite3): real bags checked against rosbags itself, the fast ROS 1
decoders, one-pass poses, and damaged bags."""

from __future__ import annotations

import itertools
import math
import re
from pathlib import Path

import numpy as np
import pytest
from rosbags.highlevel import AnyReader

from conftest import damaged_copy, real_file
from laser_corners import InputError, LaserScan
from laser_corners.io import (
    BagSource,
    TopicChoiceError,
    open_scans,
)
from laser_corners.io.poses import yaw_from_quaternion
from laser_corners.io.ros1.decode import (
    decode_ros1_laserscan,
    decode_ros1_odometry,
    decode_ros1_tf,
)

pytestmark = pytest.mark.real


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


def test_truncated_bag_is_one_clear_error(tmp_path: Path) -> None:
    bag = damaged_copy(real_file("fr079.bag"), tmp_path / "cut.bag", keep=1_000_000)
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


def test_byte_flipped_bag_chunk_is_skipped_or_named(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The lean path (standard definitions) skips the damaged chunk and names it; the
    per-message path stops with one line naming the message."""
    bag = damaged_copy(
        real_file("fr079.bag"), tmp_path / "flip.bag", flip=slice(1_200_000, 1_200_064)
    )
    source = open_scans(bag)  # the index is intact
    assert len(list(source)) < source.n_scans
    assert source.skipped["damaged bag chunk"] == 1
    assert source.skip_examples[0].startswith("chunk at byte ")
    monkeypatch.setattr(BagSource, "lean", False)
    with pytest.raises(InputError) as info:
        for _ in source:
            pass
    message = str(info.value)
    assert "flip.bag: damaged bag data" in message
    assert re.search(r"at (message \d+ of /scan|reading /odom and tf)", message)


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
            msg.angle_min,
            msg.angle_increment,
            msg.range_min,
            msg.range_max,
        )
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
            b.stamp,
            b.frame_id,
            b.pose,
            b.angle_min,
            b.angle_increment,
        )


def test_odometry_thousands_of_km_away_is_a_counted_skip(tmp_path: Path) -> None:
    """A bag whose odometry jumps to x = 1e300 for one sample: the scans posed from it are
    counted skips ("scan with an absurd pose"), the others read, and the bag's stamp lists
    keep to the scans read."""
    from dataclasses import replace

    from laser_corners.io.base import BAD_POSE
    from laser_corners.sim import UST_10LX, rectangular_room, trajectory
    from laser_corners.sim.export import simulate_sequence, write_bag

    rng = np.random.default_rng(3)
    world = rectangular_room()
    truth = trajectory(world, 40, rng, rate_hz=UST_10LX.rate_hz, speed=0.5)
    sequence = simulate_sequence(world, UST_10LX, truth, 0.005, rng, start_time=100.0)
    poses = truth.copy()
    poses[20, 0] = 1e300
    bag = tmp_path / "far.bag"
    write_bag(replace(sequence, poses=poses), bag)
    source = open_scans(bag)
    scans = list(source)
    assert source.skipped.get(BAD_POSE, 0) >= 1, source.skipped
    assert len(scans) + sum(source.skipped.values()) == 40, source.skipped
    assert len(source.stamps_ns) == len(scans)
    assert all(abs(s.pose[0]) < 1e3 for s in scans)
