"""Helpers of the ROS 2 node tests for what goes to the node and comes back (imported as
``ros2_replay``; rclpy and the message packages are imported lazily).

fr079's scans (and its odometry) as ROS 2 messages, probes and paced publishing, the replay of
scans with odometry on ``/tf`` or a topic (:class:`Replay`, :func:`running`), and recorders of
the node's outputs (:class:`Outputs`: the detector's corners and markers; :class:`Received`:
the mapping modes' poses, transforms and map).
"""

from __future__ import annotations

import importlib.util
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
from ros2_tools import STARTUP_TIMEOUT, Ros2, torn_down
from ros_helpers import FR079, wait_for

from laser_corners import LaserScan
from laser_corners.pose import compose_many
from laser_corners.ros.convert import seconds_to_sec_nanosec

RATE_HZ = 40.0  # publishing rate (as in the ROS 1 test)
Key = tuple[int, int]
HAS_TF = importlib.util.find_spec("tf2_msgs") is not None
TOLERANCE = 0.1  # the node's default transform_tolerance: map -> odom is future-dated by it


def fr079_scans(n: int) -> list[LaserScan]:
    from laser_corners.io import open_scans

    return list(islice(open_scans(FR079), n))


def to_msg(scan: LaserScan, stamp: Key | None = None) -> Any:
    """A ROS 2 sensor_msgs/LaserScan with the scan's fields (stamp overridable)."""
    from sensor_msgs.msg import LaserScan as LaserScanMsg

    msg = LaserScanMsg()
    sec, nanosec = stamp if stamp is not None else seconds_to_sec_nanosec(scan.stamp)
    msg.header.stamp.sec, msg.header.stamp.nanosec = sec, nanosec
    msg.header.frame_id = scan.frame_id
    msg.angle_min = float(scan.angle_min)
    msg.angle_increment = float(scan.angle_increment)
    msg.angle_max = float(scan.angle_min + (scan.n_beams - 1) * scan.angle_increment)
    msg.range_min, msg.range_max = float(scan.range_min), float(scan.range_max)
    msg.ranges = np.asarray(scan.ranges, dtype=np.float32).tolist()
    return msg


def key_of(stamp: Any) -> Key:
    return (int(stamp.sec), int(stamp.nanosec))


class Outputs:
    """What the node published, by input stamp, with receive times (thread-safe)."""

    def __init__(self) -> None:
        self.lock = threading.Lock()
        self.corners: dict[Key, list[Any]] = {}
        self.order: list[Key] = []
        self.markers: dict[Key, list[Any]] = {}
        self.n_marker_arrays = 0
        self.received_at: dict[Key, float] = {}

    def on_corners(self, msg: Any) -> None:
        now = time.perf_counter()
        key = key_of(msg.header.stamp)
        with self.lock:
            self.corners.setdefault(key, []).append(msg)
            self.order.append(key)
            self.received_at.setdefault(key, now)

    def on_markers(self, msg: Any) -> None:
        with self.lock:
            self.n_marker_arrays += 1
            if msg.markers:
                self.markers.setdefault(key_of(msg.markers[0].header.stamp), []).append(msg)

    def count(self, keys: list[Key], markers: bool = False) -> int:
        table = self.markers if markers else self.corners
        with self.lock:
            return sum(k in table for k in keys)


def probe(
    pub: Any, scan: LaserScan, sec: int, answered: Callable[[Key], bool], proc: Any, what: str
) -> int:
    """Publish copies of ``scan`` stamped ``(sec, k)`` until one is ``answered``; return how
    many were sent.

    An answer proves the whole path is matched: our publisher -> the node's subscription, and
    the node's publisher -> our subscription (DDS discovery is asynchronous on each side).
    """
    deadline = time.monotonic() + STARTUP_TIMEOUT
    k = 0
    while time.monotonic() < deadline:
        pub.publish(to_msg(scan, (sec, k)))
        k += 1
        inner = time.monotonic() + 0.2
        while time.monotonic() < inner:
            if any(answered((sec, i)) for i in range(k)):
                return k
            time.sleep(0.01)
        if proc.poll() is not None:
            pytest.fail(f"{what}: the node exited with code {proc.returncode}")
    pytest.fail(f"timed out after {STARTUP_TIMEOUT:.0f} s waiting for {what}")


def fr079_with_odometry(
    n: int,
) -> tuple[list[Any], list[tuple[float, Any]], tuple[float, float, float]]:
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
            samples = [(t, planar(msg.pose.pose)) for t, msg in odometry]
        return compose_many(_transform(earlier[-1]), _interpolate(samples, stamp))


def planar(pose: Any) -> np.ndarray:
    from laser_corners.io.poses import yaw_from_quaternion

    o = pose.orientation
    return np.array([pose.position.x, pose.position.y, yaw_from_quaternion(o.x, o.y, o.z, o.w)])


def _transform(ts: Any) -> np.ndarray:
    from laser_corners.io.poses import yaw_from_quaternion

    t, r = ts.transform.translation, ts.transform.rotation
    return np.array([t.x, t.y, yaw_from_quaternion(r.x, r.y, r.z, r.w)])


def _interpolate(samples: list[tuple[float, np.ndarray]], stamp: float) -> np.ndarray:
    """The planar pose at ``stamp`` between timed samples (linear, yaw unwrapped; the first
    or last sample outside them, as the node's odometry track within its tolerance)."""
    assert samples, "no odometry"
    stamps = np.array([t for t, _ in samples])
    raw = np.array([pose for _, pose in samples])
    yaw = np.unwrap(raw[:, 2])
    return np.array([np.interp(stamp, stamps, column) for column in (raw[:, 0], raw[:, 1], yaw)])


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


def tf_args(mount: Any, tf: bool = HAS_TF) -> list[str]:
    """The node's odometry parameters: none with /tf; without it the topic and the mount."""
    if tf:
        return []
    return ["-p", "odom_topic:=odom", "-p", f"mount:=[{', '.join(map(str, mount))}]"]


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


def latched_map(ros2: Ros2, name: str, got: Received, proc: Any) -> list[Any]:
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
def running(
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


def probe_first(replay: Replay, scans, msgs, keys, got: Received, proc: Any, also=None) -> None:
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


def play_rest(replay: Replay, scans, msgs, keys) -> dict[Key, float]:
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


def offline_map(scans, folder: Path) -> np.ndarray:
    """The map of these scans, written by `laser-corners slam`'s writer; its scan poses."""
    from laser_corners.slam.output import SlamRunInfo
    from laser_corners.slam.run import run_slam
    from laser_corners.viz.slam_report import write_slam_outputs

    result = run_slam(FR079, stop_scan=len(scans))
    assert len(result.poses) == len(scans)
    folder.mkdir()
    write_slam_outputs(result, folder, SlamRunInfo(str(FR079), 1.0, 0.0))
    return np.asarray(result.poses)
