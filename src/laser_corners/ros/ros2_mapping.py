"""The rclpy adapter of the ROS 2 node's ``slam`` and ``localise`` modes.

``laser-corners ros2 --ros-args -p mode:=slam`` (or ``-p mode:=localise -p map:=DIR``, or
``-p map:=map.yaml`` for a map_server map another package made):

* subscribes ``scan`` (sensor-data QoS) and odometry: ``/tf`` (the ``odom -> base``
  transform) and ``/tf_static`` (the base -> laser mount) when ``tf2_msgs`` is importable,
  or a ``nav_msgs/Odometry`` topic (``-p odom_topic:=/odom``, with ``-p mount:=[x, y, yaw]``);
* publishes ``map -> odom`` on ``/tf``, future-dated by ``transform_tolerance`` (without
  ``tf2_msgs``: as a ``geometry_msgs/TransformStamped`` on ``map_to_odom``, with one warning;
  ``ros2/build_tf2_msgs.sh`` builds ``tf2_msgs`` for PyPI installs), the base pose as
  ``geometry_msgs/PoseWithCovarianceStamped`` on ``pose``, the occupancy grid on ``map``
  (``nav_msgs/OccupancyGrid``, cells -1/0/100 as map_server's; transient local: a late
  subscriber gets the last one; slam: every ``map_period`` s while keyframes are added;
  localise: the saved ``map.pgm`` once) and its ``nav_msgs/MapMetaData`` on ``map_metadata``
  (transient local), and
  landmarks on ``landmarks`` (``visualization_msgs/MarkerArray``) when there are any;
* localise: ``/initialpose`` (RViz's 2D Pose Estimate) sets the localiser's pose;
* slam: at shutdown, with ``-p output:=DIR``, writes the map folder as ``laser-corners slam``
  (``output`` is checked at start);
* ``std_srvs/Trigger`` services (:mod:`laser_corners.ros.ros2_services`): ``save_map``
  (map_server's map.yaml + map.pgm into ``output``), ``serialize_map`` (slam: the whole map
  folder into ``output``), ``deserialize_map`` (localise: load the map the ``map`` parameter
  names now) and ``reinitialize_global_localization`` (localise: search the whole map again);
* localise: AMCL's ``set_initial_pose`` / ``initial_pose.*`` parameters set the pose, at
  start or while running; every ``LocaliseOptions`` (slam: ``SlamOptions``) field is a
  parameter by its name (:mod:`laser_corners.ros.mapping_config`).

Every step of the core runs on one worker thread
(:class:`~laser_corners.ros.mapping_worker.MappingWorker`); the publishers are in
:mod:`laser_corners.ros.ros2_outputs`.

All decisions are in :mod:`laser_corners.ros.slam_core` (ROS-free, unit-tested); this module
turns messages into its calls and its results into messages.
"""

from __future__ import annotations

import time
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import numpy as np

from laser_corners.errors import InvalidParamsError, LaserCornersError, MissingDependencyError
from laser_corners.ros.convert import scan_from_msg
from laser_corners.ros.mapping_config import RUNTIME, MappingConfig, runtime_change
from laser_corners.ros.mapping_worker import MappingWorker
from laser_corners.ros.nav_convert import odometry_of, pose_with_covariance_of, transform_of
from laser_corners.ros.ros2_outputs import MappingOutputs, latched_qos
from laser_corners.ros.ros2_services import MappingServices
from laser_corners.ros.slam_core import MappingCore

__all__ = ["MappingAdapter", "messages"]

TF_HINT = (
    "tf2_msgs is not importable (ROS 2's PyPI wheels do not include it): build it into this "
    "Python with ros2/build_tf2_msgs.sh of the laser-corners checkout (make test does), or "
    "source a ROS 2 installation, or take odometry from a topic with -p odom_topic:=/odom "
    "(and the laser mount with -p mount:=[x,y,yaw])"
)
TF_FALLBACK = (
    "tf2_msgs is not importable: map -> odom goes to {topic} (geometry_msgs/TransformStamped), "
    "not /tf, and /tf_static is not read; build tf2_msgs with ros2/build_tf2_msgs.sh "
    "(docs/ros.md)"
)


