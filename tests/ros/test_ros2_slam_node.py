"""The ROS 2 node's ``mode:=slam`` (and ``mode:=localise``) over real DDS, fed with fr079.

As ``test_ros2_node.py`` (same isolation: a domain from the pid, loopback discovery, a
namespace per node): the node runs as ``laser-corners ros2 --ros-args -p mode:=slam``; this
process replays the first scans of ``fr079.bag`` with the bag's odometry on ``/tf`` and the
laser mount on ``/tf_static`` (``tf2_msgs``, which ``make test`` builds from
``ros2/interfaces/tf2_msgs`` with ``ros2/build_tf2_msgs.sh``), and looks up ``map ->
base_link`` from the ``/tf`` messages it receives (a small buffer: the latest ``map -> odom``
composed with ``odom -> base_link`` interpolated at the stamp; ``tf2_ros`` is not on PyPI).
Without ``tf2_msgs`` (skipped, failed in CI) odometry goes over ``nav_msgs/Odometry`` and
``map -> odom`` comes back on ``map_to_odom``; that fallback also runs with ``tf2_msgs``
hidden from the node.
"""

from __future__ import annotations

import importlib.util
import os
import re
import signal
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from itertools import islice
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from ros2_tools import (
    RATE_HZ,
    REAL_DDS_MARKS,
    STARTUP_TIMEOUT,
    Key,
    call_service,
    check_clean_exit,
    interrupt,
    key_of,
    one_error_line,
    to_msg,
    torn_down,
    wait_discovered,
    wait_exit,
)
from ros_helpers import FR079, isolated_message_packages, skip_or_fail, wait_for
from test_ros2_node import Ros2, isolated_ros2

from laser_corners.pose import compose_many, invert_many
from laser_corners.ros.convert import seconds_to_sec_nanosec

pytest.importorskip("gtsam")

pytestmark = REAL_DDS_MARKS

N_SCANS = 300  # the first 64 s of fr079
HAS_TF = importlib.util.find_spec("tf2_msgs") is not None
TOLERANCE = 0.1  # the node's default transform_tolerance: map -> odom is future-dated by it


@pytest.fixture(scope="module")
def ros2(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Ros2]:
    yield from isolated_ros2(tmp_path_factory)


def _fr079(n: int) -> tuple[list[Any], list[tuple[float, Any]], tuple[float, float, float]]:
    """The first ``n`` scans, the odometry messages up to 1 s after them, and the mount."""
    from rosbags.highlevel import AnyReader

    from laser_corners.pipeline.recording import open_recording

    with open_recording(FR079, None) as rec:
        scans = list(islice(rec.scans(), n))
        mount = rec.source.mounts[scans[0].frame_id]
    end = scans[-1].stamp + 1.0
    odometry = []
    with AnyReader([FR079]) as reader:
        connections = [c for c in reader.connections if c.topic == "/odom"]
        for connection, _, raw in reader.messages(connections=connections):
            msg = reader.deserialize(raw, connection.msgtype)
            stamp = msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9
            if stamp > end:
                break
            odometry.append((stamp, msg))
    return scans, odometry, mount


def _odometry_msg(bag_msg: Any) -> Any:
    from nav_msgs.msg import Odometry

    msg = Odometry()
    msg.header.stamp.sec = bag_msg.header.stamp.sec
    msg.header.stamp.nanosec = bag_msg.header.stamp.nanosec
    msg.header.frame_id, msg.child_frame_id = bag_msg.header.frame_id, bag_msg.child_frame_id
    for name in ("x", "y", "z"):
        setattr(msg.pose.pose.position, name, float(getattr(bag_msg.pose.pose.position, name)))
    for name in ("x", "y", "z", "w"):
        value = float(getattr(bag_msg.pose.pose.orientation, name))
        setattr(msg.pose.pose.orientation, name, value)
    return msg


def _tf_msg(parent: str, child: str, stamp: float, pose: Any) -> Any:
    from geometry_msgs.msg import TransformStamped
    from tf2_msgs.msg import TFMessage

    from laser_corners.ros.nav_convert import fill_transform

    ts = fill_transform(TransformStamped(), parent, child, pose)
    ts.header.stamp.sec, ts.header.stamp.nanosec = seconds_to_sec_nanosec(stamp)
    return TFMessage(transforms=[ts])


def _shift(key: Key, seconds: float) -> Key:
    """``key`` (sec, nanosec) plus ``seconds``."""
    sec, nanosec = divmod(key[0] * 10**9 + key[1] + round(seconds * 1e9), 10**9)
    return (sec, nanosec)


