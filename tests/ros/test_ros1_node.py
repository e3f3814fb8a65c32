"""The ROS 1 node against a real ROS master (Debian's ROS 1), fed with real fr079 scans.

A real ``roscore`` runs on a free port; the node runs as a subprocess (``laser-corners ros1``)
and this process publishes scans of ``../shared/data/real/fr079.bag`` on ``scan`` at a bounded
rate and listens on ``corners`` and ``corner_markers``. ``make test`` installs ROS 1 with
apt-get (target ``ros1-deps``); without it these tests skip with the reason.
"""

from __future__ import annotations

import logging
import os
import shutil
import signal
import socket
import subprocess
import sys
import time
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from ros_helpers import (
    FR079,
    REPO_ROOT,
    check_poses,
    cli_command,
    isolated_message_packages,
    publish_paced,
    skip_or_fail,
    spawn,
    stop,
    wait_for,
)

from conftest import die_with_parent
from laser_corners import CornerDetector, DetectorParams, LaserScan
from laser_corners.errors import LaserCornersError

pytestmark = [
    pytest.mark.ros1,
    pytest.mark.real,
    pytest.mark.filterwarnings("ignore:notifyAll:DeprecationWarning"),  # Debian's rospy
]

ROS_PACKAGE_DIR = REPO_ROOT / "src" / "laser_corners" / "ros"
N_SCANS = 400  # scans of fr079 played (the first ones)
RATE_HZ = 40.0  # publishing rate
NODE_OVERRIDES = {"merge_radius": 0.0, "min_points": 4}  # non-defaults: prove params flow
# a deep scan queue: a loaded CI machine may stall the node briefly; every scan must be answered
NODE_OPTIONS = {"queue_size": N_SCANS}
STARTUP_TIMEOUT = 30.0


def _ros1() -> Any:
    """rospy, or skip (fail in CI) with the reason."""
    if shutil.which("roscore") is None:
        skip_or_fail(
            "ROS 1 not installed (no roscore on PATH): `make test` installs it with apt-get as "
            "root (target ros1-deps); apt-get was unavailable or not permitted here"
        )
    from laser_corners.ros.ros1_node import import_rospy

    try:
        return import_rospy()
    except LaserCornersError as exc:
        skip_or_fail(str(exc))


def _free_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])


@dataclass
class RosMaster:
    uri: str
    env: dict[str, str]
    tmp: Path
    rospy: Any
    processes: list[tuple[subprocess.Popen[bytes], str]] = field(default_factory=list)

    def start(self, args: list[str], name: str) -> subprocess.Popen[bytes]:
        """Start ``args`` in its own process group; stopped at teardown."""
        with (self.tmp / f"{name}.log").open("wb") as log:
            proc = spawn(args, self.env, log)
        self.processes.append((proc, name))
        return proc

    def log(self, name: str) -> str:
        return (self.tmp / f"{name}.log").read_text(errors="replace")

    def node_command(self, *args: str) -> list[str]:
        return cli_command("ros1", *args)

    def subscribed(self, topic: str, node: str) -> bool:
        import rosgraph

        _, subscribers, _ = rosgraph.Master("/probe", master_uri=self.uri).getSystemState()
        return any(t == topic and node in nodes for t, nodes in subscribers)


def _ros1_env(uri: str, home: Path) -> dict[str, str]:
    """This process's environment for a ROS 1 process: master ``uri``, home and logs in
    ``home``, unbuffered output."""
    env = dict(
        os.environ,
        ROS_MASTER_URI=uri,
        ROS_IP="127.0.0.1",
        ROS_HOME=str(home),
        ROS_LOG_DIR=str(home / "log"),
        PYTHONUNBUFFERED="1",
    )
    env.pop("ROS_HOSTNAME", None)
    return env


@pytest.fixture(scope="module")
def master(tmp_path_factory: pytest.TempPathFactory) -> Iterator[RosMaster]:
    """A real roscore on a free port, and this process as a rospy node talking to it.

    ROS 1's message packages are imported for this module only (ROS 2's have the same names).
    """
    with isolated_message_packages():
        yield from _run_master(tmp_path_factory)


