"""ROS 2 node (rclpy): ``scan`` (sensor_msgs/LaserScan) -> ``corners`` and ``corner_markers``.

Same topics, messages and parameter names as :mod:`laser_corners.ros.ros1_node`:

* subscribes ``scan`` with the sensor-data QoS (best effort, keep last ``queue_size``);
* publishes ``corners`` (``geometry_msgs/PoseArray``, one pose per keypoint, orientation = the
  keypoint's bisector) and ``corner_markers`` (``visualization_msgs/MarkerArray``, built only
  while someone subscribes), both with the scan's header;
* declares ``preset``, every :class:`~laser_corners.DetectorParams` field and the node options
  of :data:`~laser_corners.ros.node_core.NODE_OPTIONS`, all with dynamic typing: the values are
  checked by :class:`~laser_corners.ros.node_core.NodeConfig`, like the ROS 1 node's. Detector
  fields have no value until set, so only the ones you set override the preset. An invalid or
  unknown parameter at start stops the node with a one-line error (exit code 2); an invalid
  change at run time (``ros2 param set``, any parameter client) is rejected with the reason and
  the old values stay.

Run it with ``laser-corners ros2 --ros-args -r scan:=/front/scan -p preset:=auto`` (rclpy from
PyPI: ``pip install 'laser-corners[ros2]'``) or, in a ROS 2 workspace, with the colcon package
in ``ros2/`` (``ros2 run laser_corners_ros laser_corners_node``); both call :func:`main`.
SIGINT and SIGTERM end the node with a summary line and exit code 0.

The ``mode`` parameter (read at start) picks what the node does: ``detector`` (the default,
above), ``slam`` or ``localise`` (:mod:`laser_corners.ros.ros2_mapping`: mapping and
localisation with odometry from ``/tf``, ``map -> odom`` out; docs/ros.md).

The node is a managed (lifecycle) node: with ``-p lifecycle:=true`` it waits unconfigured for
nav2's lifecycle manager (``configure`` checks the parameters, loads the map and checks the
output folder; ``activate`` subscribes; ``deactivate``, ``cleanup``, ``shutdown``); without
it, it configures and activates itself at start.

This module is a thin adapter: all decisions live in :mod:`laser_corners.ros.node_core`,
:mod:`laser_corners.ros.slam_core` and :mod:`laser_corners.ros.convert`.
"""

from __future__ import annotations

import re
import signal
import sys
import threading
from collections.abc import Sequence
from types import FrameType, ModuleType, SimpleNamespace
from typing import Any

from laser_corners.errors import (
    InvalidParamsError,
    LaserCornersError,
    MissingDependencyError,
    first_line,
)
from laser_corners.io.messages import keypoints_to_marker_fields
from laser_corners.keypoints import Keypoints
from laser_corners.params import DetectorParams
from laser_corners.ros.convert import fill_marker_array, fill_pose_array, seconds_to_sec_nanosec
from laser_corners.ros.mapping_config import MAPPING_OPTIONS, estimator_parameters
from laser_corners.ros.node_core import NODE_OPTIONS, CornerNodeCore, NodeConfig, parameter_names
from laser_corners.ros.ros2_mapping import MappingAdapter, check_mode

__all__ = ["NODE_NAME", "import_rclpy", "main", "parameter_values"]

NODE_NAME = "laser_corners"
"""Default node name (change it with ``--ros-args -r __node:=name``)."""

ROS2_INSTALL_HINT = (
    "ROS 2 (rclpy) is not importable: `pip install 'laser-corners[ros2]'` installs ROS 2 Jazzy's "
    "rclpy and messages from PyPI, or source a ROS 2 installation "
    "(`source /opt/ros/jazzy/setup.bash`); see docs/ros.md"
)
SPIN_PERIOD = 0.1
"""Seconds between checks for a stop signal while the node waits for messages."""