class Received:
    """Poses, map -> odom and odom -> base_link transforms by stamp, with receive times
    (thread-safe); ``tolerance``: the node's transform_tolerance."""

    def __init__(self, tolerance: float = TOLERANCE, tf: bool = HAS_TF) -> None:
        self.lock = threading.Lock()
        self.tolerance, self.tf = tolerance, tf
        self.poses: dict[Key, Any] = {}
        self.received_at: dict[Key, float] = {}
        self.map_to_odom: dict[Key, Any] = {}
        self.odom_tf: dict[Key, Any] = {}  # odom -> base_link seen on /tf (our replay's)
        self.grids: list[Any] = []
        self.metadata: list[Any] = []

    def on_pose(self, msg: Any) -> None:
        now = time.perf_counter()
        with self.lock:
            key = key_of(msg.header.stamp)
            self.poses.setdefault(key, msg)
            self.received_at.setdefault(key, now)

    def on_transform(self, msg: Any) -> None:
        transforms = getattr(msg, "transforms", [msg])
        with self.lock:
            for ts in transforms:
                if ts.child_frame_id == "odom" and ts.header.frame_id == "map":
                    self.map_to_odom.setdefault(key_of(ts.header.stamp), ts)
                elif ts.child_frame_id == "base_link" and ts.header.frame_id == "odom":
                    self.odom_tf.setdefault(key_of(ts.header.stamp), ts)

    def on_grid(self, msg: Any) -> None:
        with self.lock:
            self.grids.append(msg)

    def on_metadata(self, msg: Any) -> None:
        with self.lock:
            self.metadata.append(msg)

    def count(self, keys: list[Key]) -> int:
        with self.lock:
            return sum(k in self.poses and self.answered(k) for k in keys)

    def answered(self, key: Key) -> bool:
        """map -> odom of the scan stamped ``key`` came: stamped ``key + tolerance``."""
        return _shift(key, self.tolerance) in self.map_to_odom

    def lookup(self, stamp: float, odometry: list[tuple[float, Any]]) -> np.ndarray:
        """``map -> base_link`` at ``stamp``, as tf2 would look it up from what came on /tf:
        the latest map -> odom stamped at or before ``stamp + tolerance`` composed with
        odom -> base_link interpolated at ``stamp`` (from /tf; without tf2_msgs, the bag's
        odometry that went to the node as nav_msgs/Odometry)."""
        with self.lock:
            transforms = sorted(self.map_to_odom.items())
            odom = sorted(self.odom_tf.items())
        limit = stamp + self.tolerance + 1e-9
        earlier = [ts for k, ts in transforms if k[0] + k[1] * 1e-9 <= limit]
        assert earlier, f"no map -> odom at or before {stamp:.3f} + {self.tolerance} s"
        if self.tf:
            samples = [(k[0] + k[1] * 1e-9, _transform(ts)) for k, ts in odom]
        else:
            samples = [(t, _planar(msg.pose.pose)) for t, msg in odometry]
        return compose_many(_transform(earlier[-1]), _interpolate(samples, stamp))


def _planar(pose: Any) -> np.ndarray:
    from laser_corners.io.poses import yaw_from_quaternion

    o = pose.orientation
    return np.array([pose.position.x, pose.position.y, yaw_from_quaternion(o.x, o.y, o.z, o.w)])


def _transform(ts: Any) -> np.ndarray:
    from laser_corners.io.poses import yaw_from_quaternion

    t, r = ts.transform.translation, ts.transform.rotation
    return np.array([t.x, t.y, yaw_from_quaternion(r.x, r.y, r.z, r.w)])


class Replay:
    """Publishes fr079's scans with its odometry (topic or /tf), odometry slightly ahead."""

    def __init__(
        self, ros2: Ros2, name: str, odometry: list[tuple[float, Any]], mount, tf: bool = HAS_TF
    ) -> None:
        from nav_msgs.msg import Odometry
        from sensor_msgs.msg import LaserScan as LaserScanMsg

        node = ros2.node
        self.node, self.odometry, self.next_odom, self.tf = node, odometry, 0, tf
        self.jump: tuple[float, float] | None = None  # (from stamp, metres added to x): /tf
        self.scan_pub = node.create_publisher(LaserScanMsg, ros2.topic(name, "scan"), 1000)
        if tf:
            from rclpy.qos import DurabilityPolicy, QoSProfile
            from tf2_msgs.msg import TFMessage

            latched = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL)
            self.static_pub = node.create_publisher(TFMessage, "/tf_static", latched)
            self.static_pub.publish(_tf_msg("base_link", "laser", 0.0, mount))
            self.odom_pub = node.create_publisher(TFMessage, "/tf", 1000)
        else:
            self.odom_pub = node.create_publisher(Odometry, ros2.topic(name, "odom"), 1000)

    def odometry_until(self, stamp: float) -> None:
        while self.next_odom < len(self.odometry) and self.odometry[self.next_odom][0] <= stamp:
            msg = self.odometry[self.next_odom][1]
            if self.tf:
                p, o = msg.pose.pose.position, msg.pose.pose.orientation
                yaw = 2.0 * np.arctan2(o.z, o.w)
                at = self.odometry[self.next_odom][0]
                dx = self.jump[1] if self.jump is not None and at >= self.jump[0] else 0.0
                self.odom_pub.publish(_tf_msg("odom", "base_link", at, (p.x + dx, p.y, yaw)))
            else:
                self.odom_pub.publish(_odometry_msg(msg))
            self.next_odom += 1

    def destroy(self) -> None:
        self.node.destroy_publisher(self.scan_pub)
        self.node.destroy_publisher(self.odom_pub)
        if self.tf:
            self.node.destroy_publisher(self.static_pub)


