"""Odometry from ``/tf`` alone: a bag with no Odometry topic but an ``odom -> base_link``
``/tf`` (and ``/tf_static`` ``base_link -> laser``) maps as the same bag with the Odometry."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("gtsam")

from rosbags.rosbag1 import Writer as Writer1
from rosbags.rosbag2 import StoragePlugin
from rosbags.rosbag2 import Writer as Writer2
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

from laser_corners.errors import InputError
from laser_corners.io import open_scans
from laser_corners.io.rosbag import tf_odometry
from laser_corners.pose import compose_many
from laser_corners.sim import SICK_LMS_1DEG, World
from laser_corners.slam import SlamOptions, run_slam

RATE = 10.0
MOUNT = (0.2, 0.0, 0.0)


def _world() -> World:
    world = World().add_polygon([[0, 0], [10, 0], [10, 6], [0, 6]])
    world.add_polygon([[3, 2], [3.8, 2], [3.8, 2.6], [3, 2.6]])
    world.add_polygon([[7, 3.5], [7.6, 3.5], [7.3, 4.3]])
    return world


def _drive() -> np.ndarray:
    """Base poses: along a room, a turn, back (0.4 m/s)."""
    out = [(1.5 + 0.04 * i, 1.2, 0.0) for i in range(150)]
    out += [(7.5, 1.2, 0.1 * k) for k in range(1, 16)]
    out += [(7.5 - 0.04 * i * math.cos(0.0), 1.2 + 0.03 * i, 1.5) for i in range(60)]
    return np.array(out)


class _Bag:
    """Messages of a drive in one typestore, for ROS 1 or ROS 2 writers."""

    def __init__(self, ros2: bool) -> None:
        self.ros2 = ros2
        self.store = get_typestore(Stores.ROS2_HUMBLE if ros2 else Stores.ROS1_NOETIC)
        if "tf2_msgs/msg/TFMessage" not in self.store.types:
            text = "geometry_msgs/TransformStamped[] transforms"
            self.store.register(get_types_from_msg(text, "tf2_msgs/msg/TFMessage"))
        self.t = self.store.types

    def ser(self, msg: object, msgtype: str) -> bytes:
        if self.ros2:
            return self.store.serialize_cdr(msg, msgtype)
        return self.store.serialize_ros1(msg, msgtype)

    def header(self, stamp: float, frame: str) -> object:
        sec = math.floor(stamp)
        time = self.t["builtin_interfaces/msg/Time"](sec=sec, nanosec=round((stamp - sec) * 1e9))
        if self.ros2:
            return self.t["std_msgs/msg/Header"](stamp=time, frame_id=frame)
        return self.t["std_msgs/msg/Header"](seq=0, stamp=time, frame_id=frame)

    def tf(self, stamp: float, parent: str, child: str, pose) -> object:
        t = self.t
        x, y, yaw = (float(v) for v in pose)
        return t["geometry_msgs/msg/TransformStamped"](
            header=self.header(stamp, parent),
            child_frame_id=child,
            transform=t["geometry_msgs/msg/Transform"](
                translation=t["geometry_msgs/msg/Vector3"](x=x, y=y, z=0.0),
                rotation=t["geometry_msgs/msg/Quaternion"](
                    x=0.0, y=0.0, z=math.sin(yaw / 2), w=math.cos(yaw / 2)
                ),
            ),
        )

    def odometry(self, stamp: float, pose) -> object:
        t = self.t
        x, y, yaw = (float(v) for v in pose)
        vec = t["geometry_msgs/msg/Vector3"](x=0.0, y=0.0, z=0.0)
        return t["nav_msgs/msg/Odometry"](
            header=self.header(stamp, "odom"),
            child_frame_id="base_link",
            pose=t["geometry_msgs/msg/PoseWithCovariance"](
                pose=t["geometry_msgs/msg/Pose"](
                    position=t["geometry_msgs/msg/Point"](x=x, y=y, z=0.0),
                    orientation=t["geometry_msgs/msg/Quaternion"](
                        x=0.0, y=0.0, z=math.sin(yaw / 2), w=math.cos(yaw / 2)
                    ),
                ),
                covariance=np.zeros(36),
            ),
            twist=t["geometry_msgs/msg/TwistWithCovariance"](
                twist=t["geometry_msgs/msg/Twist"](linear=vec, angular=vec),
                covariance=np.zeros(36),
            ),
        )

    def scan(self, stamp: float, scan) -> object:
        return self.t["sensor_msgs/msg/LaserScan"](
            header=self.header(stamp, "laser"),
            angle_min=scan.angle_min,
            angle_max=scan.angle_min + scan.angle_increment * (scan.n_beams - 1),
            angle_increment=scan.angle_increment,
            time_increment=0.0,
            scan_time=0.0,
            range_min=scan.range_min,
            range_max=scan.range_max,
            ranges=scan.ranges.astype(np.float32),
            intensities=np.zeros(0, np.float32),
        )


def _write(path: Path, odometry: str, ros2: bool = False, tf_map: bool = False) -> Path:
    """A bag of the drive: ``odometry`` is ``topic`` (nav_msgs/Odometry on /odom), ``tf``
    (odom -> base_link on /tf) or ``none``; ``tf_map`` adds a moving map -> odom above it."""
    world, base = _world(), _drive()
    odo = base  # noise-free odometry (the same in every bag)
    laser = compose_many(base, np.asarray(MOUNT))
    rng = np.random.default_rng(5)
    bag = _Bag(ros2)
    tf_type, scan_type = "tf2_msgs/msg/TFMessage", "sensor_msgs/msg/LaserScan"
    odom_type = "nav_msgs/msg/Odometry"
    writer = Writer2(path, version=9, storage_plugin=StoragePlugin.MCAP) if ros2 else Writer1(path)
    with writer:
        static = writer.add_connection("/tf_static", tf_type, typestore=bag.store)
        scans = writer.add_connection("/scan", scan_type, typestore=bag.store)
        if odometry == "topic":
            odom = writer.add_connection("/odom", odom_type, typestore=bag.store)
        if odometry == "tf":
            tf = writer.add_connection("/tf", tf_type, typestore=bag.store)
        mount = bag.tf(0.0, "base_link", "laser", MOUNT)
        writer.write(static, 0, bag.ser(bag.t[tf_type](transforms=[mount]), tf_type))
        for i, pose in enumerate(laser):
            stamp = 1.0 + i / RATE
            ns = round(stamp * 1e9)
            scan = world.scan(tuple(pose), SICK_LMS_1DEG, noise_sigma=0.01, rng=rng, stamp=stamp)
            # the odometry 20 ms before the scan and 30 ms after: it is interpolated
            for dt in (-0.02, 0.03):
                s = stamp + dt
                j = min(max(i + dt * RATE, 0.0), len(odo) - 1)
                lo = math.floor(j)
                hi = min(lo + 1, len(odo) - 1)
                p = odo[lo] + (j - lo) * (odo[hi] - odo[lo])
                if odometry == "topic":
                    writer.write(odom, round(s * 1e9), bag.ser(bag.odometry(s, p), odom_type))
                elif odometry == "tf":
                    found = [bag.tf(s, "odom", "base_link", p)]
                    if tf_map:
                        found.append(bag.tf(s, "map", "odom", (0.001 * i, 0.0, 0.0)))
                    msg = bag.t[tf_type](transforms=found)
                    writer.write(tf, round(s * 1e9), bag.ser(msg, tf_type))
            writer.write(scans, ns, bag.ser(bag.scan(stamp, scan), scan_type))
    return path


@pytest.mark.parametrize("ros2", [False, True], ids=["ros1", "ros2-mcap"])
def test_slam_from_tf_odometry_equals_the_odometry_topic_run(tmp_path: Path, ros2) -> None:
    ext = "" if ros2 else ".bag"
    with_topic = _write(tmp_path / f"topic{ext}", "topic", ros2)
    with_tf = _write(tmp_path / f"tf{ext}", "tf", ros2, tf_map=True)
    source = open_scans(with_tf)
    scans = list(source)
    assert source.odom_topic == "/tf" and source.tf_odometry == ("odom", "base_link")
    assert all(s.pose is not None for s in scans)
    options = SlamOptions(loop_closure=False)
    a = run_slam(with_topic, options)
    b = run_slam(with_tf, options)
    assert a.counts["scans"] == b.counts["scans"] == len(_drive())
    np.testing.assert_allclose(b.odometry, a.odometry, atol=1e-9)
    np.testing.assert_allclose(b.poses, a.poses, atol=1e-9)
    np.testing.assert_allclose(b.mount, MOUNT)
    # and the trajectory is the true one (noise-free odometry, a good map)
    assert np.abs(b.poses[:, :2] - _drive()[:, :2]).max() < 0.05


def test_bag_with_neither_odometry_nor_tf_is_one_line(tmp_path: Path) -> None:
    path = _write(tmp_path / "none.bag", "none")
    with pytest.raises(InputError, match="no odometry") as info:
        run_slam(path)
    assert "\n" not in str(info.value) and str(path) in str(info.value)


def test_tf_odometry_picks_the_moving_transform_nearest_above_the_laser() -> None:
    moving = {
        ("map", "odom"): [(0.0, 0.0, 0.0, 0.0), (1.0, 0.1, 0.0, 0.0)],
        ("odom", "base_link"): [(1.0, 1.0, 0.0, 0.0), (0.0, 0.0, 0.0, 0.0)],
        ("base_link", "wheel"): [(0.0, 0.1, 0.0, 0.0), (1.0, 0.1, 0.0, 0.0)],  # constant
    }
    static = {"laser": "base_link", "base_link": "odom", "odom": "map", "wheel": "base_link"}
    found = tf_odometry("/laser", static, moving, Path("x.bag"))
    assert found is not None
    edge, samples = found
    assert edge == ("odom", "base_link") and [s[0] for s in samples] == [0.0, 1.0]
    # the laser not linked: the only moving transform, or one line naming the candidates
    only = {("odom", "base_link"): moving[("odom", "base_link")]}
    found = tf_odometry("other", static, only, Path("x.bag"))
    assert found is not None and found[0] == ("odom", "base_link")
    with pytest.raises(InputError, match=r"map -> odom, odom -> base_link.*'other'") as info:
        tf_odometry("other", static, moving, Path("x.bag"))
    assert "\n" not in str(info.value) and "x.bag" in str(info.value)
    # nothing moves: no odometry
    still = {("base_link", "wheel"): moving[("base_link", "wheel")]}
    assert tf_odometry("laser", static, still, Path("x.bag")) is None