def import_rclpy() -> ModuleType:
    """Import rclpy and the message packages the node uses.

    Raises
    ------
    MissingDependencyError
        With the install hint when one of them is missing.
    """
    try:
        import geometry_msgs.msg  # type: ignore[import-not-found]
        import rclpy  # type: ignore[import-not-found]
        import sensor_msgs.msg  # type: ignore[import-not-found]  # noqa: F401
        import visualization_msgs.msg  # type: ignore[import-not-found]  # noqa: F401
    except ImportError as exc:
        raise MissingDependencyError(f"{ROS2_INSTALL_HINT} ({exc})") from None
    if not hasattr(geometry_msgs.msg.PoseArray, "get_fields_and_field_types"):
        raise MissingDependencyError(
            f"{ROS2_INSTALL_HINT} (geometry_msgs here is not a ROS 2 package: "
            f"{geometry_msgs.__file__}; ROS 1 and ROS 2 messages cannot share a process)"
        )
    return rclpy


def parameter_values(parameters: Sequence[Any], unset_type: Any) -> dict[str, Any]:
    """Name -> value of rclpy parameters, leaving out the ones never set.

    Parameters
    ----------
    parameters : sequence of rclpy.parameter.Parameter
        Objects with ``name``, ``type_`` and ``value``.
    unset_type : rclpy.parameter.Parameter.Type
        ``Parameter.Type.NOT_SET``.
    """
    values: dict[str, Any] = {}
    for parameter in parameters:
        if parameter.type_ == unset_type:
            continue
        value = parameter.value
        if isinstance(value, list | tuple) or type(value).__name__ == "array":
            value = list(value)
        values[parameter.name] = value
    return values


def _make_node_class() -> type:
    from rcl_interfaces.msg import SetParametersResult  # type: ignore[import-not-found]
    from rclpy.lifecycle import (  # type: ignore[import-not-found]
        LifecycleNode,
        TransitionCallbackReturn,
    )

    class LaserCornersNode(_NodeLogic, LifecycleNode):  # type: ignore[misc]
        """The ROS 2 node, a managed (lifecycle) node (see :class:`_NodeLogic`)."""

        Return = TransitionCallbackReturn
        Result = SetParametersResult

        def __init__(self, context: Any = None) -> None:
            LifecycleNode.__init__(self, NODE_NAME, context=context)
            self.setup()

    return LaserCornersNode