def _tf_args(mount: Any, tf: bool = HAS_TF) -> list[str]:
    """The node's odometry parameters: none with /tf; without it the topic and the mount."""
    if tf:
        return []
    return ["-p", "odom_topic:=odom", "-p", f"mount:=[{', '.join(map(str, mount))}]"]


def _reference_poses(scans: list[Any], mount) -> np.ndarray:
    """Offline SLAM on the same inputs (scans rounded to float32 as the messages carry them)."""
    import dataclasses

    from laser_corners.slam import Slam

    slam = Slam(mount=mount)
    undo = invert_many(np.asarray(mount))
    out = []
    for scan in scans:
        scan32 = dataclasses.replace(scan, ranges=scan.ranges.astype(np.float32).astype(float))
        pose, _ = slam.add(scan32, compose_many(np.asarray(scan.pose), undo), scan.stamp)
        out.append(pose)
    return np.array(out)


def _subscribe(ros2: Ros2, name: str, got: Received, tf: bool = HAS_TF) -> list[Any]:
    """Our subscriptions to the node's pose and map -> odom."""
    from geometry_msgs.msg import PoseWithCovarianceStamped, TransformStamped

    node = ros2.node
    subs = [
        node.create_subscription(
            PoseWithCovarianceStamped, ros2.topic(name, "pose"), got.on_pose, 1000
        )
    ]
    if tf:
        from tf2_msgs.msg import TFMessage

        subs.append(node.create_subscription(TFMessage, "/tf", got.on_transform, 1000))
    else:
        topic = ros2.topic(name, "map_to_odom")
        subs.append(node.create_subscription(TransformStamped, topic, got.on_transform, 1000))
    return subs


def _latched_map(ros2: Ros2, name: str, got: Received, proc: Any) -> list[Any]:
    """Subscribe ``map`` and ``map_metadata`` now (a late subscriber, transient local) and
    wait for a grid and its metadata."""
    from nav_msgs.msg import MapMetaData, OccupancyGrid
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

    latched = QoSProfile(
        depth=1,
        durability=DurabilityPolicy.TRANSIENT_LOCAL,
        reliability=ReliabilityPolicy.RELIABLE,
    )
    node = ros2.node
    subs = [
        node.create_subscription(OccupancyGrid, ros2.topic(name, "map"), got.on_grid, latched),
        node.create_subscription(
            MapMetaData, ros2.topic(name, "map_metadata"), got.on_metadata, latched
        ),
    ]
    wait_for(lambda: got.grids and got.metadata, 20.0, "the latched map and metadata", proc)
    return subs


def _check_metadata(got: Received, grid: Any) -> None:
    """``map_metadata`` (latched) describes the latched grid, as map_server's does."""
    with got.lock:
        meta = got.metadata[-1]
    assert (meta.width, meta.height) == (grid.info.width, grid.info.height)
    assert meta.resolution == pytest.approx(grid.info.resolution)
    assert meta.origin.position.x == pytest.approx(grid.info.origin.position.x)
    assert meta.origin.position.y == pytest.approx(grid.info.origin.position.y)


@dataclass
class Run:
    """A node a test started, our subscriptions to it (``subs``), the replay into it and
    what else to destroy at teardown (``destroy``)."""

    proc: Any
    got: Received
    replay: Replay
    subs: list[Any]
    destroy: list[Callable[[], object]]


@contextmanager
def _running(
    ros2: Ros2,
    name: str,
    args: list[str],
    odometry: list[tuple[float, Any]],
    mount: Any,
    env: dict[str, str] | None = None,
    tf: bool = HAS_TF,
    tolerance: float = TOLERANCE,
) -> Iterator[Run]:
    """Start the node ``name`` with ``args``, subscribe its pose and map -> odom, replay
    into it; afterwards destroy all that and stop the node."""
    proc = ros2.start(name, *args, env=env)
    subs: list[Any] = []
    destroy: list[Callable[[], object]] = []
    with torn_down(ros2.node, proc, name, subs, destroy):
        got = Received(tolerance, tf)
        subs += _subscribe(ros2, name, got, tf)
        replay = Replay(ros2, name, odometry, mount, tf)
        destroy.append(replay.destroy)
        yield Run(proc, got, replay, subs, destroy)


def _wait_matched(ros2: Ros2, name: str, proc: Any) -> None:
    subscribers, publishers = (ros2.topic(name, "scan"),), (ros2.topic(name, "pose"),)
    what = "the node's scan subscription and pose publisher"
    wait_discovered(ros2.node, proc, what, subscribers, publishers)


