"""ROS 1 node (rospy): ``scan`` (sensor_msgs/LaserScan) -> ``corners`` and ``corner_markers``.

Topics
------
``scan`` (subscribed, ``sensor_msgs/LaserScan``)
    The laser scans.
``corners`` (published, ``geometry_msgs/PoseArray``)
    One message per scan, with the scan's header; one pose per keypoint, its orientation
    the keypoint's bisector direction.
``corner_markers`` (published, ``visualization_msgs/MarkerArray``)
    Keypoints and bisector arrows for rviz; built only while someone subscribes.

Parameters (private, ``~name``)
-------------------------------
``preset`` and every :class:`~laser_corners.DetectorParams` field, plus the node options of
:data:`~laser_corners.ros.node_core.NODE_OPTIONS`. They are validated at start; an invalid
value stops the node with a one-line error.

Run it with ``laser-corners ros1`` (remappings and ``_param:=value`` arguments are passed to
rospy) or with the launch file ``laser_corners/ros/launch/laser_corners.launch``.

rospy is not on PyPI. When it is not importable, :func:`import_rospy` adds Debian's
``/usr/lib/python3/dist-packages`` (where ``apt-get install python3-rospy`` puts it) at the end
of ``sys.path``, so a virtualenv's own packages (numpy, numba) keep precedence, and loads the
ROS 1 message packages from rospy's folder even where ROS 2's same-named packages are installed.
"""

from __future__ import annotations

import importlib.abc
import importlib.machinery
import importlib.util
import os
import sys
import threading
import time
from collections.abc import Sequence
from pathlib import Path
from types import ModuleType
from typing import Any

from laser_corners.errors import InvalidParamsError, LaserCornersError, first_line
from laser_corners.io.messages import keypoints_to_marker_fields
from laser_corners.ros.convert import fill_marker_array, fill_pose_array
from laser_corners.ros.node_core import CornerNodeCore, NodeConfig

__all__ = [
    "DEBIAN_DIST_PACKAGES",
    "CornerNode",
    "Ros1MessageFinder",
    "import_rospy",
    "main",
    "release_stray_threads",
]

DEBIAN_DIST_PACKAGES = Path("/usr/lib/python3/dist-packages")
"""Where Debian's ``python3-rospy`` and the message packages install."""

ROS1_INSTALL_HINT = (
    "ROS 1 (rospy) is not importable: on Debian/Ubuntu run `sudo apt-get install ros-core "
    "python3-rospy python3-sensor-msgs python3-geometry-msgs python3-visualization-msgs`, "
    "or `source /opt/ros/noetic/setup.bash` for a ROS distribution install"
)


class Ros1MessageFinder(importlib.abc.MetaPathFinder):
    """Import ROS 1 message packages (``*_msgs``, ``*_srvs``) from the folder that holds rospy.

    ROS 2's wheels (``pip install laser-corners[ros2]``) put packages with the same names
    (``std_msgs``, ``sensor_msgs``, ``geometry_msgs``, ``visualization_msgs``,
    ``rosgraph_msgs``) into the environment, ahead of Debian's dist-packages on ``sys.path``.
    Placed first on ``sys.meta_path``, this finder makes ``import sensor_msgs`` in a ROS 1
    process load the genpy package beside rospy. Other names are left to the normal finders.

    Parameters
    ----------
    root : Path
        The folder that contains ``rospy`` and the ROS 1 message packages.
    """

    def __init__(self, root: Path) -> None:
        self.root = root

    def find_spec(self, fullname: str, path: Any = None, target: Any = None) -> Any:
        """The spec of a top-level ROS 1 message package under :attr:`root`, else ``None``."""
        if "." in fullname or not fullname.endswith(ROS1_MESSAGE_SUFFIXES):
            return None
        if not (self.root / fullname / "__init__.py").is_file():
            return None
        return importlib.machinery.PathFinder.find_spec(fullname, [str(self.root)])


ROS1_MESSAGE_SUFFIXES = ("_msgs", "_srvs")


def _ros1_root() -> Path:
    """The folder holding rospy: on ``sys.path`` already, or Debian's dist-packages."""
    spec = importlib.util.find_spec("rospy")
    if spec is not None and spec.origin:
        return Path(spec.origin).resolve().parent.parent
    if not (DEBIAN_DIST_PACKAGES / "rospy").is_dir():
        raise LaserCornersError(ROS1_INSTALL_HINT)
    dist = str(DEBIAN_DIST_PACKAGES)
    if dist not in sys.path:
        sys.path.append(dist)  # appended: the environment's own packages win
    return DEBIAN_DIST_PACKAGES


