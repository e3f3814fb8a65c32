"""Simulated drives for the tests: worlds, paths, odometry, a SLAM fed scan by scan, and bags.

* :func:`two_rooms`: the building of the SLAM tests (two rooms joined by a door, a pillar, a
  triangle, optionally a round post); :func:`straight`: poses along a leg at 0.05 m a scan;
* :func:`marked_building`: :func:`two_rooms` with two marks that break its near-symmetry
  (a 180° turn about the centre maps the pillar near the triangle); :func:`legs`: a drive
  along waypoints;
* :func:`noisy_odometry`: odometry from true poses with a scale error, a yaw bias and white
  noise (optionally no motion across chosen steps, a kidnap);
* :func:`drive_slam`: every scan of a drive through a world, fed to ``Slam.add``;
* :func:`write_drive_bag`: a ROS 1 ``.bag`` or ROS 2 MCAP bag of a drive with ``/tf_static``
  (``base_link -> laser``), ``/scan`` and any number of odometry sources
  (``nav_msgs/Odometry`` topics, an ``odom -> base_link`` on ``/tf``), each sampled 20 ms
  before and 30 ms after every scan (so a reader interpolates) and offset by its own amount,
  so a test can tell which source a reader took; :class:`BagMessages` builds the messages.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np
from rosbags.rosbag1 import Writer as Writer1
from rosbags.rosbag2 import StoragePlugin
from rosbags.rosbag2 import Writer as Writer2
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

from laser_corners.pose import between_many, compose, compose_many
from laser_corners.sim import SICK_LMS_1DEG, World

TF = "tf"
"""The odometry source written as ``odom -> base_link`` on ``/tf`` (else: a topic name)."""
TF_TYPE = "tf2_msgs/msg/TFMessage"
SCAN_TYPE = "sensor_msgs/msg/LaserScan"
ODOM_TYPE = "nav_msgs/msg/Odometry"


def two_rooms(post: bool = True) -> World:
    """Two rooms joined by a door, with a pillar and a triangle (and, with ``post``, a round
    post): structure in every direction."""
    world = World().add_polygon([[0, 0], [12, 0], [12, 8], [0, 8]])
    world.add_polygon([[6, 0], [6.1, 0], [6.1, 3], [6, 3]])
    world.add_polygon([[6, 5], [6.1, 5], [6.1, 8], [6, 8]])
    world.add_polygon([[2.5, 2.5], [3.3, 2.5], [3.3, 3.2], [2.5, 3.2]])
    world.add_polygon([[9, 5.5], [10, 5.5], [9.5, 6.4]])
    if post:
        world.add_circle((8.5, 2.0), 0.15)
    return world


def straight(a, b) -> list[tuple[float, float, float]]:
    """Poses from ``a`` towards ``b`` (``b`` excluded), 0.05 m apart, heading along the leg."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    heading = math.atan2(b[1] - a[1], b[0] - a[0])
    n = int(np.hypot(*(b - a)) / 0.05)
    return [(*(a + t * (b - a)), heading) for t in np.arange(n) / n]


def marked_building() -> World:
    """:func:`two_rooms` with a slanted corner (top left) and a second post (4, 6.5): no
    pose of the building looks like another."""
    world = two_rooms()
    world.add_polygon([[0, 7.0], [1.0, 8.0], [0, 8]])
    world.add_circle((4.0, 6.5), 0.2)
    return world


def legs(waypoints: Sequence[Sequence[float]], pause: int = 3) -> np.ndarray:
    """Poses along the legs between ``waypoints`` (:func:`straight`), ``pause`` scans at each
    waypoint after the first."""
    poses: list[tuple[float, float, float]] = []
    for a, b in itertools.pairwise(waypoints):
        poses += straight(a, b)
        heading = math.atan2(b[1] - a[1], b[0] - a[0])
        poses.extend((float(b[0]), float(b[1]), heading) for _ in range(pause))
    return np.array(poses)


def noisy_odometry(
    truth: np.ndarray,
    rng: np.random.Generator,
    scale: tuple[float, float, float] = (1.03, 1.02, 0.002),
    sigma: Sequence[float] = (0.004, 0.002, 0.003),
    still: Sequence[int] = (),
) -> np.ndarray:
    """Odometry of the true poses: each increment's forward step times ``scale[0]``, its turn
    times ``scale[1]`` plus the bias ``scale[2]``, plus white noise of ``sigma``; the steps
    into the scans ``still`` read no motion (the robot was carried)."""
    steps = between_many(truth[:-1], truth[1:])
    for i in still:
        steps[i - 1] = 0.0
    odo = [truth[0]]
    for d in steps:
        noisy = np.array([d[0] * scale[0], d[1], d[2] * scale[1] + scale[2]])
        noisy += rng.normal(0.0, sigma)
        odo.append(compose(odo[-1], noisy))
    return np.array(odo)


def drive_slam(
    slam,
    world: World,
    laser: np.ndarray,
    odometry: np.ndarray,
    stamps: np.ndarray,
    rng: np.random.Generator,
) -> None:
    """Feed ``slam`` the scans of ``world`` from the ``laser`` poses (SICK LMS, 1 deg, 1 cm
    noise) with their ``odometry`` poses and ``stamps``."""
    for pose, odom, stamp in zip(laser, odometry, stamps.tolist(), strict=True):
        scan = world.scan(tuple(pose), SICK_LMS_1DEG, noise_sigma=0.01, rng=rng, stamp=stamp)
        slam.add(scan, odom, stamp)


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
        sec, nanosec = divmod(round(stamp * 1e9), 10**9)
        time = self.t["builtin_interfaces/msg/Time"](sec=sec, nanosec=nanosec)
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

    def scan(self, stamp: float, scan, frame: str = "laser") -> object:
        return self.t[SCAN_TYPE](
            header=self.header(stamp, frame),
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
