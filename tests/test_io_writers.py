"""Writers: message conversions, CSV/Parquet tables, keypoint bags read back with rosbags."""

from __future__ import annotations

import csv
import math
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq
import pytest
from rosbags.highlevel import AnyReader
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.typesys import Stores, get_typestore

from conftest import real_file
from laser_corners import CornerDetector, InputError, Keypoints, LaserScan
from laser_corners.io import open_keypoint_writer, open_scans
from laser_corners.io.messages import (
    MARKER_ADD,
    MARKER_ARROW,
    MARKER_DELETEALL,
    keypoints_to_marker_fields,
    keypoints_to_pose_array_fields,
)
from laser_corners.io.rosbag import yaw_from_quaternion
from laser_corners.io.writers import MAP_COLUMNS, TABLE_COLUMNS
from laser_corners.pipeline import detect_recording


def _keypoints(n: int, seed: int = 0) -> Keypoints:
    rng = np.random.default_rng(seed)
    return Keypoints(
        xy=rng.uniform(-5, 5, (n, 2)),
        beam_index=rng.integers(0, 100, n),
        opening_angle_deg=rng.uniform(45, 135, n),
        orientation=rng.uniform(-math.pi, math.pi, n),
        n_scales=rng.integers(3, 9, n),
        rmse=rng.uniform(0, 0.02, n),
        n_merged=rng.integers(1, 4, n),
        stamp=12.5,
        frame_id="laser",
    )


# ----------------------------------------------------------------------------- messages
def test_pose_array_fields_carry_position_and_yaw() -> None:
    kps = _keypoints(7)
    fields = keypoints_to_pose_array_fields(kps)
    assert fields["positions"].shape == (7, 3) and fields["orientations"].shape == (7, 4)
    np.testing.assert_array_equal(fields["positions"][:, :2], kps.xy)
    assert not fields["positions"][:, 2].any()
    q = fields["orientations"]
    np.testing.assert_allclose(np.linalg.norm(q, axis=1), 1.0)
    yaws = [yaw_from_quaternion(*row) for row in q]
    np.testing.assert_allclose(np.cos(np.subtract(yaws, kps.orientation)), 1.0, atol=1e-12)


def test_marker_fields_clear_then_one_arrow_per_keypoint() -> None:
    kps = _keypoints(4)
    markers = keypoints_to_marker_fields(kps, ns="c", lifetime=0.5)
    assert markers[0]["action"] == MARKER_DELETEALL
    arrows = markers[1:]
    assert [m["id"] for m in arrows] == [0, 1, 2, 3]
    assert all(m["type"] == MARKER_ARROW and m["action"] == MARKER_ADD for m in arrows)
    assert all(m["ns"] == "c" and m["lifetime"] == 0.5 for m in arrows)
    np.testing.assert_allclose([m["position"][:2] for m in arrows], kps.xy)
    assert keypoints_to_marker_fields(Keypoints.empty())[0]["action"] == MARKER_DELETEALL
    assert len(keypoints_to_marker_fields(Keypoints.empty())) == 1


# ----------------------------------------------------------------------------- tables
def _scans_with_keypoints(n: int) -> list[tuple[LaserScan, Keypoints]]:
    out = []
    for i in range(n):
        pose = None if i == 2 else (float(i), -1.0, 0.3 * i)
        scan = LaserScan(np.ones(10), 0.0, 0.1, stamp=100.0 + i, frame_id="laser", pose=pose)
        out.append((scan, _keypoints(i % 3, seed=i)))
    return out


@pytest.mark.parametrize("suffix", [".csv", ".parquet"])
def test_table_rows_match_the_keypoints(tmp_path: Path, suffix: str) -> None:
    items = _scans_with_keypoints(7)
    path = tmp_path / f"k{suffix}"
    # the table writers do not use the source
    with open_keypoint_writer(path, None, with_map=True, flush_every=2) as writer:  # type: ignore[arg-type]
        for i, (scan, kps) in enumerate(items):
            writer.write(i, scan, kps)
    if suffix == ".csv":
        with path.open() as handle:
            rows = list(csv.DictReader(handle))
        columns = list(rows[0])
        get = lambda name: np.array([float(r[name]) if r[name] else np.nan for r in rows])  # noqa: E731
    else:
        table = pq.read_table(path)
        columns = table.column_names
        assert pq.ParquetFile(path).metadata.num_row_groups > 1  # written incrementally
        get = lambda name: table.column(name).to_numpy(zero_copy_only=False).astype(float)  # noqa: E731
    assert columns == list(TABLE_COLUMNS + MAP_COLUMNS)
    expected = [(i, scan, kps) for i, (scan, kps) in enumerate(items) for _ in range(len(kps))]
    assert len(get("x")) == len(expected) == writer.n_keypoints
    np.testing.assert_array_equal(get("scan_index"), [e[0] for e in expected])
    np.testing.assert_array_equal(get("stamp"), [e[1].stamp for e in expected])
    all_kps = [(kps, j) for _, (_, kps) in enumerate(items) for j in range(len(kps))]
    np.testing.assert_array_equal(get("x"), [k.xy[j, 0] for k, j in all_kps])
    np.testing.assert_array_equal(
        get("opening_angle_deg"), [k.opening_angle_deg[j] for k, j in all_kps]
    )
    np.testing.assert_array_equal(get("n_merged"), [k.n_merged[j] for k, j in all_kps])
    map_x = get("map_x")
    no_pose = np.array([scan.pose is None for _, scan, _ in expected])
    assert no_pose.any() and np.isnan(map_x[no_pose]).all() and not np.isnan(map_x[~no_pose]).any()
    first = items[1]  # scan 1 has a pose and one keypoint
    start = sum(len(k) for _, k in items[:1])
    assert map_x[start] == pytest.approx(first[1].transformed(first[0].pose).xy[0, 0])