def _install_message_finder(root: Path) -> None:
    """Put a :class:`Ros1MessageFinder` for ``root`` first on ``sys.meta_path`` (once).

    Raises
    ------
    LaserCornersError
        When a message package of the same name is already imported from elsewhere (ROS 2's
        rclpy messages): both cannot live in one process.
    """
    for name, module in list(sys.modules.items()):
        if "." in name or not name.endswith(ROS1_MESSAGE_SUFFIXES):
            continue
        origin = Path(getattr(module, "__file__", None) or "")
        if (root / name).is_dir() and root not in origin.resolve().parents:
            raise LaserCornersError(
                f"ROS 1 needs its own {name} package but this process already imported "
                f"{name} from {origin.parent}: ROS 1 and ROS 2 messages cannot share a process"
            )
    if not any(isinstance(f, Ros1MessageFinder) and f.root == root for f in sys.meta_path):
        sys.meta_path.insert(0, Ros1MessageFinder(root))


def import_rospy() -> ModuleType:
    """Import rospy and ROS 1's message packages, whatever else is installed.

    rospy comes from ``sys.path`` or, when it is not there, from Debian's dist-packages
    appended to ``sys.path``. Message packages come from rospy's folder (see
    :class:`Ros1MessageFinder`), so ROS 2's same-named packages in the environment do not
    shadow them.

    Raises
    ------
    LaserCornersError
        With the install hint, when rospy or the message packages are not found, or when ROS 2
        message packages are already imported in this process.
    """
    root = _ros1_root()
    _install_message_finder(root)
    try:
        import geometry_msgs.msg  # type: ignore[import-not-found]  # noqa: F401
        import rospy  # type: ignore[import-not-found]
        import sensor_msgs.msg  # type: ignore[import-not-found]  # noqa: F401
        import visualization_msgs.msg  # type: ignore[import-not-found]  # noqa: F401
    except ImportError as exc:
        raise LaserCornersError(f"{ROS1_INSTALL_HINT} ({exc})") from None
    return rospy


class CornerNode:
    """The ROS 1 adapter: subscriptions, publications and logging around :class:`CornerNodeCore`.

    Parameters
    ----------
    config : NodeConfig
        Validated parameters.
    rospy : module
        The imported rospy (``rospy.init_node`` already called).
    """

    def __init__(self, config: NodeConfig, rospy: ModuleType) -> None:
        from geometry_msgs.msg import Point, Pose, PoseArray
        from sensor_msgs.msg import LaserScan as LaserScanMsg
        from visualization_msgs.msg import Marker, MarkerArray

        self._rospy = rospy
        self._msg = {
            "Point": Point,
            "Pose": Pose,
            "PoseArray": PoseArray,
            "Marker": Marker,
            "MarkerArray": MarkerArray,
        }
        self.core = CornerNodeCore(config)
        self.n_scans = 0
        self.n_skipped = 0
        queue_size = int(config.options["queue_size"])
        self.corners_pub = rospy.Publisher("corners", PoseArray, queue_size=queue_size)
        self.markers_pub = rospy.Publisher("corner_markers", MarkerArray, queue_size=queue_size)
        self.scan_sub = rospy.Subscriber(
            "scan", LaserScanMsg, self.on_scan, queue_size=queue_size, buff_size=2**20
        )
        rospy.loginfo(
            "laser_corners: %s -> %s, %s (preset %s, overrides %s)",
            self.scan_sub.resolved_name,
            self.corners_pub.resolved_name,
            self.markers_pub.resolved_name,
            config.preset,
            config.overrides or "none",
        )

    def on_scan(self, msg: Any) -> None:
        """Detect and publish; a malformed message is logged and skipped."""
        rospy = self._rospy
        try:
            keypoints, seconds = self.core.process(msg)
        except InvalidParamsError as exc:
            self.n_skipped += 1
            rospy.logerr_throttle(5.0, "laser_corners: parameters invalid for this scan: %s", exc)
            return
        except LaserCornersError as exc:
            self.n_skipped += 1
            rospy.logwarn_throttle(5.0, "laser_corners: skipped a malformed scan: %s", exc)
            return
        except Exception:  # a bug: keep the node alive, show the traceback
            self.n_skipped += 1
            rospy.logerr("laser_corners: scan processing failed", exc_info=True)
            return
        self.n_scans += 1
        out = fill_pose_array(self._msg["PoseArray"](), self._msg["Pose"], keypoints)
        out.header = msg.header
        self.corners_pub.publish(out)
        if self.markers_pub.get_num_connections() > 0:
            options = self.core.config.options
            markers = keypoints_to_marker_fields(
                keypoints, ns=options["marker_ns"], lifetime=options["marker_lifetime"]
            )
            self.markers_pub.publish(
                fill_marker_array(
                    self._msg["MarkerArray"](),
                    self._msg["Marker"],
                    self._msg["Point"],
                    rospy.Duration.from_sec,
                    msg.header,
                    markers,
                )
            )
        rospy.logdebug(
            "laser_corners: scan %.6f: %d keypoints, %.3f ms",
            keypoints.stamp,
            len(keypoints),
            seconds * 1e3,
        )