def _run_master(tmp_path_factory: pytest.TempPathFactory) -> Iterator[RosMaster]:
    rospy = _ros1()
    if not FR079.is_file():
        pytest.skip(f"real data file not found: {FR079} (expected ../shared/data/real)")
    tmp = tmp_path_factory.mktemp("ros1")
    port = _free_port()
    uri = f"http://127.0.0.1:{port}"
    env = _ros1_env(uri, tmp)
    env["PATH"] = f"{Path(sys.executable).parent}{os.pathsep}{env.get('PATH', '')}"
    saved = {
        k: os.environ.get(k)
        for k in ("ROS_MASTER_URI", "ROS_IP", "ROS_HOME", "ROS_HOSTNAME", "ROS_LOG_FILENAME")
    }
    # rospy.init_node reconfigures logging (root handlers, levels): restore it afterwards
    root_logger = logging.getLogger()
    saved_logging = (root_logger.handlers[:], root_logger.level)
    ros = RosMaster(uri, env, tmp, rospy)
    try:
        roscore = ros.start(["roscore", "-p", str(port)], "roscore")
        import rosgraph

        def online() -> bool:
            return bool(rosgraph.Master("/probe", master_uri=uri).is_online())

        wait_for(online, STARTUP_TIMEOUT, "roscore", roscore)
        os.environ.update({k: env[k] for k in ("ROS_MASTER_URI", "ROS_IP", "ROS_HOME")})
        os.environ.pop("ROS_HOSTNAME", None)
        rospy.init_node("laser_corners_test", anonymous=True, disable_signals=True)
        yield ros
    finally:
        if rospy.core.is_initialized():
            rospy.signal_shutdown("test done")
        for proc, name in reversed(ros.processes):
            stop(proc, name)
        root_logger.handlers[:] = saved_logging[0]
        root_logger.setLevel(saved_logging[1])
        for key, value in saved.items():
            if value is None:
                os.environ.pop(key, None)
            else:
                os.environ[key] = value


def _fr079_messages(n: int) -> list[Any]:
    """The first ``n`` /scan messages of fr079.bag (rosbags dataclasses)."""
    from rosbags.highlevel import AnyReader

    out = []
    with AnyReader([FR079]) as reader:
        conns = [c for c in reader.connections if c.msgtype == "sensor_msgs/msg/LaserScan"]
        for conn, _, raw in reader.messages(connections=conns):
            out.append(reader.deserialize(raw, conn.msgtype))
            if len(out) == n:
                break
    return out


def _as_ros1(msg: Any) -> Any:
    """A rospy sensor_msgs/LaserScan with the fields of a rosbags message."""
    import rospy
    from sensor_msgs.msg import LaserScan as LaserScanMsg

    out = LaserScanMsg()
    out.header.stamp = rospy.Time(msg.header.stamp.sec, msg.header.stamp.nanosec)
    out.header.frame_id = msg.header.frame_id
    for name in (
        "angle_min",
        "angle_max",
        "angle_increment",
        "time_increment",
        "scan_time",
        "range_min",
        "range_max",
    ):
        setattr(out, name, float(getattr(msg, name)))
    out.ranges = [float(r) for r in msg.ranges]
    out.intensities = [float(v) for v in msg.intensities]
    return out


def _expected(msg: Any, detector: CornerDetector) -> Any:
    """The library's keypoints for a rosbags message, built without the node's conversion."""
    scan = LaserScan(
        ranges=np.asarray(msg.ranges, dtype=np.float64),
        angle_min=float(msg.angle_min),
        angle_increment=float(msg.angle_increment),
        range_min=float(msg.range_min),
        range_max=float(msg.range_max),
    )
    return detector.detect(scan)