class _NodeLogic:
    """What the node does; ``mode`` (read at start) picks the adapter that does the work.

    A managed (lifecycle) node: ``configure`` makes the adapter (parameters checked, map
    loaded, output checked, publishers and services), ``activate`` subscribes,
    ``deactivate`` unsubscribes, ``cleanup`` removes it, ``shutdown`` writes the map and
    removes it. Unless ``lifecycle`` is true, the node configures and activates itself at
    start (an error there stops it with one line). Mixed into rclpy's ``LifecycleNode``
    (imported lazily): ``Return`` and ``Result`` are its transition return and rcl's
    ``SetParametersResult``.
    """

    Return: Any
    Result: Any

    def setup(self) -> None:
        """Declare the parameters; without ``lifecycle``: configure and activate."""
        from rcl_interfaces.msg import ParameterDescriptor  # type: ignore[import-not-found]

        dynamic = ParameterDescriptor(dynamic_typing=True)
        self.declare_parameter("mode", "detector", dynamic)
        self.declare_parameter("lifecycle", False, dynamic)
        self.mode = check_mode(self.get_parameter("mode").value)
        self.managed = check_lifecycle(self.get_parameter("lifecycle").value)
        self.service_node = None if self.mode == "detector" else _service_node(self)
        self.defaults = mode_parameters(self.mode)
        self.unknown = _declare(self, self.defaults)
        self.adapter = None
        self.error: BaseException | None = None
        self.finished: list[str] = []
        self.add_on_set_parameters_callback(self.on_set_parameters)
        if not self.managed:  # nav2's autostart: configure and activate now
            self.trigger_configure()
            if self.error is not None:
                raise self.error
            self.trigger_activate()
        else:
            self.get_logger().info(
                "lifecycle: unconfigured; waiting for configure "
                "(lifecycle_msgs/srv/ChangeState on ~/change_state)"
            )

    def on_configure(self, state: Any) -> Any:
        """Check the parameters (their values now), load the map, check ``output``;
        make the publishers and services."""
        values = {**self.unknown, **_values(self, list(self.defaults))}
        self.error, self.finished = None, []
        try:
            if self.mode == "detector":
                self.adapter = _DetectorAdapter(self, values)
            else:
                self.adapter = MappingAdapter(self, {**values, "mode": self.mode})
        except Exception as exc:  # a managed node stays unconfigured and says why
            self.error = exc
            if self.managed:
                text = first_line(exc) if isinstance(exc, LaserCornersError) else repr(exc)
                self.get_logger().error(f"configure failed: {text}")
            return self.Return.FAILURE
        return self.Return.SUCCESS

    def on_activate(self, state: Any) -> Any:
        """Subscribe: scans are processed from now."""
        self.adapter.activate()
        return self.Return.SUCCESS

    def on_deactivate(self, state: Any) -> Any:
        """Unsubscribe: scans are no longer taken."""
        self.adapter.deactivate()
        return self.Return.SUCCESS

    def on_cleanup(self, state: Any) -> Any:
        """Remove what ``configure`` made."""
        self.adapter.close()
        self.adapter = None
        return self.Return.SUCCESS

    def on_shutdown(self, state: Any) -> Any:
        """Summary, then slam with ``output``: the map folder (as at SIGINT)."""
        for line in self.finish("lifecycle shutdown"):
            self.get_logger().info(line)
        return self.Return.SUCCESS

    def on_set_parameters(self, parameters: list[Any]) -> Any:
        """Check a change against all current values; apply it only when valid (while
        unconfigured: any change, checked at ``configure``)."""
        fixed = [p.name for p in parameters if p.name in ("mode", "lifecycle")]
        if fixed:
            reason = f"{', '.join(fixed)}: read at start only"
            return self.Result(successful=False, reason=reason)
        if self.adapter is None:
            return self.Result(successful=True)
        ok, reason = self.adapter.set_parameters(parameters)
        return self.Result(successful=ok, reason=reason)

    def finish(self, reason: str) -> list[str]:
        """The summary line (``reason``: ...) and what the adapter wrote at shutdown;
        once (later calls return the same lines)."""
        if self.adapter is not None:
            self.finished = [f"{reason}: {self.adapter.summary()}"]
            written = self.adapter.shutdown()
            self.finished += [written] if written else []
            self.adapter.close()
            self.adapter = None
        return self.finished or [f"{reason}: not configured, nothing processed"]


def check_lifecycle(value: Any) -> bool:
    """The ``lifecycle`` parameter, checked."""
    if not isinstance(value, bool):
        raise InvalidParamsError(
            f"ROS 2 parameter lifecycle: expected true or false, got {value!r}"
        )
    return value


def mode_parameters(mode: str) -> dict[str, Any]:
    """The parameters of ``mode`` (``mode`` and ``lifecycle`` aside) with their defaults
    (None: unset until given)."""
    if mode == "detector":
        return {"preset": "paper", **dict.fromkeys(DetectorParams.model_fields), **NODE_OPTIONS}
    own = {k: v for k, v in MAPPING_OPTIONS.items() if k != "mode"}
    return {**own, **dict.fromkeys(estimator_parameters(mode))}


def _values(node: Any, names: list[str]) -> dict[str, Any]:
    """The current values of ``names`` that are set."""
    from rclpy.parameter import Parameter  # type: ignore[import-not-found]

    return parameter_values(node.get_parameters(names), Parameter.Type.NOT_SET)


