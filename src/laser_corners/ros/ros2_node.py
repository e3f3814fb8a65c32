"""ROS 2 node (rclpy): ``scan`` (sensor_msgs/LaserScan) -> ``corners`` and ``corner_markers``.

Same topics, messages and parameter names as :mod:`laser_corners.ros.ros1_node`:

* subscribes ``scan`` with the sensor-data QoS (best effort, keep last 5);
* publishes ``corners`` (``geometry_msgs/PoseArray``, one pose per keypoint, orientation = the
  keypoint's bisector) and ``corner_markers`` (``visualization_msgs/MarkerArray``, built only
  while someone subscribes), both with the scan's header;
* declares ``preset``, every :class:`~laser_corners.DetectorParams` field and the node options
  of :data:`~laser_corners.ros.node_core.NODE_OPTIONS`. Detector fields are declared without
  a value (dynamic typing), so only the ones you set override the preset. Values are
  validated at start (an invalid one stops the node with a one-line error) and on every
  ``ros2 param set`` (an invalid change is rejected with the reason, the old values stay).

This module is a thin adapter: all decisions live in :mod:`laser_corners.ros.node_core` and
:mod:`laser_corners.ros.convert`, which are tested without ROS. rclpy is not installable from
this project's package registries, so this file itself has not run here (see ``docs/ros.md``).
Build it with colcon from the ``ros2/`` folder of the repository.
"""

from __future__ import annotations

import sys
from collections.abc import Sequence
from typing import Any

from laser_corners.errors import InvalidParamsError, LaserCornersError
from laser_corners.io.messages import keypoints_to_marker_fields
from laser_corners.params import DetectorParams
from laser_corners.ros.convert import fill_marker_array, fill_pose_array, seconds_to_sec_nanosec
from laser_corners.ros.node_core import (
    NODE_OPTIONS,
    CornerNodeCore,
    NodeConfig,
    parameter_names,
)

__all__ = ["main", "parameter_values"]

ROS2_INSTALL_HINT = (
    "ROS 2 (rclpy) is not importable: source your ROS 2 installation "
    "(e.g. `source /opt/ros/jazzy/setup.bash`) and build ros2/ with colcon (docs/ros.md)"
)


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
    import rclpy.node  # type: ignore[import-not-found]
    from builtin_interfaces.msg import Duration  # type: ignore[import-not-found]
    from geometry_msgs.msg import Point, Pose, PoseArray  # type: ignore[import-not-found]
    from rcl_interfaces.msg import (  # type: ignore[import-not-found]
        ParameterDescriptor,
        SetParametersResult,
    )
    from rclpy.parameter import Parameter  # type: ignore[import-not-found]
    from rclpy.qos import qos_profile_sensor_data  # type: ignore[import-not-found]
    from sensor_msgs.msg import LaserScan as LaserScanMsg  # type: ignore[import-not-found]
    from visualization_msgs.msg import Marker, MarkerArray  # type: ignore[import-not-found]

    def duration(seconds: float) -> Any:
        sec, nanosec = seconds_to_sec_nanosec(seconds)
        return Duration(sec=sec, nanosec=nanosec)

    class CornerNode2(rclpy.node.Node):  # type: ignore[misc]
        """The ROS 2 adapter around :class:`CornerNodeCore`."""

        def __init__(self) -> None:
            super().__init__("laser_corners")
            dynamic = ParameterDescriptor(dynamic_typing=True)
            self.declare_parameter("preset", "paper")
            for name in DetectorParams.model_fields:
                self.declare_parameter(name, None, dynamic)
            for name, default in NODE_OPTIONS.items():
                self.declare_parameter(name, default)
            names = parameter_names()
            values = parameter_values(self.get_parameters(names), Parameter.Type.NOT_SET)
            config = NodeConfig.from_mapping(values)  # raises InvalidParamsError
            self.core = CornerNodeCore(config)
            depth = int(config.options["queue_size"])
            self.corners_pub = self.create_publisher(PoseArray, "corners", depth)
            self.markers_pub = self.create_publisher(MarkerArray, "corner_markers", depth)
            self.scan_sub = self.create_subscription(
                LaserScanMsg, "scan", self.on_scan, qos_profile_sensor_data
            )
            self.add_on_set_parameters_callback(self.on_set_parameters)
            self.get_logger().info(
                f"scan -> corners, corner_markers (preset {config.preset}, "
                f"overrides {config.overrides or 'none'})"
            )

        def on_set_parameters(self, parameters: list[Any]) -> Any:
            ours = set(parameter_names())  # use_sim_time and other ROS parameters pass through
            changes = parameter_values(
                [p for p in parameters if p.name in ours], Parameter.Type.NOT_SET
            )
            try:
                config = self.core.config.updated(changes)
            except InvalidParamsError as exc:
                return SetParametersResult(successful=False, reason=str(exc))
            self.core.reconfigure(config)
            return SetParametersResult(successful=True)

        def on_scan(self, msg: Any) -> None:
            try:
                keypoints, seconds = self.core.process(msg)
            except InvalidParamsError as exc:
                self.get_logger().error(
                    f"parameters invalid for this scan: {exc}", throttle_duration_sec=5.0
                )
                return
            except LaserCornersError as exc:
                self.get_logger().warning(
                    f"skipped a malformed scan: {exc}", throttle_duration_sec=5.0
                )
                return
            except Exception as exc:  # a bug: keep the node alive, show the error
                self.get_logger().error(f"scan processing failed: {exc!r}")
                return
            out = fill_pose_array(PoseArray(), Pose, keypoints)
            out.header = msg.header
            self.corners_pub.publish(out)
            if self.markers_pub.get_subscription_count() > 0:
                options = self.core.config.options
                markers = keypoints_to_marker_fields(
                    keypoints, ns=options["marker_ns"], lifetime=options["marker_lifetime"]
                )
                self.markers_pub.publish(
                    fill_marker_array(MarkerArray(), Marker, Point, duration, msg.header, markers)
                )
            self.get_logger().debug(f"{len(keypoints)} keypoints in {seconds * 1e3:.3f} ms")

    return CornerNode2


def main(args: Sequence[str] | None = None) -> None:
    """Run the ROS 2 node until shutdown (``ros2 run laser_corners_ros laser_corners_node``)."""
    try:
        import rclpy  # type: ignore[import-not-found]
    except ImportError:
        print(f"laser_corners: error: {ROS2_INSTALL_HINT}", file=sys.stderr)
        sys.exit(2)
    rclpy.init(args=list(args) if args is not None else None)
    node = None
    try:
        node = _make_node_class()()
        rclpy.spin(node)
    except InvalidParamsError as exc:
        print(f"laser_corners: error: {exc}", file=sys.stderr)
        sys.exit(2)
    except KeyboardInterrupt:
        pass
    finally:
        if node is not None:
            node.destroy_node()
        if rclpy.ok():
            rclpy.shutdown()