def _probe_first(replay: Replay, scans, msgs, keys, got: Received, proc: Any, also=None) -> None:
    """The first scan, repeated until answered: proves the whole path matched (discovery)."""
    deadline = time.monotonic() + STARTUP_TIMEOUT
    while got.count(keys[:1]) == 0:
        assert time.monotonic() < deadline, "no pose for the first scan"
        assert proc.poll() is None, f"the node exited with code {proc.returncode}"
        replay.next_odom = 0  # again: the first ones may have gone before discovery matched
        replay.odometry_until(scans[0].stamp + 0.5)
        if also is not None:
            also()
        replay.scan_pub.publish(msgs[0])
        time.sleep(0.3)


def _play_rest(replay: Replay, scans, msgs, keys) -> dict[Key, float]:
    """Scans 1.. at RATE_HZ with the odometry 0.5 s ahead; the publish times."""
    published_at: dict[Key, float] = {}
    start = time.perf_counter()
    for i, msg in enumerate(msgs[1:], start=1):
        delay = start + i / RATE_HZ - time.perf_counter()
        if delay > 0:
            time.sleep(delay)
        replay.odometry_until(scans[i].stamp + 0.5)
        published_at[keys[i]] = time.perf_counter()
        replay.scan_pub.publish(msg)
    replay.odometry_until(np.inf)
    return published_at


def _play_all(ros2: Ros2, name: str, run: Run, scans, msgs, keys) -> None:
    """Wait for discovery, probe with the first scan, play the rest; wait for every pose."""
    _wait_matched(ros2, name, run.proc)
    _probe_first(run.replay, scans, msgs, keys, run.got, run.proc)
    _play_rest(run.replay, scans, msgs, keys)
    wait_for(lambda: run.got.count(keys) == len(keys), 60.0, "a pose for every scan", run.proc)


def _interpolate(samples: list[tuple[float, np.ndarray]], stamp: float) -> np.ndarray:
    """The planar pose at ``stamp`` between timed samples (linear, yaw unwrapped; the first
    or last sample outside them, as the node's odometry track within its tolerance)."""
    assert samples, "no odometry"
    stamps = np.array([t for t, _ in samples])
    raw = np.array([pose for _, pose in samples])
    yaw = np.unwrap(raw[:, 2])
    return np.array([np.interp(stamp, stamps, column) for column in (raw[:, 0], raw[:, 1], yaw)])


def _check_pose_messages(got: Received, keys, scans, odometry) -> np.ndarray:
    """map -> base_link looked up from /tf = the published pose; frames; covariance. The
    poses."""
    poses = []
    for key, scan in zip(keys, scans, strict=True):
        pose = _planar(got.poses[key].pose.pose)
        assert got.answered(key), f"scan {key}: no map -> odom stamped {got.tolerance} s later"
        # 5 mm: under load the node's odometry queue (keep last N) may drop a sample, so its
        # interpolation bracket can be wider than ours (0.5 mm seen); a wrong composition is
        # off by centimetres to metres
        np.testing.assert_allclose(got.lookup(scan.stamp, odometry)[:2], pose[:2], atol=5e-3)
        assert got.poses[key].header.frame_id == "map"
        cov = np.asarray(got.poses[key].pose.covariance).reshape(6, 6)
        assert cov[0, 0] > 0 and cov[1, 1] > 0 and cov[5, 5] > 0
        poses.append(pose)
    return np.array(poses).reshape(-1, 3)


def _latency(got: Received, published_at: dict[Key, float]) -> str:
    ms = np.array([got.received_at[k] - t for k, t in published_at.items() if k in got.poses])
    ms *= 1e3
    return (
        f"publish scan -> pose received over {ms.size} scans at {RATE_HZ:g} Hz: median "
        f"{np.median(ms):.2f} ms, p95 {np.percentile(ms, 95):.2f} ms, max {ms.max():.2f} ms"
    )