def test_node_publishes_library_keypoints_for_every_scan(master: RosMaster) -> None:
    rospy = master.rospy
    from geometry_msgs.msg import PoseArray
    from sensor_msgs.msg import LaserScan as LaserScanMsg
    from visualization_msgs.msg import MarkerArray

    messages = _fr079_messages(N_SCANS)
    assert len(messages) == N_SCANS
    detector = CornerDetector(DetectorParams(**NODE_OVERRIDES))
    expected = {
        (m.header.stamp.sec, m.header.stamp.nanosec): _expected(m, detector) for m in messages
    }
    assert len(expected) == N_SCANS, "fr079 stamps are not unique"
    default = CornerDetector()
    assert any(
        len(_expected(m, default)) != len(expected[(m.header.stamp.sec, m.header.stamp.nanosec)])
        for m in messages
    ), "the overrides do not change the output: the test could not see them ignored"
    assert sum(len(k) for k in expected.values()) > 0

    params = [f"_{k}:={v}" for k, v in {**NODE_OVERRIDES, **NODE_OPTIONS}.items()]
    node = master.start(master.node_command("__name:=lc_main", *params), "node_main")

    received: dict[tuple[int, int], list[Any]] = {}
    order: list[tuple[int, int]] = []
    markers: dict[tuple[int, int], Any] = {}
    published_at: dict[tuple[int, int], float] = {}
    latency: list[float] = []

    def on_corners(msg: Any) -> None:
        now = time.perf_counter()
        key = (msg.header.stamp.secs, msg.header.stamp.nsecs)
        received.setdefault(key, []).append(msg)
        order.append(key)
        if key in published_at:
            latency.append(now - published_at[key])

    def on_markers(msg: Any) -> None:
        if msg.markers:
            stamp = msg.markers[0].header.stamp
            markers[(stamp.secs, stamp.nsecs)] = msg

    sub = rospy.Subscriber("/corners", PoseArray, on_corners, queue_size=N_SCANS + 10)
    marker_sub = rospy.Subscriber("/corner_markers", MarkerArray, on_markers, queue_size=N_SCANS)
    pub = rospy.Publisher("/scan", LaserScanMsg, queue_size=N_SCANS + 10)
    try:
        wait_for(
            lambda: master.subscribed("/scan", "/lc_main"),
            STARTUP_TIMEOUT,
            "the node to subscribe /scan",
            node,
        )
        wait_for(
            lambda: (
                pub.get_num_connections() >= 1
                and sub.get_num_connections() >= 1
                and marker_sub.get_num_connections() >= 1
            ),
            STARTUP_TIMEOUT,
            "topic connections",
            node,
        )
        ros_msgs = [_as_ros1(m) for m in messages]

        # a malformed scan first: logged and skipped, the node carries on
        bad = _as_ros1(messages[0])
        bad.header.stamp = rospy.Time(1, 0)
        bad.angle_increment = 0.0
        pub.publish(bad)

        publish_paced(pub, ros_msgs, published_at, lambda s: (s.secs, s.nsecs), RATE_HZ)
        deadline = time.monotonic() + 20.0
        while time.monotonic() < deadline and (len(received) < N_SCANS or len(markers) < N_SCANS):
            time.sleep(0.05)
        time.sleep(0.3)  # anything extra would arrive now
        alive = node.poll() is None
    finally:
        sub.unregister()
        marker_sub.unregister()
        pub.unregister()
        stop(node, "node_main")

    assert alive, f"the node died:\n{master.log('node_main')}"
    assert (1, 0) not in received, "the malformed scan produced output"
    keys = list(expected)
    missing = [keys.index(k) for k in set(expected) - set(received)]
    assert not missing, f"no PoseArray for {len(missing)} scans, indices {sorted(missing)[:20]}"
    assert set(received) == set(expected)
    assert all(len(v) == 1 for v in received.values()), "a scan was answered more than once"
    assert order == sorted(order), "outputs arrived out of order"
    frames = {m.header.frame_id for m in messages}
    for key, (msg,) in received.items():
        assert msg.header.frame_id in frames
        kps = expected[key]
        check_poses(msg, kps, key)
        arrows = [m for m in markers[key].markers if m.type == 0 and m.action == 0]
        assert len(arrows) == len(kps)

    lat_ms = np.array(latency) * 1e3
    assert lat_ms.size == N_SCANS
    print(
        f"\nROS 1 end-to-end latency over {lat_ms.size} fr079 scans at {RATE_HZ:g} Hz "
        f"(publish -> PoseArray received): median {np.median(lat_ms):.2f} ms, "
        f"p95 {np.percentile(lat_ms, 95):.2f} ms, max {lat_ms.max():.2f} ms; "
        f"{sum(len(k) for k in expected.values())} keypoints"
    )


