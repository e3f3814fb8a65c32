"""Simulated scan sequences written to disk: NPZ scans, NPZ ground truth, a ROS 1 bag.

Files written by :func:`simulate_sequence` + :func:`write_sequence` (``laser-corners
simulate``):

``scans.npz``
    The scans in the NPZ layout of :mod:`laser_corners.io.arrays` (``ranges`` (S, N) with
    ``inf`` for no return, ``angle_min``, ``angle_increment``, ``range_min``, ``range_max``,
    ``stamps`` (S,), ``poses`` (S, 3) = sensor ``x, y, theta`` in the world frame,
    ``frame_id``), so every reader and command of the package opens it.
``truth.npz``
    ``corners`` (C, 2): every corner of the world, world frame; ``corner_angles_deg`` (C,);
    ``visible`` (S, C) bool: which corners each scan sees (see
    :meth:`~laser_corners.sim.World.visible_corner_mask`); ``segments`` (W, 4) walls;
    ``circles`` (M, 3) round obstacles; ``poses`` (S, 3); ``stamps`` (S,); ``noise_sigma``,
    ``probe``, ``min_beams`` (scalars); ``sensor`` and ``world`` (names).
``scans.bag``
    ROS 1 bag: ``/scan`` (``sensor_msgs/msg/LaserScan``, frame ``laser``), ``/odom``
    (``nav_msgs/msg/Odometry``, frame ``map``, child frame ``laser``: the exact sensor pose,
    so :func:`laser_corners.io.open_scans` gives every scan its pose) and
    ``/sim/visible_corners`` (``geometry_msgs/msg/PoseArray``, frame ``laser``: the visible
    true corners in the sensor frame), all stamped with the scan's time.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray
from rosbags.rosbag1 import Writer
from rosbags.typesys import Stores, get_typestore

from laser_corners.io.arrays import write_scans_npz
from laser_corners.scan import LaserScan
from laser_corners.sim.checks import check_number
from laser_corners.sim.sensors import SensorProfile
from laser_corners.sim.worlds import World

__all__ = ["SimSequence", "simulate_sequence", "write_bag", "write_sequence"]


@dataclass(frozen=True)
class SimSequence:
    """Scans of a drive through a world, with the ground truth."""

    world: World
    sensor: SensorProfile
    scans: list[LaserScan]
    poses: NDArray[np.float64]
    visible: NDArray[np.bool_]
    noise_sigma: float
    probe: float
    min_beams: float

    @property
    def stamps(self) -> NDArray[np.float64]:
        """Scan times, seconds."""
        return np.array([s.stamp for s in self.scans], dtype=np.float64)

    def visible_corners(self, index: int) -> NDArray[np.float64]:
        """The true corners seen by scan ``index``, sensor frame, shape (V, 2)."""
        corners = self.world.corners[self.visible[index]]
        return self.world.to_sensor_frame(corners, tuple(self.poses[index]))


def simulate_sequence(
    world: World,
    sensor: SensorProfile,
    poses: NDArray[np.float64],
    noise_sigma: float,
    rng: np.random.Generator,
    start_time: float = 0.0,
    probe: float = 0.25,
    min_beams: float = 4.0,
) -> SimSequence:
    """Scan ``world`` from each pose (stamped at the sensor's rate) with its ground truth.

    Raises
    ------
    InvalidParamsError
        ``noise_sigma`` is negative or not finite.
    """
    noise_sigma = check_number("noise_sigma", noise_sigma)
    scans = []
    visible = np.zeros((len(poses), len(world.corners)), dtype=bool)
    for i, p in enumerate(poses):
        pose = (float(p[0]), float(p[1]), float(p[2]))
        stamp = start_time + i / sensor.rate_hz
        scans.append(world.scan(pose, sensor, noise_sigma=noise_sigma, rng=rng, stamp=stamp))
        visible[i] = world.visible_corner_mask(pose, sensor, probe=probe, min_beams=min_beams)
    return SimSequence(
        world,
        sensor,
        scans,
        np.asarray(poses, dtype=np.float64),
        visible,
        noise_sigma,
        probe,
        min_beams,
    )


def write_sequence(sequence: SimSequence, output: Path, bag: bool = True) -> dict[str, Path]:
    """Write ``scans.npz``, ``truth.npz`` and (with ``bag``) ``scans.bag`` into ``output``."""
    output.mkdir(parents=True, exist_ok=True)
    paths = {"scans": output / "scans.npz", "truth": output / "truth.npz"}
    write_scans_npz(paths["scans"], sequence.scans)
    world = sequence.world
    np.savez(
        paths["truth"],
        corners=world.corners,
        corner_angles_deg=world.corner_angles_deg,
        visible=sequence.visible,
        segments=world.segments,
        circles=np.asarray(world.circles).reshape(-1, 3),
        poses=sequence.poses,
        stamps=sequence.stamps,
        noise_sigma=np.float64(sequence.noise_sigma),
        probe=np.float64(sequence.probe),
        min_beams=np.float64(sequence.min_beams),
        sensor=np.str_(sequence.sensor.name),
        world=np.str_(world.name),
    )
    if bag:
        paths["bag"] = output / "scans.bag"
        write_bag(sequence, paths["bag"])
    return paths


def _time(typestore: object, stamp: float) -> object:
    sec = math.floor(stamp)
    return typestore.types["builtin_interfaces/msg/Time"](  # type: ignore[attr-defined]
        sec=int(sec), nanosec=round((stamp - sec) * 1e9)
    )


def write_bag(sequence: SimSequence, path: Path) -> None:
    """Write the sequence as a ROS 1 bag (topics in the module docstring); replaces ``path``."""
    store = get_typestore(Stores.ROS1_NOETIC)
    t = store.types
    scan_type, odom_type, array_type = (
        "sensor_msgs/msg/LaserScan",
        "nav_msgs/msg/Odometry",
        "geometry_msgs/msg/PoseArray",
    )
    header_cls = t["std_msgs/msg/Header"]
    point_cls, quat_cls, pose_cls = (
        t["geometry_msgs/msg/Point"],
        t["geometry_msgs/msg/Quaternion"],
        t["geometry_msgs/msg/Pose"],
    )

    def pose_msg(x: float, y: float, yaw: float) -> object:
        return pose_cls(
            position=point_cls(x=x, y=y, z=0.0),
            orientation=quat_cls(x=0.0, y=0.0, z=math.sin(yaw / 2), w=math.cos(yaw / 2)),
        )

    if path.exists():
        path.unlink()
    sensor = sequence.sensor
    with Writer(path) as writer:
        c_scan = writer.add_connection("/scan", scan_type, typestore=store)
        c_pose = writer.add_connection("/odom", odom_type, typestore=store)
        c_corners = writer.add_connection("/sim/visible_corners", array_type, typestore=store)
        for i, scan in enumerate(sequence.scans):
            stamp = float(scan.stamp if scan.stamp is not None else i / sensor.rate_hz)
            t_ns = round(stamp * 1e9)
            laser = header_cls(seq=i, stamp=_time(store, stamp), frame_id=scan.frame_id)
            world_header = header_cls(seq=i, stamp=_time(store, stamp), frame_id="map")
            msg = t[scan_type](
                header=laser,
                angle_min=scan.angle_min,
                angle_max=scan.angle_min + scan.angle_increment * (scan.n_beams - 1),
                angle_increment=scan.angle_increment,
                time_increment=0.0,
                scan_time=1.0 / sensor.rate_hz,
                range_min=scan.range_min,
                range_max=scan.range_max,
                ranges=scan.ranges.astype(np.float32),
                intensities=np.zeros(0, dtype=np.float32),
            )
            writer.write(c_scan, t_ns, store.serialize_ros1(msg, scan_type))
            x, y, yaw = (float(v) for v in sequence.poses[i])
            odom = t[odom_type](
                header=world_header,
                child_frame_id=scan.frame_id,
                pose=t["geometry_msgs/msg/PoseWithCovariance"](
                    pose=pose_msg(x, y, yaw), covariance=np.zeros(36)
                ),
                twist=t["geometry_msgs/msg/TwistWithCovariance"](
                    twist=t["geometry_msgs/msg/Twist"](
                        linear=t["geometry_msgs/msg/Vector3"](x=0.0, y=0.0, z=0.0),
                        angular=t["geometry_msgs/msg/Vector3"](x=0.0, y=0.0, z=0.0),
                    ),
                    covariance=np.zeros(36),
                ),
            )
            writer.write(c_pose, t_ns, store.serialize_ros1(odom, odom_type))
            corners = sequence.visible_corners(i)
            pa = t[array_type](
                header=laser, poses=[pose_msg(float(cx), float(cy), 0.0) for cx, cy in corners]
            )
            writer.write(c_corners, t_ns, store.serialize_ros1(pa, array_type))