def test_slam_mode_end_to_end(ros2: Ros2, tmp_path: Path) -> None:
    """fr079 scans + odometry in: a pose and map -> odom per scan, /map latched, the map
    folder written at SIGINT."""
    scans, odometry, mount = _fr079(N_SCANS)
    msgs = [to_msg(s) for s in scans]
    keys = [key_of(m.header.stamp) for m in msgs]
    name, output = "lc_slam", tmp_path / "map"
    args = ["-p", "mode:=slam", "-p", "map_period:=1.0", "-p", f"output:={output}"]
    args += ["-p", f"queue_size:={N_SCANS}", *_tf_args(mount)]
    with _running(ros2, name, args, odometry, mount) as run:
        got = run.got
        _wait_matched(ros2, name, run.proc)
        _probe_first(run.replay, scans, msgs, keys, got, run.proc)
        published_at = _play_rest(run.replay, scans, msgs, keys)
        wait_for(lambda: got.count(keys) == N_SCANS, 60.0, "a pose for every scan", run.proc)
        time.sleep(1.5)  # one map_period after the last keyframe: the final grid
        run.subs += _latched_map(ros2, name, got, run.proc)  # a late subscriber gets it
        returncode = interrupt(run.proc)

    log = ros2.log(name)
    check_clean_exit(returncode, log)
    summary = re.search(r"stopped by SIGINT: (\d+) scans, (\d+) processed, (\d+) without", log)
    assert summary, log
    assert int(summary.group(2)) >= N_SCANS and int(summary.group(3)) == 0, log
    assert f"map written to {output}" in log, log
    node_poses = _check_pose_messages(got, keys, scans, odometry)
    # the node's SLAM is the library's: same poses as an offline run on the same inputs
    reference = _reference_poses(scans, mount)
    err = np.hypot(*(node_poses[:, :2] - reference[:, :2]).T)
    assert np.percentile(err, 95) < 0.05, f"node vs offline SLAM: p95 {np.percentile(err, 95)}"
    # the latched map: frame, size of the first 64 s of fr079, walls and free space
    grid = got.grids[-1]
    assert grid.header.frame_id == "map"
    assert grid.info.resolution == pytest.approx(0.05)
    width, height = grid.info.width * 0.05, grid.info.height * 0.05
    assert 5.0 < width < 100.0 and 5.0 < height < 100.0, (width, height)
    data = np.asarray(grid.data, dtype=np.int8)
    assert data.size == grid.info.width * grid.info.height
    assert set(np.unique(data).tolist()) <= {-1, 0, 100}  # trinary, as map_server publishes
    assert (data == 100).sum() > 500 and (data == 0).sum() > 5000
    _check_metadata(got, grid)
    for file in ("map.yaml", "map.pgm", "trajectory.tum", "summary.json", "keyframes.npz"):
        assert (output / file).is_file(), file  # the folder of `laser-corners slam`
    print(
        f"\nROS 2 slam node, fr079: {_latency(got, published_at)}; node vs offline SLAM "
        f"median {np.median(err) * 1e3:.2f} mm; grid {grid.info.width} x {grid.info.height}; "
        f"node log: {re.search(r'stopped by SIGINT: .*', log).group(0)}"
    )


def _offline_map(scans, folder: Path) -> np.ndarray:
    """The map of these scans, written by `laser-corners slam`'s writer; its scan poses."""
    from laser_corners.slam.output import SlamRunInfo
    from laser_corners.slam.run import run_slam
    from laser_corners.viz.slam_report import write_slam_outputs

    result = run_slam(FR079, stop_scan=len(scans))
    assert len(result.poses) == len(scans)
    folder.mkdir()
    write_slam_outputs(result, folder, SlamRunInfo(str(FR079), 1.0, 0.0))
    return np.asarray(result.poses)