def test_invalid_parameter_stops_node_with_one_line_error(master: RosMaster) -> None:
    proc = master.start(master.node_command("__name:=lc_bad", "_min_points:=1"), "node_bad")
    try:
        proc.wait(timeout=STARTUP_TIMEOUT)
    except subprocess.TimeoutExpired:
        pytest.fail("the node kept running with min_points=1")
    assert proc.returncode == 2
    errors = [line for line in master.log("node_bad").splitlines() if "error:" in line]
    assert len(errors) == 1 and "min_points" in errors[0], master.log("node_bad")


def test_launch_file_starts_the_node(master: RosMaster) -> None:
    """roslaunch finds the package folder and runs the node; it answers a scan."""
    rospy = master.rospy
    from geometry_msgs.msg import PoseArray
    from sensor_msgs.msg import LaserScan as LaserScanMsg

    launch = ROS_PACKAGE_DIR / "launch" / "laser_corners.launch"
    master.env["ROS_PACKAGE_PATH"] = str(ROS_PACKAGE_DIR)
    proc = master.start(["roslaunch", "--wait", str(launch), "scan:=/launch_scan"], "roslaunch")
    got: list[Any] = []
    sub = rospy.Subscriber("/corners", PoseArray, got.append, queue_size=10)
    pub = rospy.Publisher("/launch_scan", LaserScanMsg, queue_size=10)
    try:
        wait_for(
            lambda: master.subscribed("/launch_scan", "/laser_corners"),
            STARTUP_TIMEOUT,
            "the launched node to subscribe /launch_scan",
            proc,
        )
        wait_for(
            lambda: pub.get_num_connections() >= 1 and sub.get_num_connections() >= 1,
            STARTUP_TIMEOUT,
            "topic connections",
            proc,
        )
        msg = _as_ros1(_fr079_messages(1)[0])
        pub.publish(msg)
        wait_for(lambda: len(got) >= 1, 10.0, "a PoseArray from the launched node", proc)
    finally:
        sub.unregister()
        pub.unregister()
        stop(proc, "roslaunch")
    assert got[0].header.stamp == msg.header.stamp
    assert got[0].header.frame_id == msg.header.frame_id


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM], ids=["SIGINT", "SIGTERM"])
def test_signal_stops_running_node_cleanly(master: RosMaster, sig: signal.Signals) -> None:
    """Ctrl-C or SIGTERM to a connected node: exit code 0, a summary line, no traceback."""
    name = f"lc_{sig.name.lower()}"
    proc = master.start(master.node_command(f"__name:={name}", f"scan:=/{name}_scan"), name)
    wait_for(
        lambda: master.subscribed(f"/{name}_scan", f"/{name}"),
        STARTUP_TIMEOUT,
        f"the node to subscribe /{name}_scan",
        proc,
    )
    os.kill(proc.pid, sig)
    try:
        proc.wait(timeout=STARTUP_TIMEOUT)
    except subprocess.TimeoutExpired:
        pytest.fail(f"the node kept running after {sig.name}")
    log = master.log(name)
    assert proc.returncode == 0, log
    assert "Traceback" not in log, log
    assert "0 scans processed, 0 skipped" in log, log


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM], ids=["SIGINT", "SIGTERM"])
def test_signal_while_waiting_for_master_exits_cleanly(tmp_path: Path, sig: signal.Signals) -> None:
    """No master: rospy retries; Ctrl-C (or SIGTERM) ends it with one line and exit code 0."""
    _ros1()
    uri = f"http://127.0.0.1:{_free_port()}"  # nothing listens there
    env = _ros1_env(uri, tmp_path)
    out, err = tmp_path / "stdout.log", tmp_path / "stderr.log"
    with out.open("wb") as stdout, err.open("wb") as stderr:
        proc = subprocess.Popen(
            cli_command("ros1"),
            env=env,
            stdout=stdout,
            stderr=stderr,
            start_new_session=True,
            preexec_fn=die_with_parent(),
        )
    try:
        wait_for(
            lambda: "Unable to register with master" in out.read_text(errors="replace"),
            STARTUP_TIMEOUT,
            "rospy to say it waits for the master",
            proc,
        )
        os.kill(proc.pid, sig)
        try:
            proc.wait(timeout=STARTUP_TIMEOUT)
        except subprocess.TimeoutExpired:
            pytest.fail(f"the node kept waiting for the master after {sig.name}")
    finally:
        stop(proc, "node_no_master")
    text = err.read_text(errors="replace") + out.read_text(errors="replace")
    assert proc.returncode == 0, text
    assert "Traceback" not in text and "Exception" not in text, text
    ours = [line for line in text.splitlines() if line.startswith("laser_corners:")]
    assert ours == [
        f"laser_corners: shut down before the node started (ROS master {uri} not reached)"
    ], text


