"""What the ROS 2 node's ``slam`` and ``localise`` modes publish (rclpy).

:class:`MappingOutputs` holds the publishers: the base pose on ``pose``, ``map -> odom`` on
``/tf`` (future-dated by ``transform_tolerance``; on ``map_to_odom`` without ``tf2_msgs``),
the occupancy grid on ``map`` with its ``map_metadata`` and the landmarks (latched), and the
thread that builds the SLAM grid beside the worker.
"""

from __future__ import annotations

from collections.abc import Callable
from concurrent.futures import Future, ThreadPoolExecutor
from types import SimpleNamespace
from typing import Any

from laser_corners.errors import LaserCornersError
from laser_corners.io.occupancy import OccupancyGrid
from laser_corners.ros.convert import fill_marker_array, seconds_to_sec_nanosec
from laser_corners.ros.nav_convert import (
    fill_occupancy_grid,
    fill_pose_with_covariance,
    fill_transform,
    landmark_marker_fields,
)
from laser_corners.ros.slam_core import MappingCore, Update

__all__ = ["MappingOutputs", "latched_qos", "stamp_msg"]


def stamp_msg(m: SimpleNamespace, seconds: float) -> Any:
    """A ``builtin_interfaces/Time`` of ``seconds`` (negative: 0)."""
    sec, nanosec = seconds_to_sec_nanosec(max(seconds, 0.0))
    return m.Time(sec=sec, nanosec=nanosec)


def latched_qos(m: SimpleNamespace, depth: int = 1) -> Any:
    """Reliable, transient local (map_server's ``map`` QoS)."""
    return m.qos.QoSProfile(
        history=m.qos.HistoryPolicy.KEEP_LAST,
        depth=depth,
        reliability=m.qos.ReliabilityPolicy.RELIABLE,
        durability=m.qos.DurabilityPolicy.TRANSIENT_LOCAL,
    )


class MappingOutputs:
    """The publishers of the mapping modes on ``node`` and the grid-building thread.

    Parameters
    ----------
    node : rclpy.node.Node
        The node.
    m : SimpleNamespace
        The message classes (:func:`laser_corners.ros.ros2_mapping.messages`).
    core : MappingCore
        The core whose map, landmarks and odometry frame are published.
    """

    def __init__(self, node: Any, m: SimpleNamespace, core: MappingCore) -> None:
        self.node, self.m, self.core = node, m, core
        self.config = config = core.config
        depth = config.queue_size
        latched = latched_qos(m)
        self.pose_pub = node.create_publisher(m.PoseWithCovarianceStamped, "pose", depth)
        self.map_pub = node.create_publisher(m.OccupancyGrid, "map", latched)
        self.metadata_pub = node.create_publisher(m.MapMetaData, "map_metadata", latched)
        self.marker_pub = node.create_publisher(m.MarkerArray, "landmarks", latched)
        if m.tf is not None:
            self.tf_pub = node.create_publisher(m.tf, "/tf", 100)
        else:
            self.tf_pub = node.create_publisher(m.TransformStamped, "map_to_odom", depth)
        self.pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="grid")
        self.building: Future[OccupancyGrid] | None = None

    def publish(self, update: Update) -> None:
        """Pose and ``map -> odom`` of one processed scan (``map -> odom`` future-dated by
        ``transform_tolerance``, as AMCL does: valid until the next scan's)."""
        m, config = self.m, self.config
        pose = fill_pose_with_covariance(
            m.PoseWithCovarianceStamped(), update.pose, update.covariance
        )
        pose.header.stamp, pose.header.frame_id = stamp_msg(m, update.stamp), config.map_frame
        self.pose_pub.publish(pose)
        ts = fill_transform(
            m.TransformStamped(), config.map_frame, self.core.book.odom_frame, update.map_to_odom
        )
        ts.header.stamp = stamp_msg(m, update.stamp + config.transform_tolerance)
        self.tf_pub.publish(m.tf(transforms=[ts]) if m.tf is not None else ts)
        self.node.get_logger().debug(f"{update.status}: {update.ms:.2f} ms")

    def publish_map(self, grid: OccupancyGrid | None = None) -> None:
        """The grid (default: the core's) and landmarks on the latched topics."""
        grid = self.core.grid() if grid is None else grid
        if grid is None:
            return
        msg = fill_occupancy_grid(self.m.OccupancyGrid(), grid)
        msg.header.frame_id = self.config.map_frame
        msg.header.stamp = self.node.get_clock().now().to_msg()
        msg.info.map_load_time = msg.header.stamp
        self.map_pub.publish(msg)
        self.metadata_pub.publish(msg.info)
        markers = landmark_marker_fields(self.core.landmarks())
        if markers:
            m = self.m

            def duration(seconds: float) -> Any:
                sec, nanosec = seconds_to_sec_nanosec(seconds)
                return m.Duration(sec=sec, nanosec=nanosec)

            out = fill_marker_array(
                m.MarkerArray(), m.Marker, m.Point, duration, msg.header, markers
            )
            self.marker_pub.publish(out)

    def grid_step(self, skip: Callable[[str], None]) -> None:
        """On the worker: publish a grid the grid thread finished (``skip`` is told when it
        cannot be); start the next one when due (a snapshot of the keyframes, built beside
        the worker)."""
        if self.building is not None and self.building.done():
            future, self.building = self.building, None
            try:
                self.publish_map(future.result())
            except LaserCornersError as exc:
                skip(f"map not published: {exc}")
        if self.building is None and self.core.grid_due():
            job = self.core.grid_job()
            if job is not None:
                self.building = self.pool.submit(job)

    def close(self) -> None:
        """Stop the grid thread (a grid being built is dropped) and the publishers."""
        self.pool.shutdown(wait=False, cancel_futures=True)
        for pub in (self.pose_pub, self.map_pub, self.metadata_pub, self.marker_pub):
            self.node.destroy_publisher(pub)
        self.node.destroy_publisher(self.tf_pub)