def test_localise_mode_end_to_end(ros2: Ros2, tmp_path: Path) -> None:
    """The same fr079 scans localised in their map: /initialpose starts tracking, the poses
    stay on the map's trajectory, the saved map is latched on /map."""
    from geometry_msgs.msg import PoseWithCovarianceStamped

    from laser_corners.ros.nav_convert import fill_pose_with_covariance

    scans, odometry, mount = _fr079(N_SCANS)
    truth = _offline_map(scans, tmp_path / "map")
    msgs = [to_msg(s) for s in scans]
    keys = [key_of(m.header.stamp) for m in msgs]
    name = "lc_localise"
    args = ["-p", "mode:=localise", "-p", f"map:={tmp_path / 'map'}"]
    args += ["-p", f"queue_size:={N_SCANS}", "-p", "transform_tolerance:=0.25"]
    args += _tf_args(mount)
    initial = fill_pose_with_covariance(
        PoseWithCovarianceStamped(), truth[0], np.diag([0.01, 0.01, 0.003])
    )
    initial.header.frame_id = "map"
    with _running(ros2, name, args, odometry, mount, tolerance=0.25) as run:
        got, proc, replay = run.got, run.proc, run.replay
        initial_pub = ros2.node.create_publisher(PoseWithCovarianceStamped, "/initialpose", 10)
        run.destroy.append(lambda: ros2.node.destroy_publisher(initial_pub))
        run.subs += _latched_map(ros2, name, got, proc)  # at start: the saved map.pgm
        _wait_matched(ros2, name, proc)
        # no fix without it on the first scan: an answer proves /initialpose arrived
        _probe_first(replay, scans, msgs, keys, got, proc, lambda: initial_pub.publish(initial))
        published_at = _play_rest(replay, scans, msgs, keys)
        wait_for(lambda: got.count(keys[-1:]) == 1, 60.0, "a pose for the last scan", proc)
        restarted = _trigger(ros2, name, "reinitialize_global_localization", proc)
        assert restarted.success, restarted.message
        refused = _trigger(ros2, name, "serialize_map", proc)  # the map is the input here
        assert not refused.success and "mode slam" in refused.message, refused.message
        returncode = interrupt(proc, signal.SIGTERM)

    log = ros2.log(name)
    check_clean_exit(returncode, log)
    assert re.search(r"initial pose \[.*\] applied", log), log
    assert "reinitialize_global_localization: global search from the next scan" in log, log
    # every step of the core runs on the worker: no callback waits for it
    longest = re.search(r"longest callback ([\d.]+) ms", log)
    assert longest and float(longest.group(1)) < 50.0, log
    answered = [i for i, k in enumerate(keys) if k in got.poses and got.answered(k)]
    assert len(answered) >= 0.95 * N_SCANS, f"{len(answered)} of {N_SCANS} scans got a pose"
    poses = _check_pose_messages(
        got, [keys[i] for i in answered], [scans[i] for i in answered], odometry
    )
    err = np.hypot(*(poses[:, :2] - truth[answered, :2]).T)
    dyaw = np.degrees(np.abs(np.angle(np.exp(1j * (poses[:, 2] - truth[answered, 2])))))
    assert err.max() < 0.3 and dyaw.max() < 3.0, (err.max(), dyaw.max())
    grid = got.grids[0]
    saved = (tmp_path / "map" / "map.pgm").read_bytes()
    assert grid.info.width * grid.info.height == len(grid.data) and len(grid.data) < len(saved)
    data = np.asarray(grid.data, dtype=np.int8)
    assert set(np.unique(data).tolist()) == {-1, 0, 100}  # the same convention as slam's
    _check_metadata(got, grid)
    print(
        f"\nROS 2 localise node, fr079 in its own map: {_latency(got, published_at)}; "
        f"{len(answered)} of {N_SCANS} scans localised, max error {err.max() * 100:.1f} cm / "
        f"{dyaw.max():.2f} deg; node log: {re.search(r'stopped by SIGTERM: .*', log).group(0)}"
    )


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["-p", "mode:=mapping"], "ROS 2 parameter mode: unknown mode 'mapping'"),
        (["-p", "mode:=slam", "-p", "mape:=x"], "ROS 2 parameters: unknown parameter 'mape'"),
        (["-p", "mode:=localise"], "map: mode localise needs -p map:=DIR"),
        (["-p", "mode:=localise", "-p", "map:=/nonexistent/map"], "/nonexistent/map: no such"),
        (["-p", "mode:=slam", "-p", "map_period:=-1.0"], "ROS 2 parameters: map_period"),
    ],
)
def test_mapping_modes_refuse_bad_parameters(ros2: Ros2, args: list[str], message: str) -> None:
    name = f"lc_bad_{abs(hash(tuple(args))) % 10**6}"
    proc = ros2.start(name, *args)
    returncode = wait_exit(proc, f"bad parameters ({args})")
    log = ros2.log(name)
    assert returncode == 2, log
    assert "Traceback" not in log, log
    assert message in one_error_line(log), log


def test_tf2_msgs_is_importable() -> None:
    """``make test`` builds tf2_msgs into the venv (ros2/build_tf2_msgs.sh): /tf works."""
    if not HAS_TF:
        skip_or_fail("tf2_msgs is not importable: run ros2/build_tf2_msgs.sh .venv/bin/python")
    with isolated_message_packages():  # ROS 2's geometry_msgs, gone again afterwards
        from geometry_msgs.msg import TransformStamped
        from tf2_msgs.msg import TF2Error, TFMessage

        msg = TFMessage(transforms=[TransformStamped(child_frame_id="odom")])
        assert msg.transforms[0].child_frame_id == "odom" and TF2Error.LOOKUP_ERROR == 1


@pytest.fixture
def hidden_tf2_msgs(tmp_path: Path) -> dict[str, str]:
    """Environment of a node that cannot import tf2_msgs (a package on PYTHONPATH that raises
    ImportError shadows the built one), as with the PyPI wheels alone."""
    shadow = tmp_path / "shadow" / "tf2_msgs"
    shadow.mkdir(parents=True)
    (shadow / "__init__.py").write_text('raise ImportError("tf2_msgs hidden by the test")\n')
    path = os.pathsep.join(p for p in (str(shadow.parent), os.environ.get("PYTHONPATH")) if p)
    return {"PYTHONPATH": path}


def test_without_tf2_msgs_slam_mode_needs_an_odometry_topic(
    ros2: Ros2, hidden_tf2_msgs: dict[str, str]
) -> None:
    """Without tf2_msgs and without odom_topic: one line saying what to do, exit code 2."""
    name = "lc_no_tf"
    proc = ros2.start(name, "-p", "mode:=slam", env=hidden_tf2_msgs)
    returncode = wait_exit(proc, "mode slam without tf2_msgs")
    log = ros2.log(name)
    assert returncode == 2, log
    error = one_error_line(log)
    assert "-p odom_topic:=/odom" in error and "build_tf2_msgs.sh" in error, log