def messages() -> SimpleNamespace:
    """The message and QoS classes of these modes (``tf`` is None without ``tf2_msgs``).

    Raises
    ------
    MissingDependencyError
        When ``nav_msgs`` is missing.
    """
    import builtin_interfaces.msg as builtin  # type: ignore[import-not-found]
    import geometry_msgs.msg as geometry  # type: ignore[import-not-found]
    import sensor_msgs.msg as sensor  # type: ignore[import-not-found]
    import visualization_msgs.msg as visualization  # type: ignore[import-not-found]
    from rclpy import qos  # type: ignore[import-not-found]
    from rclpy.event_handler import (  # type: ignore[import-not-found]
        SubscriptionEventCallbacks,
    )

    try:
        import nav_msgs.msg as nav  # type: ignore[import-not-found]
    except ImportError as exc:
        raise MissingDependencyError(
            f"nav_msgs is not importable ({exc}): pip install 'laser-corners[ros2]'"
        ) from None
    try:
        import tf2_msgs.msg as tf2  # type: ignore[import-not-found]
    except ImportError:
        tf2 = None
    try:
        from std_srvs.srv import Trigger  # type: ignore[import-not-found]
    except ImportError:
        Trigger = None
    return SimpleNamespace(
        Duration=builtin.Duration,
        Time=builtin.Time,
        Point=geometry.Point,
        PoseWithCovarianceStamped=geometry.PoseWithCovarianceStamped,
        TransformStamped=geometry.TransformStamped,
        LaserScan=sensor.LaserScan,
        Marker=visualization.Marker,
        MarkerArray=visualization.MarkerArray,
        OccupancyGrid=nav.OccupancyGrid,
        MapMetaData=nav.MapMetaData,
        Odometry=nav.Odometry,
        tf=None if tf2 is None else tf2.TFMessage,
        Trigger=Trigger,
        qos=qos,
        events=SubscriptionEventCallbacks,
    )