def _declare(node: Any, defaults: dict[str, Any]) -> dict[str, Any]:
    """Declare ``defaults`` (dynamic typing) on ``node``; return the start-up overrides
    (``-p``, ``--params-file``) of names the node does not know, so that the mode's config
    rejects them as ROS 1 does (rclpy itself would ignore them silently); a dotted name is
    ours to reject when its head is (``places.x``), else rclpy's (``qos_overrides....``).
    """
    from rcl_interfaces.msg import ParameterDescriptor  # type: ignore[import-not-found]

    dynamic = ParameterDescriptor(dynamic_typing=True)
    for name, default in defaults.items():  # an empty list (mount) stays unset until given
        node.declare_parameter(name, None if default == [] else default, dynamic)
    heads = {name.partition(".")[0] for name in defaults if "." in name}
    # rclpy keeps the start-up overrides in a private dict (no public accessor)
    overrides = getattr(node, "_parameter_overrides", {})
    return {
        name: override.value
        for name, override in overrides.items()
        if not node.has_parameter(name) and ("." not in name or name.partition(".")[0] in heads)
    }


class _DetectorAdapter:
    """The detector mode: ``scan`` -> ``corners`` and ``corner_markers`` (the default)."""

    def __init__(self, node: Any, values: dict[str, Any]) -> None:
        from builtin_interfaces.msg import Duration  # type: ignore[import-not-found]
        from geometry_msgs.msg import Point, Pose, PoseArray  # type: ignore[import-not-found]
        from rclpy.qos import (  # type: ignore[import-not-found]
            DurabilityPolicy,
            HistoryPolicy,
            QoSProfile,
            ReliabilityPolicy,
        )
        from sensor_msgs.msg import LaserScan as LaserScanMsg  # type: ignore[import-not-found]
        from visualization_msgs.msg import Marker, MarkerArray  # type: ignore[import-not-found]

        self.m = SimpleNamespace(
            Duration=Duration,
            Point=Point,
            Pose=Pose,
            PoseArray=PoseArray,
            Marker=Marker,
            MarkerArray=MarkerArray,
        )
        self.node = node
        self.n_scans = self.n_skipped = self.n_markers = 0
        config = NodeConfig.from_mapping(values, source="ROS 2 parameter", prefix="")
        self.core = CornerNodeCore(config)
        depth = int(config.options["queue_size"])
        scan_qos = QoSProfile(  # rclpy's sensor-data profile, with our depth
            history=HistoryPolicy.KEEP_LAST,
            depth=depth,
            reliability=ReliabilityPolicy.BEST_EFFORT,
            durability=DurabilityPolicy.VOLATILE,
        )
        self.corners_pub = node.create_publisher(PoseArray, "corners", depth)
        self.markers_pub = node.create_publisher(MarkerArray, "corner_markers", depth)
        self.subscribe = lambda: node.create_subscription(
            LaserScanMsg, "scan", self.on_scan, scan_qos
        )
        self.scan_sub: Any = None

    def activate(self) -> None:
        """Subscribe ``scan``: scans are processed from now."""
        self.scan_sub = self.subscribe()
        config = self.core.config
        self.node.get_logger().info(
            f"{self.scan_sub.topic_name} -> {self.corners_pub.topic_name}, "
            f"{self.markers_pub.topic_name} (preset {config.preset}, "
            f"overrides {config.overrides or 'none'})"
        )

    def deactivate(self) -> None:
        """Unsubscribe ``scan``."""
        if self.scan_sub is not None:
            self.node.destroy_subscription(self.scan_sub)
            self.scan_sub = None

    def close(self) -> None:
        """Remove the subscription and the publishers."""
        self.deactivate()
        self.node.destroy_publisher(self.corners_pub)
        self.node.destroy_publisher(self.markers_pub)

    def get_logger(self) -> Any:
        return self.node.get_logger()

    def get_parameters(self, names: list[str]) -> Any:
        return self.node.get_parameters(names)

    def set_parameters(self, parameters: list[Any]) -> tuple[bool, str]:
        from rclpy.parameter import Parameter  # type: ignore[import-not-found]

        return _set_parameters(self, parameters, Parameter.Type.NOT_SET)

    def on_scan(self, msg: Any) -> None:
        """Detect and publish; a malformed message is logged and skipped."""
        m = self.m

        def duration(seconds: float) -> Any:
            sec, nanosec = seconds_to_sec_nanosec(seconds)
            return m.Duration(sec=sec, nanosec=nanosec)

        keypoints = _process_scan(self, msg)
        if keypoints is None:
            return
        out = fill_pose_array(m.PoseArray(), m.Pose, keypoints)
        out.header = msg.header
        self.corners_pub.publish(out)
        if self.markers_pub.get_subscription_count() > 0:
            options = self.core.config.options
            markers = keypoints_to_marker_fields(
                keypoints, ns=options["marker_ns"], lifetime=options["marker_lifetime"]
            )
            self.markers_pub.publish(
                fill_marker_array(m.MarkerArray(), m.Marker, m.Point, duration, msg.header, markers)
            )
            self.n_markers += 1

    def summary(self) -> str:
        """Counts for the log line at shutdown."""
        return (
            f"{self.n_scans} scans processed, {self.n_skipped} skipped, "
            f"markers published for {self.n_markers}"
        )

    def shutdown(self) -> str | None:
        return None


