"""Bags of a simulated drive, for tests: ROS 1 ``.bag`` or ROS 2 MCAP, with any number of
``nav_msgs/Odometry`` topics and an ``odom -> base_link`` on ``/tf``.

:func:`write_drive_bag` writes ``/tf_static`` (``base_link -> laser``), ``/scan`` (the world
seen from each laser pose) and the odometry sources it is given, each sampled 20 ms before
and 30 ms after every scan (so a reader interpolates). Every source is the drive plus its own
offset, so a test can tell which source a reader took.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np
from rosbags.rosbag1 import Writer as Writer1
from rosbags.rosbag2 import StoragePlugin
from rosbags.rosbag2 import Writer as Writer2
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

from laser_corners.pose import compose_many
from laser_corners.sim import SICK_LMS_1DEG, World

TF = "tf"
"""The odometry source written as ``odom -> base_link`` on ``/tf`` (else: a topic name)."""
TF_TYPE = "tf2_msgs/msg/TFMessage"
SCAN_TYPE = "sensor_msgs/msg/LaserScan"
ODOM_TYPE = "nav_msgs/msg/Odometry"


class BagMessages:
    """Messages of a drive in one typestore, for the ROS 1 or ROS 2 writers."""

    def __init__(self, ros2: bool) -> None:
        self.ros2 = ros2
        self.store = get_typestore(Stores.ROS2_HUMBLE if ros2 else Stores.ROS1_NOETIC)
        if TF_TYPE not in self.store.types:
            text = "geometry_msgs/TransformStamped[] transforms"
            self.store.register(get_types_from_msg(text, TF_TYPE))
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

    def quaternion(self, yaw: float) -> object:
        q = self.t["geometry_msgs/msg/Quaternion"]
        return q(x=0.0, y=0.0, z=math.sin(yaw / 2), w=math.cos(yaw / 2))

    def tf(self, stamp: float, parent: str, child: str, pose) -> object:
        t = self.t
        x, y, yaw = (float(v) for v in pose)
        return t["geometry_msgs/msg/TransformStamped"](
            header=self.header(stamp, parent),
            child_frame_id=child,
            transform=t["geometry_msgs/msg/Transform"](
                translation=t["geometry_msgs/msg/Vector3"](x=x, y=y, z=0.0),
                rotation=self.quaternion(yaw),
            ),
        )

    def odometry(self, stamp: float, pose) -> object:
        t = self.t
        x, y, yaw = (float(v) for v in pose)
        vec = t["geometry_msgs/msg/Vector3"](x=0.0, y=0.0, z=0.0)
        return t[ODOM_TYPE](
            header=self.header(stamp, "odom"),
            child_frame_id="base_link",
            pose=t["geometry_msgs/msg/PoseWithCovariance"](
                pose=t["geometry_msgs/msg/Pose"](
                    position=t["geometry_msgs/msg/Point"](x=x, y=y, z=0.0),
                    orientation=self.quaternion(yaw),
                ),
                covariance=np.zeros(36),
            ),
            twist=t["geometry_msgs/msg/TwistWithCovariance"](
                twist=t["geometry_msgs/msg/Twist"](linear=vec, angular=vec),
                covariance=np.zeros(36),
            ),
        )

    def scan(self, stamp: float, scan) -> object:
        return self.t[SCAN_TYPE](
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


def _odometry_at(base: np.ndarray, i: int, dt: float, rate: float) -> np.ndarray:
    """The base pose ``dt`` seconds after scan ``i`` (linear between the scans)."""
    j = min(max(i + dt * rate, 0.0), len(base) - 1)
    lo = math.floor(j)
    hi = min(lo + 1, len(base) - 1)
    return base[lo] + (j - lo) * (base[hi] - base[lo])


def write_drive_bag(
    path: Path,
    world: World,
    base: np.ndarray,
    mount: Sequence[float],
    odometry: Mapping[str, Sequence[float]],
    *,
    ros2: bool = False,
    tf_map: bool = False,
    rate: float = 10.0,
) -> Path:
    """A bag of the drive ``base`` (base poses, one per scan, scans at ``rate`` Hz from 1 s).

    Parameters
    ----------
    odometry : mapping of str to (dx, dy, dyaw)
        Each odometry source and the offset added to its poses: a ``nav_msgs/Odometry``
        topic name (``odom -> base_link``), or :data:`TF` for ``odom -> base_link`` on
        ``/tf``. Empty: no odometry.
    ros2 : bool
        A ROS 2 bag with MCAP storage (``path`` is its folder) instead of a ROS 1 bag.
    tf_map : bool
        With a :data:`TF` source, a moving ``map -> odom`` above it on ``/tf``.
    """
    laser = compose_many(base, np.asarray(mount))
    rng = np.random.default_rng(5)
    bag = BagMessages(ros2)
    writer = Writer2(path, version=9, storage_plugin=StoragePlugin.MCAP) if ros2 else Writer1(path)
    with writer:
        static = writer.add_connection("/tf_static", TF_TYPE, typestore=bag.store)
        scans = writer.add_connection("/scan", SCAN_TYPE, typestore=bag.store)
        connections = {
            source: writer.add_connection(
                "/tf" if source == TF else source,
                TF_TYPE if source == TF else ODOM_TYPE,
                typestore=bag.store,
            )
            for source in odometry
        }
        mount_tf = bag.tf(0.0, "base_link", "laser", mount)
        writer.write(static, 0, bag.ser(bag.t[TF_TYPE](transforms=[mount_tf]), TF_TYPE))
        for i, pose in enumerate(laser):
            stamp = 1.0 + i / rate
            scan = world.scan(tuple(pose), SICK_LMS_1DEG, noise_sigma=0.01, rng=rng, stamp=stamp)
            for dt in (-0.02, 0.03):  # the odometry 20 ms before the scan and 30 ms after
                s, ns = stamp + dt, round((stamp + dt) * 1e9)
                p = _odometry_at(base, i, dt, rate)
                for source, offset in odometry.items():
                    q = p + np.asarray(offset, dtype=np.float64)
                    if source != TF:
                        msg = bag.ser(bag.odometry(s, q), ODOM_TYPE)
                        writer.write(connections[source], ns, msg)
                        continue
                    found = [bag.tf(s, "odom", "base_link", q)]
                    if tf_map:
                        found.append(bag.tf(s, "map", "odom", (0.001 * i, 0.0, 0.0)))
                    msg = bag.ser(bag.t[TF_TYPE](transforms=found), TF_TYPE)
                    writer.write(connections[source], ns, msg)
            writer.write(scans, round(stamp * 1e9), bag.ser(bag.scan(stamp, scan), SCAN_TYPE))
    return path
