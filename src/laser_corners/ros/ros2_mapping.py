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
* ``std_srvs/Trigger`` services: ``save_map`` (map_server's map.yaml + map.pgm into
  ``output``), ``serialize_map`` (slam: the whole map folder into ``output``) and
  ``reinitialize_global_localization`` (localise: search the whole map again).

All decisions are in :mod:`laser_corners.ros.slam_core` (ROS-free, unit-tested); this module
turns messages into its calls and its results into messages.
"""

from __future__ import annotations

import threading
import time
from concurrent.futures import Future, ThreadPoolExecutor
from pathlib import Path
from types import SimpleNamespace
from typing import Any

from laser_corners.errors import (
    InvalidParamsError,
    LaserCornersError,
    MissingDependencyError,
    first_line,
)
from laser_corners.io.occupancy import OccupancyGrid
from laser_corners.ros.convert import fill_marker_array, scan_from_msg, seconds_to_sec_nanosec
from laser_corners.ros.nav_convert import (
    fill_occupancy_grid,
    fill_pose_with_covariance,
    fill_transform,
    landmark_marker_fields,
    odometry_of,
    pose_with_covariance_of,
    transform_of,
)
from laser_corners.ros.slam_core import MappingConfig, MappingCore, Update

__all__ = ["MappingAdapter", "messages"]

TF_HINT = (
    "tf2_msgs is not importable (ROS 2's PyPI wheels do not include it): build it into this "
    "Python with ros2/build_tf2_msgs.sh of the laser-corners checkout (make test does), or "
    "source a ROS 2 installation, or take odometry from a topic with -p odom_topic:=/odom "
    "(and the laser mount with -p mount:=[x,y,yaw])"
)
NO_OUTPUT = "no output folder: start the node with -p output:=DIR"
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
    )


def _stamp(m: SimpleNamespace, seconds: float) -> Any:
    sec, nanosec = seconds_to_sec_nanosec(max(seconds, 0.0))
    return m.Time(sec=sec, nanosec=nanosec)


class MappingAdapter:
    """Publishers, subscriptions and callbacks of the mapping modes on ``node``.

    Parameters
    ----------
    node : rclpy.node.Node
        The node (parameters already declared).
    values : dict
        The parameter values given at start (``mode`` included).
    """

    def __init__(self, node: Any, values: dict[str, Any]) -> None:
        self.node = node
        self.m = m = messages()
        self.config = MappingConfig.from_mapping(values)
        self.core = MappingCore(self.config)  # reads and checks the map first
        self.pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="grid")
        self.building: Future[OccupancyGrid] | None = None
        self.worker = ThreadPoolExecutor(max_workers=1, thread_name_prefix="mapping")
        """Every step of the core (scans, odometry, initial poses, services) runs here, in
        arrival order: no callback waits for a global search or an optimisation."""
        self.pending = 0  # scans submitted to the worker and not yet processed
        self.lock = threading.Lock()
        self.busy_drops = 0  # scans dropped because the worker was still busy
        self.callback_ms = 0.0  # the longest callback
        if m.tf is None and not self.config.odom_topic:
            raise MissingDependencyError(TF_HINT)
        self.started = time.monotonic()
        self.n_skipped = 0
        depth = self.config.queue_size
        sensor = m.qos.QoSProfile(
            history=m.qos.HistoryPolicy.KEEP_LAST,
            depth=depth,
            reliability=m.qos.ReliabilityPolicy.BEST_EFFORT,
        )
        latched = m.qos.QoSProfile(
            history=m.qos.HistoryPolicy.KEEP_LAST,
            depth=1,
            reliability=m.qos.ReliabilityPolicy.RELIABLE,
            durability=m.qos.DurabilityPolicy.TRANSIENT_LOCAL,
        )
        self.pose_pub = node.create_publisher(m.PoseWithCovarianceStamped, "pose", depth)
        self.map_pub = node.create_publisher(m.OccupancyGrid, "map", latched)
        self.metadata_pub = node.create_publisher(m.MapMetaData, "map_metadata", latched)
        self.marker_pub = node.create_publisher(m.MarkerArray, "landmarks", latched)
        self._subscribe(sensor, latched, depth)
        if m.tf is None:
            node.get_logger().warning(TF_FALLBACK.format(topic=self.tf_pub.topic_name))
        scan_sub = node.create_subscription(m.LaserScan, "scan", self.on_scan, sensor)
        self.core.watch.scan_topic = scan_sub.topic_name
        if self.config.mode == "localise":
            node.create_subscription(
                m.PoseWithCovarianceStamped, "/initialpose", self.on_initial_pose, 10
            )
            self.publish_map()
        node.create_timer(1.0, self.on_timer)
        self._services()
        odometry = self.config.odom_topic or "/tf"
        node.get_logger().info(
            f"mode {self.config.mode}: scans on {scan_sub.topic_name}, odometry "
            f"from {odometry}; publishing {self.pose_pub.topic_name}, {self.map_pub.topic_name}"
        )

    def _subscribe(self, sensor: Any, latched: Any, depth: int) -> None:
        """Odometry (topic or /tf) and /tf_static subscriptions; the map -> odom publisher."""
        m, node = self.m, self.node
        if self.config.odom_topic:
            node.create_subscription(m.Odometry, self.config.odom_topic, self.on_odometry, sensor)
        if m.tf is not None:
            tf_qos = m.qos.QoSProfile(  # tf2_ros's listener QoS (reliable), deeper queue
                history=m.qos.HistoryPolicy.KEEP_LAST,
                depth=max(depth, 100),
                reliability=m.qos.ReliabilityPolicy.RELIABLE,
            )
            static_qos = m.qos.QoSProfile(
                history=m.qos.HistoryPolicy.KEEP_LAST,
                depth=100,
                reliability=m.qos.ReliabilityPolicy.RELIABLE,
                durability=m.qos.DurabilityPolicy.TRANSIENT_LOCAL,
            )
            if not self.config.odom_topic:
                node.create_subscription(m.tf, "/tf", self.on_tf, tf_qos)
            node.create_subscription(m.tf, "/tf_static", self.on_tf_static, static_qos)
            self.tf_pub = node.create_publisher(m.tf, "/tf", 100)
        else:
            self.tf_pub = node.create_publisher(m.TransformStamped, "map_to_odom", depth)

    def _services(self) -> None:
        """``std_srvs/Trigger`` services: save_map, serialize_map,
        reinitialize_global_localization (a warning without std_srvs)."""
        m, node = self.m, self.node
        if m.Trigger is None:
            node.get_logger().warning(
                "std_srvs is not importable: no save_map, serialize_map or "
                "reinitialize_global_localization services (pip install 'laser-corners[ros2]')"
            )
            return
        node.create_service(m.Trigger, "save_map", self.on_save_map)
        node.create_service(m.Trigger, "serialize_map", self.on_serialize_map)
        node.create_service(m.Trigger, "reinitialize_global_localization", self.on_reinitialize)

    # ------------------------------------------------------------------ services
    def _answer(self, response: Any, service: str, step: Any) -> Any:
        """Fill a Trigger response from ``step() -> (success, message)``, run on the worker
        (after the scans before it); log it."""
        try:
            ok, text = self._submit(step).result()
        except LaserCornersError as exc:
            ok, text = False, first_line(exc)
        response.success, response.message = bool(ok), text
        if ok:  # two call sites: rclpy refuses one site logging at two severities
            self.node.get_logger().info(f"{service}: {text}")
        else:
            self.node.get_logger().warning(f"{service}: {text}")
        return response

    def on_save_map(self, request: Any, response: Any) -> Any:
        """``save_map``: map_server's map.yaml + map.pgm of the current grid into ``output``."""

        def step() -> tuple[bool, str]:
            if not self.config.output:
                return False, NO_OUTPUT
            path = self.core.save_grid(Path(self.config.output))
            return True, f"wrote {path}, {path.with_suffix('.pgm')}"

        return self._answer(response, "save_map", step)

    def on_serialize_map(self, request: Any, response: Any) -> Any:
        """``serialize_map`` (slam): the whole map folder (what ``localise`` reads) into
        ``output``, as at shutdown."""

        def step() -> tuple[bool, str]:
            if self.config.mode != "slam":
                return False, "mode localise: the map is the input here (needs mode slam)"
            if not self.config.output:
                return False, NO_OUTPUT
            wall = time.monotonic() - self.started
            folder = self.core.write_map(Path(self.config.output), wall)
            if folder is None:
                return False, "nothing mapped yet"
            return True, f"wrote the map folder {folder}"

        return self._answer(response, "serialize_map", step)

    def on_reinitialize(self, request: Any, response: Any) -> Any:
        """``reinitialize_global_localization`` (localise): search the whole map again."""

        def step() -> tuple[bool, str]:
            if self.core.reinitialize():
                return True, "global search from the next scan"
            return False, "nothing to reinitialize in mode slam (mode localise only)"

        return self._answer(response, "reinitialize_global_localization", step)

    # ------------------------------------------------------------------ inputs
    def on_scan(self, msg: Any) -> None:
        """Hand the scan to the worker, unless ``queue_size`` scans still wait there (then it
        is dropped and counted)."""
        began = time.perf_counter()
        try:
            scan = scan_from_msg(msg)
        except LaserCornersError as exc:
            self._post(self.core.malformed_scan, "a malformed scan")
            self.node.get_logger().warning(
                f"skipped a malformed scan: {exc}", throttle_duration_sec=5.0
            )
            return
        with self.lock:
            full = self.pending >= self.config.queue_size
            self.pending += not full
            self.busy_drops += full
        if full:
            self.node.get_logger().warning(
                "scans dropped: the worker is busy (a global search or an optimisation)",
                throttle_duration_sec=5.0,
            )
        else:
            self._post(lambda: self._scan_step(scan), "a scan")
        self._timed(began)

    def _scan_step(self, scan: Any) -> None:
        try:
            self._run(lambda: self.core.add_scan(scan))
        finally:
            with self.lock:
                self.pending -= 1

    def drain(self) -> None:
        """Wait until the worker has run every step submitted so far."""
        self._submit(lambda: None).result()

    def _submit(self, step: Any) -> Future[Any]:
        """Run ``step`` on the worker (in arrival order); the caller reads its result."""
        return self.worker.submit(step)

    def _post(self, step: Any, what: str) -> None:
        """Run ``step`` on the worker, nobody waiting: a known error skips ``what`` (logged,
        counted), any other is an error line; none is lost in an unread future."""

        def guarded() -> None:
            try:
                step()
            except LaserCornersError as exc:
                self._skip(f"skipped {what}: {exc}")
            except Exception as exc:  # a bug: keep the node alive, show the error
                self.n_skipped += 1
                self.node.get_logger().error(f"{what} failed: {exc!r}")

        self._submit(guarded)

    def _timed(self, began: float) -> None:
        self.callback_ms = max(self.callback_ms, (time.perf_counter() - began) * 1e3)

    def on_odometry(self, msg: Any) -> None:
        """A ``nav_msgs/Odometry`` sample (booked and released on the worker)."""
        began = time.perf_counter()
        try:
            sample = odometry_of(msg)
        except LaserCornersError as exc:
            self._skip(f"skipped an odometry message: {exc}")
            return

        def step() -> None:
            self.core.book.add_odometry(*sample)
            self._run(self.core.release)

        self._post(step, "an odometry message")
        self._timed(began)

    def on_tf(self, msg: Any, static: bool = False) -> None:
        """A ``tf2_msgs/TFMessage`` on ``/tf`` (or ``/tf_static``), booked on the worker."""
        began = time.perf_counter()
        try:
            transforms = [transform_of(ts) for ts in msg.transforms]
        except LaserCornersError as exc:
            self._skip(f"skipped a tf message: {exc}")
            return

        def step() -> None:
            self.core.book.add_transforms(transforms, static)
            self._run(self.core.release)

        self._post(step, "a tf message")
        self._timed(began)

    def on_tf_static(self, msg: Any) -> None:
        """A ``/tf_static`` message."""
        self.on_tf(msg, static=True)

    def on_initial_pose(self, msg: Any) -> None:
        """RViz's 2D Pose Estimate: the localiser starts tracking from it."""
        try:
            frame, pose, cov = pose_with_covariance_of(msg)
        except LaserCornersError as exc:
            self._skip(f"skipped an initial pose: {exc}")
            return
        if frame.lstrip("/") != self.config.map_frame:
            self._skip(f"skipped an initial pose in frame {frame!r}, not {self.config.map_frame}")
            return

        def step() -> None:
            applied = self.core.set_pose(pose, cov)
            self.node.get_logger().info(
                f"initial pose {pose.round(3).tolist()} "
                + ("applied" if applied else "ignored (mode slam)")
            )

        self._post(step, "an initial pose")

    def _skip(self, text: str) -> None:
        self.n_skipped += 1
        self.node.get_logger().warning(text, throttle_duration_sec=5.0)

    def _run(self, step: Any) -> None:
        """Run a core step, publish what it released, log the watch's warnings due."""
        updates = []
        try:
            updates = step()
        except LaserCornersError as exc:
            self._skip(f"scan skipped: {exc}")
        except Exception as exc:  # a bug: keep the node alive, show the error
            self.n_skipped += 1
            self.node.get_logger().error(f"scan processing failed: {exc!r}")
        for update in updates:
            self.publish(update)
        for text in self.core.watch.warnings(self.core.book):
            self.node.get_logger().warning(text)

    # ------------------------------------------------------------------ outputs
    def publish(self, update: Update) -> None:
        """Pose and ``map -> odom`` of one processed scan (``map -> odom`` future-dated by
        ``transform_tolerance``, as AMCL does: valid until the next scan's)."""
        m, config = self.m, self.config
        stamp = _stamp(m, update.stamp)
        pose = fill_pose_with_covariance(
            m.PoseWithCovarianceStamped(), update.pose, update.covariance
        )
        pose.header.stamp, pose.header.frame_id = stamp, config.map_frame
        self.pose_pub.publish(pose)
        ts = fill_transform(
            m.TransformStamped(), config.map_frame, self.core.book.odom_frame, update.map_to_odom
        )
        ts.header.stamp = _stamp(m, update.stamp + config.transform_tolerance)
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
            header = msg.header

            def duration(seconds: float) -> Any:
                sec, nanosec = seconds_to_sec_nanosec(seconds)
                return m.Duration(sec=sec, nanosec=nanosec)

            out = fill_marker_array(m.MarkerArray(), m.Marker, m.Point, duration, header, markers)
            self.marker_pub.publish(out)

    def on_timer(self) -> None:
        """On the worker: drop the scans that waited too long for odometry; publish a grid
        the grid thread finished; start the next one when due."""
        self._post(self._timer_step, "the timer's step")

    def _timer_step(self) -> None:
        self._run(self.core.release)
        if self.building is not None and self.building.done():
            future, self.building = self.building, None
            try:
                self.publish_map(future.result())
            except LaserCornersError as exc:
                self._skip(f"map not published: {exc}")
        if self.building is None and self.core.grid_due():
            job = self.core.grid_job()
            if job is not None:
                self.building = self.pool.submit(job)

    # ------------------------------------------------------------------ lifecycle
    def set_parameters(self, parameters: list[Any]) -> tuple[bool, str]:
        """Parameters of these modes are read at start only."""
        ours = [p.name for p in parameters if p.name in MappingConfig.model_fields]
        if ours:
            return False, f"{', '.join(ours)}: read at start only in mode {self.config.mode}"
        return True, ""

    def summary(self) -> str:
        """The counts for the log line at shutdown, after the worker's queue and a last
        release (the scans whose ``tf_wait`` ran out count as dropped, not as waiting)."""
        self._submit(lambda: self._run(self.core.release)).result()
        return (
            f"{self.core.summary()}, {self.busy_drops} scans dropped while the worker was "
            f"busy, {self.n_skipped} messages skipped, longest callback {self.callback_ms:.1f} ms"
        )

    def shutdown(self) -> str | None:
        """Finish the worker's queue; slam with ``output``: write the map folder; a line
        saying where (or None)."""
        self.worker.shutdown(wait=True)
        self.pool.shutdown(wait=False, cancel_futures=True)
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