def _set_parameters(node: Any, parameters: list[Any], not_set: Any) -> tuple[bool, str]:
    """A run-time parameter change: (applied, reason when rejected)."""
    ours = parameter_names()  # use_sim_time and other ROS parameters pass through
    if not any(p.name in ours for p in parameters):
        return True, ""
    current = {p.name: p for p in node.get_parameters(ours)}
    current.update({p.name: p for p in parameters if p.name in current})
    try:
        config = NodeConfig.from_mapping(
            parameter_values(list(current.values()), not_set),
            source="ROS 2 parameter",
            prefix="",
        )
    except InvalidParamsError as exc:
        return False, str(exc)
    node.core.reconfigure(config)
    node.get_logger().info(
        f"parameters changed: preset {config.preset}, overrides {config.overrides or 'none'}"
    )
    return True, ""


def _process_scan(node: Any, msg: Any) -> Keypoints | None:
    """Detect keypoints in a scan message; None (logged, counted) when it is skipped."""
    try:
        keypoints, seconds = node.core.process(msg)
    except InvalidParamsError as exc:
        node.n_skipped += 1
        node.get_logger().error(
            f"parameters invalid for this scan: {exc}", throttle_duration_sec=5.0
        )
        return None
    except LaserCornersError as exc:
        node.n_skipped += 1
        node.get_logger().warning(f"skipped a malformed scan: {exc}", throttle_duration_sec=5.0)
        return None
    except Exception as exc:  # a bug: keep the node alive, show the error
        node.n_skipped += 1
        node.get_logger().error(f"scan processing failed: {exc!r}")
        return None
    node.n_scans += 1
    node.get_logger().debug(f"{len(keypoints)} keypoints in {seconds * 1e3:.3f} ms")
    return keypoints


def _rcl_message(exc: BaseException) -> str:
    """rcl's error text without its C source locations."""
    return re.sub(r",? at /\S+:\d+", "", first_line(exc))


class _StopSignals:
    """SIGINT and SIGTERM set a flag the spin loop checks (instead of raising anywhere)."""

    def __init__(self) -> None:
        self.received: str | None = None
        self._previous: dict[int, Any] = {}

    def __enter__(self) -> _StopSignals:
        if threading.current_thread() is threading.main_thread():
            for sig in (signal.SIGINT, signal.SIGTERM):
                self._previous[sig] = signal.signal(sig, self._handle)
        return self

    def _handle(self, signum: int, frame: FrameType | None) -> None:
        self.received = signal.Signals(signum).name

    def __exit__(self, *exc: object) -> None:
        for sig, handler in self._previous.items():
            signal.signal(sig, handler)


def _check_arguments(args: list[str]) -> None:
    """Reject arguments that are not ROS arguments (they would be ignored silently)."""
    from rclpy.utilities import remove_ros_args  # type: ignore[import-not-found]

    extra = remove_ros_args(["laser_corners", *args])[1:]
    if extra:
        raise LaserCornersError(
            f"unexpected argument(s) {' '.join(extra)}: ROS arguments go after --ros-args, "
            "e.g. --ros-args -r scan:=/front/scan -p preset:=auto --params-file corners.yaml"
        )