def test_without_tf2_msgs_map_to_odom_goes_to_a_topic(
    ros2: Ros2, hidden_tf2_msgs: dict[str, str]
) -> None:
    """The fallback: odometry from nav_msgs/Odometry, map -> odom (future-dated) on
    ``map_to_odom``, and one warning saying so."""
    n = 40
    scans, odometry, mount = _fr079(n)
    msgs = [to_msg(s) for s in scans]
    keys = [key_of(m.header.stamp) for m in msgs]
    name = "lc_fallback"
    args = ["-p", "mode:=slam", "-p", f"queue_size:={n}", *_tf_args(mount, tf=False)]
    with _running(ros2, name, args, odometry, mount, env=hidden_tf2_msgs, tf=False) as run:
        got = run.got
        _play_all(ros2, name, run, scans, msgs, keys)
        returncode = interrupt(run.proc)
    log = ros2.log(name)
    check_clean_exit(returncode, log)
    assert log.count("tf2_msgs is not importable") == 1, log
    assert "map -> odom goes to" in log and "map_to_odom" in log, log
    _check_pose_messages(got, keys, scans, odometry)


def _summary_counts(log: str, signal_name: str) -> dict[str, int]:
    """The scan counts of the node's shutdown line."""
    line = re.search(rf"stopped by {signal_name}: .*", log)
    assert line, log
    names = ("scans", "processed", "without odometry", "malformed", "still waiting")
    found = {n: re.search(rf"(\d+) {n}\b", line.group(0)) for n in names}
    assert all(found.values()), line.group(0)
    return {n: int(m.group(1)) for n, m in found.items()}


def _warnings(log: str) -> list[str]:
    return [line for line in log.splitlines() if line.startswith("[WARN]")]


@pytest.mark.parametrize("case", ["wrong base_frame", "no odometry"])
def test_missing_odometry_is_never_silent(ros2: Ros2, case: str) -> None:
    """Scans with odometry in other frames, or none at all: throttled warnings on stderr
    naming the frames and topics seen, and every scan counted in the summary."""
    n = 60  # 3 s at 20 Hz: past odom_timeout (2 s)
    scans, odometry, mount = _fr079(n)
    msgs = [to_msg(s) for s in scans]
    name = "lc_wrong_frame" if case == "wrong base_frame" else "lc_no_odom"
    args = ["-p", "mode:=slam", "-p", f"queue_size:={n}", "-p", "tf_wait:=0.5"]
    if case == "wrong base_frame":
        args += ["-p", "base_frame:=base_footprint"]
    proc = ros2.start(name, *args)
    destroy: list[Callable[[], object]] = []
    with torn_down(ros2.node, proc, name, [], destroy):
        replay = Replay(ros2, name, odometry, mount)
        destroy.append(replay.destroy)
        topics = (ros2.topic(name, "scan"), "/tf")
        wait_discovered(ros2.node, proc, "the node's scan and /tf subscriptions", topics)
        time.sleep(0.5)  # our side matched; give the node's side a moment (best effort)
        start = time.perf_counter()
        for i, msg in enumerate(msgs):
            time.sleep(max(0.0, start + i / 20.0 - time.perf_counter()))
            if case == "wrong base_frame":
                replay.odometry_until(scans[i].stamp + 0.5)
            replay.scan_pub.publish(msg)
        wait_for(lambda: "no odometry for" in ros2.log(name), 10.0, "the warning", proc)
        time.sleep(1.0)  # the last scans' tf_wait: dropped, not waiting
        returncode = interrupt(proc)
    log = ros2.log(name)
    check_clean_exit(returncode, log)
    warnings = _warnings(log)
    topic = ros2.topic(name, "scan")
    lost = [w for w in warnings if "no odometry for" in w]
    assert len(lost) == 1, log  # throttled: one in 3 s (every 5 s)
    assert f"while scans arrive on {topic}" in lost[0], lost
    dropped = [w for w in warnings if "dropped so far without odometry" in w]
    assert dropped and topic in dropped[0], log
    if case == "wrong base_frame":
        frames = [w for w in warnings if "no odometry in frames odom -> base_footprint" in w]
        assert frames and re.search(r"seen there: odom -> base_link \(\d+\)", frames[0]), log
        assert re.search(r"seen there: odom -> base_link \(\d+\)", lost[0]), lost
    else:
        assert "expecting odom -> (any child) on /tf (none yet); seen there: nothing" in lost[0]
    counts = _summary_counts(log, "SIGINT")
    assert counts["processed"] == 0 and counts["malformed"] == 0, log
    assert counts["without odometry"] + counts["still waiting"] == counts["scans"], log
    assert 0.9 * n <= counts["scans"] <= n and counts["without odometry"] >= 0.9 * n, log
    assert "0 odometry samples" in log, log


def _trigger(ros2: Ros2, name: str, service: str, proc: Any) -> Any:
    """Call the node's ``std_srvs/Trigger`` service ``service``; the response."""
    from std_srvs.srv import Trigger

    client = ros2.node.create_client(Trigger, ros2.topic(name, service))
    try:
        wait_for(client.service_is_ready, STARTUP_TIMEOUT, f"the {service} service", proc)
        return call_service(lambda: client.call_async(Trigger.Request()), service)
    finally:
        ros2.node.destroy_client(client)