# ------------------------------------------------------------------ ROS 1 beside ROS 2 wheels
def test_message_finder_loads_packages_beside_rospy(tmp_path: Path) -> None:
    """ROS 2's wheels shadow sensor_msgs & co. on sys.path; the finder picks rospy's folder."""
    from laser_corners.ros.ros1_node import Ros1MessageFinder

    (tmp_path / "fake_msgs").mkdir()
    (tmp_path / "fake_msgs" / "__init__.py").write_text("")
    finder = Ros1MessageFinder(tmp_path)
    spec = finder.find_spec("fake_msgs")
    assert spec is not None and Path(spec.origin).parent == tmp_path / "fake_msgs"
    assert finder.find_spec("fake_msgs.msg") is None  # submodules follow the package's path
    assert finder.find_spec("other_msgs") is None  # not in the folder
    assert finder.find_spec("numpy") is None  # not a message package


def test_ros1_refuses_when_ros2_messages_are_loaded(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from types import SimpleNamespace

    from laser_corners.ros.ros1_node import Ros1MessageFinder, _install_message_finder

    root = tmp_path / "dist-packages"
    (root / "fake_msgs").mkdir(parents=True)
    (root / "fake_msgs" / "__init__.py").write_text("")
    elsewhere = SimpleNamespace(__file__=str(tmp_path / "venv" / "fake_msgs" / "__init__.py"))
    monkeypatch.setitem(sys.modules, "fake_msgs", elsewhere)
    with pytest.raises(LaserCornersError, match="ROS 1 and ROS 2 messages cannot share"):
        _install_message_finder(root)
    assert not [f for f in sys.meta_path if isinstance(f, Ros1MessageFinder) and f.root == root]


STRAY_CONNECTION = """
import sys
from laser_corners.ros.ros1_node import import_rospy, release_stray_threads
import_rospy()
from rospy.topics import _PublisherImpl
from std_msgs.msg import String


class Transport:  # what a subscriber's TCPROS connection to our publisher offers
    endpoint_id = "/late_subscriber"
    done = False
    def set_cleanup_callback(self, callback):
        self.callback = callback
    def close(self):
        self.done = True
        self.callback(self)
    def write_data(self, data):
        pass


publisher = _PublisherImpl("/corners", String)
publisher.queue_size = 10
publisher.close()  # what rospy's shutdown did a moment before
try:
    publisher.add_connection(Transport())  # a subscriber's connection arriving after it
except TypeError:  # rospy: the closed publisher's listeners are None
    pass
print("released", release_stray_threads(5.0), flush=True)
"""


def test_a_connection_arriving_during_shutdown_does_not_keep_the_node_alive(
    tmp_path: Path,
) -> None:
    """The flaky SIGTERM test's cause: rospy wraps a subscriber's connection to a queued
    publisher in a QueuedConnection, whose non-daemon thread waits for data, *before* it
    finds the publisher closed; nobody closes that connection, and Python's exit waits for the
    thread forever. Under load a subscriber (roscore's rosout node, to /rosout) often connects
    while the node shuts down. ``release_stray_threads`` (run by ``main`` after shutdown)
    closes such connections: the process exits."""
    _ros1()
    env = {**os.environ, "PYTHONPATH": str(REPO_ROOT / "src")}
    process = subprocess.Popen(
        [sys.executable, "-c", STRAY_CONNECTION],
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        preexec_fn=die_with_parent(),
    )
    try:
        out, err = process.communicate(timeout=60)
    except subprocess.TimeoutExpired:
        process.kill()
        out, err = process.communicate()
        pytest.fail(f"the process kept running after its last line: {out} {err}")
    assert process.returncode == 0, err
    assert "released 1" in out, (out, err)