def _run(rclpy: ModuleType, args: list[str], stop: _StopSignals) -> None:
    """Start the node and spin it until ``stop`` sees a signal or the context shuts down
    (its service node, see :func:`_service_node`, on a thread of its own)."""
    from rclpy.executors import SingleThreadedExecutor  # type: ignore[import-not-found]
    from rclpy.signals import SignalHandlerOptions  # type: ignore[import-not-found]

    context = rclpy.Context()
    try:
        _check_arguments(args)
        rclpy.init(
            args=["laser_corners", *args],
            context=context,
            signal_handler_options=SignalHandlerOptions.NO,
        )
    except RuntimeError as exc:  # rclpy's RCLError, UnknownROSArgsError
        raise LaserCornersError(f"ROS 2 arguments: {_rcl_message(exc)}") from None
    node = None
    services = SingleThreadedExecutor(context=context)
    spinner = threading.Thread(target=_spin, args=(services,), name="services", daemon=True)
    try:
        node = _make_node_class()(context=context)
        if node.service_node is not None:
            services.add_node(node.service_node)
            spinner.start()
        executor = SingleThreadedExecutor(context=context)
        executor.add_node(node)
        while stop.received is None and context.ok():
            executor.spin_once(timeout_sec=SPIN_PERIOD)
        reason = f"stopped by {stop.received}" if stop.received else "ROS 2 context shut down"
        for line in node.finish(reason):
            node.get_logger().info(line)
        executor.shutdown(timeout_sec=1.0)
    finally:
        services.shutdown(timeout_sec=1.0)
        if spinner.is_alive():  # out of its wait before the context goes (else: abort)
            spinner.join(timeout=5.0)
        if node is not None and node.service_node is not None:
            node.service_node.destroy_node()
        if node is not None:
            node.destroy_node()
        if context.ok():
            rclpy.shutdown(context=context)


def _spin(executor: Any) -> None:
    """Spin ``executor`` until it is shut down."""
    from rclpy.executors import ExternalShutdownException  # type: ignore[import-not-found]

    try:
        executor.spin()
    except ExternalShutdownException:
        pass


def _service_node(node: Any) -> Any:
    """A second node (``<name>_services``, same namespace, no parameters) for the mapping
    modes' services, spun on a thread of its own: a service that waits for the worker (a map
    write takes seconds) then holds none of the node's callbacks (scans, parameters,
    lifecycle). It ignores the process's remappings (``__node:=`` would give it the node's
    name); the services take the names the node resolves (:meth:`resolve_service_name`)."""
    import rclpy  # type: ignore[import-not-found]

    return rclpy.create_node(
        f"{node.get_name()}_services",
        namespace=node.get_namespace(),
        context=node.context,
        use_global_arguments=False,
        start_parameter_services=False,
    )


def main(argv: Sequence[str] | None = None) -> int:
    """Run the ROS 2 node until SIGINT or SIGTERM.

    Parameters
    ----------
    argv : sequence of str, optional
        The arguments after the program name: ``--ros-args`` and ROS arguments
        (``-r scan:=/front/scan``, ``-p preset:=auto``, ``--params-file corners.yaml``,
        ``--log-level laser_corners:=debug``, ``-r __node:=name``); ``sys.argv[1:]`` when
        omitted (``ros2 run`` passes them so).

    Returns
    -------
    int
        The exit code: 0 after SIGINT or SIGTERM; 2 after a one-line error on stderr (rclpy
        missing, invalid arguments, an invalid or unknown parameter).
    """
    args = list(sys.argv[1:] if argv is None else argv)
    with _StopSignals() as stop:  # from the start: Ctrl-C while loading must not raise either
        try:
            rclpy = import_rclpy()
            if stop.received is None:
                _run(rclpy, args, stop)
            else:
                print(f"laser_corners: stopped by {stop.received} while starting", file=sys.stderr)
        except LaserCornersError as exc:
            print(f"laser_corners: error: {first_line(exc)}", file=sys.stderr)
            return 2
    return 0


if __name__ == "__main__":  # pragma: no cover - `python -m laser_corners.ros.ros2_node`
    sys.exit(main())