def test_slam_services_write_the_map_while_running(ros2: Ros2, tmp_path: Path) -> None:
    """save_map writes map_server's files, serialize_map the folder `localise` reads, while
    the node runs; reinitialize_global_localization is refused in slam mode."""
    from laser_corners.io.occupancy import read_map
    from laser_corners.registration.mapfolder import load_map

    n = 60
    scans, odometry, mount = _fr079(n)
    msgs = [to_msg(s) for s in scans]
    keys = [key_of(m.header.stamp) for m in msgs]
    name, output = "lc_services", tmp_path / "live"
    args = ["-p", "mode:=slam", "-p", f"output:={output}", "-p", "queue_size:=60"]
    first = 40  # then the services; then the rest: mapping goes on after serialize_map
    with _running(ros2, name, args, odometry, mount) as run:
        got, proc, replay = run.got, run.proc, run.replay
        _wait_matched(ros2, name, proc)
        _probe_first(replay, scans, msgs, keys, got, proc)
        _play_rest(replay, scans[:first], msgs[:first], keys[:first])
        wait_for(lambda: got.count(keys[:first]) == first, 60.0, "the first poses", proc)
        assert not (output / "map.yaml").exists()
        saved = _trigger(ros2, name, "save_map", proc)
        assert saved.success and str(output / "map.yaml") in saved.message, saved.message
        grid = read_map(output / "map.yaml")
        assert (grid.occupancy == 100).sum() > 100 and (grid.occupancy == 0).sum() > 1000
        folder = _trigger(ros2, name, "serialize_map", proc)
        assert folder.success and str(output) in folder.message, folder.message
        saved_map = load_map(output)  # what `laser-corners localise` and mode:=localise read
        assert len(saved_map) >= 5 and saved_map.grid is not None
        refused = _trigger(ros2, name, "reinitialize_global_localization", proc)
        assert not refused.success and "mode localise" in refused.message, refused.message
        for i in range(first, n):
            replay.odometry_until(scans[i].stamp + 0.5)
            replay.scan_pub.publish(msgs[i])
            time.sleep(1.0 / RATE_HZ)
        replay.odometry_until(np.inf)
        wait_for(lambda: got.count(keys) == n, 60.0, "poses after serialize_map", proc)
        returncode = interrupt(proc)
    log = ros2.log(name)
    check_clean_exit(returncode, log)
    assert f"save_map: wrote {output / 'map.yaml'}" in log, log
    _check_pose_messages(got, keys, scans, odometry)  # the poses after it still fit the tf
    assert len(load_map(output)) > len(saved_map)  # the folder of the whole run at SIGINT


def test_an_unwritable_output_stops_the_node_at_start(ros2: Ros2, tmp_path: Path) -> None:
    """`output` is checked at start (not at shutdown, after the run): one line, exit 2."""
    blocker = tmp_path / "a_file"
    blocker.write_text("not a folder")
    name = "lc_bad_output"
    started = time.monotonic()
    proc = ros2.start(name, "-p", "mode:=slam", "-p", f"output:={blocker / 'map'}")
    returncode = wait_exit(proc, "an unwritable output")
    log = ros2.log(name)
    assert returncode == 2 and "Traceback" not in log, log
    assert f"output {blocker / 'map'}" in one_error_line(log), log
    assert time.monotonic() - started < STARTUP_TIMEOUT


def test_an_odometry_jump_is_never_silent(ros2: Ros2) -> None:
    """slam: the odometry teleports 5 m (a reset, a wrong message): a warning naming it and
    the count in the summary; the scans are still mapped."""
    n = 40
    scans, odometry, mount = _fr079(n)
    msgs = [to_msg(s) for s in scans]
    keys = [key_of(m.header.stamp) for m in msgs]
    name = "lc_jump"
    args = ["-p", "mode:=slam", "-p", f"queue_size:={n}"]
    with _running(ros2, name, args, odometry, mount) as run:
        run.replay.jump = ((scans[19].stamp + scans[20].stamp) / 2.0, 5.0)
        _play_all(ros2, name, run, scans, msgs, keys)
        returncode = interrupt(run.proc)
    log = ros2.log(name)
    check_clean_exit(returncode, log)
    jumps = [w for w in _warnings(log) if "odometry jumped" in w]
    assert len(jumps) == 1 and "odom -> base_link from /tf; max_odom_jump 1 m" in jumps[0], log
    found = re.search(r"odometry jumped (\d+\.\d+) m", jumps[0])
    assert found and 1.0 < float(found.group(1)) < 6.0, jumps
    summary = re.search(r"stopped by SIGINT: .*", log).group(0)
    found = re.search(r"(\d+) odometry jumps", summary)
    assert found and 1 <= int(found.group(1)) <= 2, summary  # the scan straddling it: 2
    assert _summary_counts(log, "SIGINT")["processed"] >= n, log  # + repeated probes