def test_csv_rows_are_on_disk_before_close(tmp_path: Path) -> None:
    path = tmp_path / "k.csv"
    writer = open_keypoint_writer(path, None, with_map=False, flush_every=1)  # type: ignore[arg-type]
    scan = LaserScan(np.ones(10), 0.0, 0.1, stamp=1.0)
    writer.write(0, scan, _keypoints(3))
    assert len(path.read_text().splitlines()) == 4  # header + 3 rows, not closed yet
    writer.close()


def test_interrupted_run_keeps_a_readable_parquet(tmp_path: Path) -> None:
    scans = list(open_scans(real_file("intel-corrected.clf.gz")))[:300]

    class Interrupting:
        path, kind, topic, skipped, skip_examples, position = (
            Path("x"),
            "npz",
            None,
            {},
            [],
            "row 0",
        )

        def __iter__(self) -> Iterator[LaserScan]:
            for i, scan in enumerate(scans):
                if i == 250:
                    raise KeyboardInterrupt
                self.position = f"row {i}"
                yield scan

    path = tmp_path / "k.parquet"
    writer = open_keypoint_writer(path, None, with_map=True, flush_every=100)  # type: ignore[arg-type]
    summary = detect_recording(Interrupting(), CornerDetector(), writer)  # type: ignore[arg-type]
    assert summary.interrupted and summary.n_scans == 250 and summary.position == "row 249"
    table = pq.read_table(path)
    assert table.num_rows == summary.n_keypoints > 0
    assert table.column("scan_index").to_numpy().max() <= 249


def test_unknown_output_suffix_and_bag_output_for_a_log(tmp_path: Path) -> None:
    source = open_scans(real_file("intel-corrected.clf.gz"))
    with pytest.raises(InputError, match=r"unknown output kind '\.txt'"):
        open_keypoint_writer(tmp_path / "k.txt", source, with_map=True)
    with pytest.raises(InputError, match="a bag output needs a bag input"):
        open_keypoint_writer(tmp_path / "k.bag", source, with_map=True)


# ----------------------------------------------------------------------------- bags
def test_fr079_keypoint_bag_reads_back_with_the_scan_stamps(tmp_path: Path) -> None:
    bag = real_file("fr079.bag")
    source = open_scans(bag)
    out = tmp_path / "fr079_corners.bag"
    detector = CornerDetector()
    writer = open_keypoint_writer(out, source, with_map=True)
    summary = detect_recording(source, detector, writer)
    assert summary.n_scans == 4934 and not summary.interrupted
    with pytest.raises(InputError, match="exists already"):
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


@pytest.mark.parametrize("suffix", [".csv", ".parquet"])
def test_write_many_writes_what_write_writes(tmp_path: Path, suffix: str) -> None:
    items = _scans_with_keypoints(7)
    one_by_one, chunked = tmp_path / f"a{suffix}", tmp_path / f"b{suffix}"
    with open_keypoint_writer(one_by_one, None, with_map=True, flush_every=2) as writer:  # type: ignore[arg-type]
        for i, (scan, kps) in enumerate(items):
            writer.write(i, scan, kps)
    with open_keypoint_writer(chunked, None, with_map=True, flush_every=2) as chunk_writer:  # type: ignore[arg-type]
        for start, stop in ((0, 3), (3, 4), (4, 7)):
            part = items[start:stop]
            chunk_writer.write_many(start, [s for s, _ in part], [k for _, k in part])
    assert (chunk_writer.n_scans, chunk_writer.n_keypoints) == (writer.n_scans, writer.n_keypoints)
    assert writer.n_keypoints > 0
    if suffix == ".csv":
        assert chunked.read_text() == one_by_one.read_text()
    else:
        assert pq.read_table(chunked).equals(pq.read_table(one_by_one))
    with pytest.raises(ValueError, match="2 scans but 1 keypoint sets"):
        chunk_writer.write_many(0, [items[0][0], items[1][0]], [items[0][1]])