class MappingAdapter:
    """Subscriptions and callbacks of the mapping modes on ``node``.

    Made at start (or at a managed node's ``configure``): it checks the parameters, loads
    the map, checks ``output`` and creates the publishers
    (:class:`~laser_corners.ros.ros2_outputs.MappingOutputs`), the worker
    (:class:`~laser_corners.ros.mapping_worker.MappingWorker`) and the services
    (:class:`~laser_corners.ros.ros2_services.MappingServices`); :meth:`activate` subscribes,
    :meth:`deactivate` unsubscribes, :meth:`close` removes everything.

    Parameters
    ----------
    node : rclpy.node.Node
        The node (parameters already declared).
    values : dict
        The parameter values (``mode`` included).
    """

    def __init__(self, node: Any, values: dict[str, Any]) -> None:
        self.node = node
        self.m = m = messages()
        self.config = MappingConfig.from_mapping(values)
        self.core = MappingCore(self.config)  # reads and checks the map first
        if m.tf is None and not self.config.odom_topic:
            raise MissingDependencyError(TF_HINT)
        self.map_path = self.config.map
        """The ``map`` parameter now (``deserialize_map`` loads it)."""
        self.outputs = MappingOutputs(node, m, self.core)
        self.worker = MappingWorker(self.core, node.get_logger, self.outputs.publish)
        self.services = MappingServices(node, m, self.worker, self.outputs, lambda: self.map_path)
        self.subscriptions: list[Any] = []
        self.timer: Any = None
        self.started = time.monotonic()
        if m.tf is None:
            topic = self.outputs.tf_pub.topic_name
            node.get_logger().warning(TF_FALLBACK.format(topic=topic))

    def activate(self) -> None:
        """Subscribe the inputs and start the timer (scans are processed from now)."""
        m, node, config = self.m, self.node, self.config
        sensor = m.qos.QoSProfile(
            history=m.qos.HistoryPolicy.KEEP_LAST,
            depth=config.queue_size,
            reliability=m.qos.ReliabilityPolicy.BEST_EFFORT,
        )
        subs = self._odometry_subscriptions(sensor)
        events = m.events(message_lost=self.on_scans_lost)  # DDS's lost samples: counted
        scan_sub = node.create_subscription(
            m.LaserScan, "scan", self.on_scan, sensor, event_callbacks=events
        )
        self.core.watch.scan_topic = scan_sub.topic_name
        subs.append(scan_sub)
        if config.mode == "localise":
            subs.append(
                node.create_subscription(
                    m.PoseWithCovarianceStamped, "/initialpose", self.on_initial_pose, 10
                )
            )
            self.outputs.publish_map()
        self.subscriptions = subs
        self.timer = node.create_timer(1.0, self.on_timer)
        node.get_logger().info(
            f"mode {config.mode}: scans on {scan_sub.topic_name}, odometry from "
            f"{config.odom_topic or '/tf'}; publishing {self.outputs.pose_pub.topic_name}, "
            f"{self.outputs.map_pub.topic_name}"
        )

    def _odometry_subscriptions(self, sensor: Any) -> list[Any]:
        """Odometry (topic or /tf) and /tf_static."""
        m, node, config = self.m, self.node, self.config
        subs = []
        if config.odom_topic:
            subs.append(
                node.create_subscription(m.Odometry, config.odom_topic, self.on_odometry, sensor)
            )
        if m.tf is not None:
            tf_qos = m.qos.QoSProfile(  # tf2_ros's listener QoS (reliable), deeper queue
                history=m.qos.HistoryPolicy.KEEP_LAST,
                depth=max(config.queue_size, 100),
                reliability=m.qos.ReliabilityPolicy.RELIABLE,
            )
            if not config.odom_topic:
                subs.append(node.create_subscription(m.tf, "/tf", self.on_tf, tf_qos))
            static_qos = latched_qos(m, depth=100)
            subs.append(node.create_subscription(m.tf, "/tf_static", self.on_tf_static, static_qos))
        return subs

    def deactivate(self) -> None:
        """Unsubscribe and stop the timer (scans are no longer taken); the worker finishes
        what it has."""
        for sub in self.subscriptions:
            self.node.destroy_subscription(sub)
        self.subscriptions = []
        if self.timer is not None:
            self.node.destroy_timer(self.timer)
            self.timer = None
        self.worker.drain()

    def close(self) -> None:
        """Remove everything :meth:`__init__` made (a managed node's ``cleanup``)."""
        self.deactivate()
        self.worker.shutdown()
        self.services.close()
        self.outputs.close()

    def drain(self) -> None:
        """Wait until the worker has run every step submitted so far."""
        self.worker.drain()

    # ------------------------------------------------------------------ inputs
    def on_scan(self, msg: Any) -> None:
        """Hand the scan to the worker, unless ``queue_size`` scans still wait there (then it
        is dropped and counted)."""
        began = time.perf_counter()
        try:
            scan = scan_from_msg(msg)
        except LaserCornersError as exc:
            self.worker.post(self.core.malformed_scan, "a malformed scan")
            self.node.get_logger().warning(
                f"skipped a malformed scan: {exc}", throttle_duration_sec=5.0
            )
            return
        self.worker.offer_scan(scan)
        self.worker.timed(began)

    def on_scans_lost(self, info: Any) -> None:
        """The middleware lost scans before they reached the node (its queue overflowed, a
        best-effort sample went missing): counted, a throttled warning."""
        self.worker.lost = int(info.total_count)
        self.node.get_logger().warning(
            f"{info.total_count} scans lost before they reached the node (DDS)",
            throttle_duration_sec=5.0,
        )

    def on_odometry(self, msg: Any) -> None:
        """A ``nav_msgs/Odometry`` sample (booked and released on the worker)."""
        began = time.perf_counter()
        try:
            sample = odometry_of(msg)
        except LaserCornersError as exc:
            self.worker.skip(f"skipped an odometry message: {exc}")
            return

        def step() -> None:
            self.core.book.add_odometry(*sample)
            self.worker.run(self.core.release)

        self.worker.post(step, "an odometry message")
        self.worker.timed(began)

    def on_tf(self, msg: Any, static: bool = False) -> None:
        """A ``tf2_msgs/TFMessage`` on ``/tf`` (or ``/tf_static``), booked on the worker."""
        began = time.perf_counter()
        try:
            transforms = [transform_of(ts) for ts in msg.transforms]
        except LaserCornersError as exc:
            self.worker.skip(f"skipped a tf message: {exc}")
            return

        def step() -> None:
            self.core.book.add_transforms(transforms, static)
            self.worker.run(self.core.release)

        self.worker.post(step, "a tf message")
        self.worker.timed(began)

    def on_tf_static(self, msg: Any) -> None:
        """A ``/tf_static`` message."""
        self.on_tf(msg, static=True)

    def on_initial_pose(self, msg: Any) -> None:
        """RViz's 2D Pose Estimate: the localiser starts tracking from it."""
        try:
            frame, pose, cov = pose_with_covariance_of(msg)
        except LaserCornersError as exc:
            self.worker.skip(f"skipped an initial pose: {exc}")
            return
        if frame.lstrip("/") != self.config.map_frame:
            self.worker.skip(
                f"skipped an initial pose in frame {frame!r}, not {self.config.map_frame}"
            )
            return
        self.set_pose(pose, cov, "initial pose")

    def set_pose(self, pose: Any, covariance: Any, what: str) -> None:
        """Hand a pose to the localiser on the worker (logged there)."""

        def step() -> None:
            applied = self.core.set_pose(pose, covariance)
            self.node.get_logger().info(
                f"{what} {np.round(pose, 3).tolist()} "
                + ("applied" if applied else "ignored (mode slam)")
            )

        self.worker.post(step, f"an {what}" if what[0] in "aeiou" else f"a {what}")

    def on_timer(self) -> None:
        """On the worker: drop the scans that waited too long for odometry; publish a grid
        the grid thread finished; start the next one when due."""

        def step() -> None:
            self.worker.run(self.core.release)
            self.outputs.grid_step(self.worker.skip)

        self.worker.post(step, "the timer's step")

    # ------------------------------------------------------------------ lifecycle
    def set_parameters(self, parameters: list[Any]) -> tuple[bool, str]:
        """A run-time change (:func:`~laser_corners.ros.mapping_config.runtime_change`):
        localise takes ``map`` (``deserialize_map`` loads it) and AMCL's
        ``set_initial_pose`` / ``initial_pose.*`` (the pose is set now)."""
        changes = {p.name: p.value for p in parameters}
        current = {p.name: p.value for p in self.node.get_parameters(list(RUNTIME))}
        try:
            after = runtime_change(self.config.mode, changes, current)
        except InvalidParamsError as exc:
            return False, str(exc)
        if after is not None:
            self.map_path = after.map
            pose = after.pose()
            if pose is not None and set(changes) & set(RUNTIME) - {"map"}:
                self.set_pose(np.asarray(pose, dtype=np.float64), None, "initial_pose")
        return True, ""

    def summary(self) -> str:
        """The counts for the log line at shutdown, after the worker's queue and a last
        release (the scans whose ``tf_wait`` ran out count as dropped, not as waiting)."""
        worker = self.worker.summary()
        return f"{self.core.summary()}, {worker}"

    def shutdown(self) -> str | None:
        """Finish the worker's queue; slam with ``output``: write the map folder; a line
        saying where (or None)."""
        self.worker.shutdown()
        self.outputs.pool.shutdown(wait=False, cancel_futures=True)
        if not self.config.output:
            return None
        folder = self.core.write_map(Path(self.config.output), time.monotonic() - self.started)
        if folder is None:
            return f"nothing mapped: {self.config.output} not written"
        return f"map written to {folder}"


def check_mode(value: Any) -> str:
    """The ``mode`` parameter, checked."""
    if value not in ("detector", "slam", "localise"):
        raise InvalidParamsError(
            f"ROS 2 parameter mode: unknown mode {value!r}; choose detector, slam or localise"
        )
    return str(value)