def main(
    argv: Sequence[str] | None = None, node_name: str = "laser_corners", debug: bool = False
) -> int:
    """Run the ROS 1 node until shutdown.

    SIGINT (Ctrl-C), SIGTERM and ``rosnode kill`` end it cleanly, also while it still waits
    for the ROS master: one log line, exit code 0, no traceback.

    Parameters
    ----------
    argv : sequence of str, optional
        ROS arguments (remappings ``scan:=/base_scan``, private parameters
        ``_min_points:=6``, ``__name:=...``); ``sys.argv`` when omitted.
    node_name : str
        Node name (overridden by ``__name:=``).
    debug : bool
        Log at debug level (per-scan latency).

    Returns
    -------
    int
        The exit code: 0 after a shutdown.

    Raises
    ------
    InvalidParamsError
        When a parameter is invalid (logged as fatal too).
    LaserCornersError
        When rospy is not installed, or the node cannot start for another reason.
    """
    rospy = import_rospy()
    args = list(sys.argv if argv is None else ["laser_corners_node", *argv])
    node: CornerNode | None = None
    try:
        rospy.init_node(
            node_name,
            argv=args,
            log_level=rospy.DEBUG if debug else rospy.INFO,
            disable_signals=False,
        )
        node = CornerNode(_read_config(rospy), rospy)
        rospy.spin()
    except InvalidParamsError:
        raise
    except (KeyboardInterrupt, Exception) as exc:
        if not rospy.core.is_shutdown_requested():
            if isinstance(exc, rospy.ROSException):
                raise LaserCornersError(f"ROS 1 node failed: {first_line(exc)}") from None
            raise
        # a signal (Ctrl-C, SIGTERM) arrived while rospy was busy, e.g. waiting for the master
    if node is None:
        import rosgraph  # type: ignore[import-not-found]

        print(
            f"laser_corners: shut down before the node started (ROS master "
            f"{rosgraph.get_master_uri()} not reached)",
            file=sys.stderr,
        )
    else:
        rospy.loginfo("laser_corners: %d scans processed, %d skipped", node.n_scans, node.n_skipped)
    release_stray_threads()  # else Python's exit may wait for ever (see there)
    return 0


def release_stray_threads(timeout: float = 5.0) -> int:
    """End the threads rospy leaves behind after its shutdown; returns how many it released.

    rospy wraps a subscriber's connection to a publisher with a queue in a
    ``QueuedConnection``, whose thread (not a daemon) waits for data until the connection
    closes, *before* it checks that the publisher is still open: a subscriber that connects
    while the node shuts down (roscore's rosout node to ``/rosout``, often, on a loaded
    machine) leaves a connection nobody closes, and Python's exit waits for its thread for
    ever (the node "still running" after SIGTERM). Their connections are closed here; any
    other non-daemon thread of rospy's still alive after ``timeout`` s makes the process leave
    at once (``os._exit``, after flushing), as rospy's own shutdown gives up joining its
    threads. Threads that are not rospy's are left alone.
    """
    released = 0
    for thread in threading.enumerate():
        target = getattr(thread, "_target", None)  # CPython keeps it while the thread runs
        queued = getattr(target, "__self__", None)
        if type(queued).__name__ == "QueuedConnection" and thread.is_alive():
            try:
                queued._connection.close()
            except Exception:  # a half-open transport: the exit below covers it
                continue
            released += 1
    deadline = time.monotonic() + timeout
    for thread in threading.enumerate():
        if thread is threading.current_thread() or thread.daemon or not _rospy_thread(thread):
            continue
        thread.join(max(deadline - time.monotonic(), 0.0))
        if thread.is_alive():
            print(f"laser_corners: thread {thread.name} did not stop; exiting", file=sys.stderr)
            sys.stdout.flush()
            sys.stderr.flush()
            os._exit(0)
    return released


def _rospy_thread(thread: threading.Thread) -> bool:
    """Whether ``thread`` runs rospy's (or rosgraph's) code."""
    target = getattr(thread, "_target", None)
    owner = getattr(target, "__self__", target)
    module = getattr(owner, "__module__", None) or type(owner).__module__
    return module.split(".")[0] in ("rospy", "rosgraph")


def _read_config(rospy: ModuleType) -> NodeConfig:
    """The node's private parameters, validated; an invalid one is logged as fatal too."""
    try:
        return NodeConfig.from_mapping(rospy.get_param("~", {}))
    except InvalidParamsError as exc:
        rospy.logfatal("laser_corners: %s", exc)
        rospy.signal_shutdown("invalid parameters")
        raise


if __name__ == "__main__":  # pragma: no cover - `python -m laser_corners.ros.ros1_node`
    try:
        sys.exit(main())
    except LaserCornersError as exc:
        print(f"laser-corners: error: {exc}", file=sys.stderr)
        sys.exit(2)
