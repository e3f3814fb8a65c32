"""Helpers of the ROS 2 node tests for the node's process (imported as ``ros2_tools``; rclpy
is imported lazily).

This process's rclpy node on a domain of its own (:class:`Ros2`, :func:`isolated_ros2`), the
node processes a test starts, bounded waits for processes, discovery and service answers,
Trigger and parameter calls, and the teardown, exit and log checks of a node a test started.
What goes to the node and comes back (messages, replays, outputs) is in ``ros2_replay``.
"""

from __future__ import annotations

import os
import re
import signal
import subprocess
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pytest
from ros_helpers import (
    FR079,
    cli_command,
    isolated_message_packages,
    skip_or_fail,
    spawn,
    stop,
    wait_for,
)

STARTUP_TIMEOUT = 45.0  # a loaded 2-core machine: python start, numba load, DDS discovery
REAL_DDS_MARKS = [  # the pytestmark of the tests over real DDS with fr079
    pytest.mark.ros2,
    pytest.mark.real,
    pytest.mark.filterwarnings("ignore:module 'sre_:DeprecationWarning"),  # lark, via rosidl
]
DOMAIN_ID = 1 + os.getpid() % 101
NAMESPACE = f"/lc_test_{os.getpid()}"


@dataclass
class Ros2:
    """This process's rclpy node and the node processes a test starts."""

    rclpy: Any
    node: Any
    env: dict[str, str]
    tmp: Path
    processes: list[tuple[subprocess.Popen[bytes], str]] = field(default_factory=list)

    def start(
        self, name: str, *ros_args: str, env: dict[str, str] | None = None
    ) -> subprocess.Popen[bytes]:
        """``laser-corners ros2`` as node ``name`` in its own namespace (``env``: variables
        to set besides the test's); stopped at teardown."""
        args = cli_command(
            "ros2",
            "--ros-args",
            "-r",
            f"__ns:={NAMESPACE}/{name}",
            "-r",
            f"__node:={name}",
            *ros_args,
        )
        with (self.tmp / f"{name}.log").open("wb") as log:
            proc = spawn(args, {**self.env, **(env or {})}, log)
        self.processes.append((proc, name))
        return proc

    def log(self, name: str) -> str:
        return (self.tmp / f"{name}.log").read_text(errors="replace")

    @staticmethod
    def topic(name: str, topic: str) -> str:
        return f"{NAMESPACE}/{name}/{topic}"

    @staticmethod
    def node_path(name: str) -> str:
        """The full name of the node ``name`` a test started (its parameter and lifecycle
        services are below it)."""
        return f"{NAMESPACE}/{name}/{name}"


def rclpy_or_skip() -> Any:
    """rclpy, or skip (fail in CI) with the reason."""
    from laser_corners.errors import MissingDependencyError
    from laser_corners.ros.ros2_node import import_rclpy

    try:
        return import_rclpy()
    except MissingDependencyError as exc:
        skip_or_fail(f"{exc}; install with: pip install -e '.[ros2]'")


def isolated_ros2(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Ros2]:
    """The ``ros2`` fixture of a test module: :func:`run_ros2` with the message packages
    of ROS 2 imported only meanwhile (``isolated_message_packages``)."""
    with isolated_message_packages():
        yield from run_ros2(tmp_path_factory)


def run_ros2(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Ros2]:
    rclpy = rclpy_or_skip()
    if not FR079.is_file():
        pytest.skip(f"real data file not found: {FR079} (expected ../shared/data/real)")
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.signals import SignalHandlerOptions

    tmp = tmp_path_factory.mktemp("ros2")
    ros_env = {
        "ROS_DOMAIN_ID": str(DOMAIN_ID),
        "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST",
        "ROS_LOG_DIR": str(tmp / "log"),
        "RCUTILS_COLORIZED_OUTPUT": "0",
    }
    env = dict(os.environ, PYTHONUNBUFFERED="1", **ros_env)
    for name in ("ROS_LOCALHOST_ONLY", "ROS_STATIC_PEERS"):
        env.pop(name, None)
    saved = {k: os.environ.get(k) for k in (*ros_env, "ROS_LOCALHOST_ONLY", "ROS_STATIC_PEERS")}
    os.environ.update(ros_env)
    for name in ("ROS_LOCALHOST_ONLY", "ROS_STATIC_PEERS"):
        os.environ.pop(name, None)
    context = rclpy.Context()
    rclpy.init(context=context, domain_id=DOMAIN_ID, signal_handler_options=SignalHandlerOptions.NO)
    node = rclpy.create_node("lc_test", namespace=NAMESPACE, context=context)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    spinner = threading.Thread(target=_spin, args=(executor,), daemon=True)
    spinner.start()
    ros = Ros2(rclpy, node, env, tmp)
    try:
        yield ros
    finally:
        for proc, name in reversed(ros.processes):
            stop(proc, name)
        executor.shutdown(timeout_sec=5.0)
        node.destroy_node()
        rclpy.shutdown(context=context)
        spinner.join(timeout=5.0)
        for key, value in saved.items():
            if value is None:
                os.environ.pop(key, None)
            else:
                os.environ[key] = value


def _spin(executor: Any) -> None:
    from rclpy.executors import ExternalShutdownException

    try:
        executor.spin()
    except ExternalShutdownException:
        pass


def wait_exit(proc: subprocess.Popen[bytes], what: str) -> int:
    try:
        return proc.wait(timeout=STARTUP_TIMEOUT)
    except subprocess.TimeoutExpired:
        pytest.fail(f"the node kept running after {what}")


def interrupt(proc: subprocess.Popen[bytes], sig: signal.Signals = signal.SIGINT) -> int:
    """Send ``sig`` to the node ``proc``; its exit code (fail if it keeps running)."""
    os.kill(proc.pid, sig)
    return wait_exit(proc, sig.name)


def check_clean_exit(returncode: int, log: str) -> None:
    """The node exited with code 0 and no traceback in its ``log``."""
    assert returncode == 0, log
    assert "Traceback" not in log, log


def one_error_line(log: str) -> str:
    """The one line of ``log`` with ``error:`` (fail if there are none or several)."""
    errors = [line for line in log.splitlines() if "error:" in line]
    assert len(errors) == 1, log
    return errors[0]


def wait_discovered(
    node: Any,
    proc: subprocess.Popen[bytes],
    what: str,
    subscribers: tuple[str, ...] = (),
    publishers: tuple[str, ...] = (),
    timeout: float = STARTUP_TIMEOUT,
) -> None:
    """Wait until ``node`` sees a subscriber on each of ``subscribers`` and a publisher on
    each of ``publishers`` (fail after ``timeout`` s or when ``proc`` exits)."""
    wait_for(
        lambda: (
            all(node.count_subscribers(t) >= 1 for t in subscribers)
            and all(node.count_publishers(t) >= 1 for t in publishers)
        ),
        timeout,
        what,
        proc,
    )


@contextmanager
def torn_down(
    node: Any,
    proc: subprocess.Popen[bytes],
    name: str,
    subs: list[Any],
    destroy: list[Callable[[], object]] | None = None,
) -> Iterator[None]:
    """Run a block; afterwards destroy ``subs`` on ``node``, call each of ``destroy`` (both
    lists may grow in the block) and stop the node process ``proc``."""
    try:
        yield
    finally:
        try:
            for sub in subs:
                node.destroy_subscription(sub)
            for fn in destroy or []:
                fn()
        finally:
            stop(proc, name)


def call_service(request: Callable[[], Any], what: str) -> Any:
    """Send a (idempotent) parameter service request; resend if no answer came in 15 s."""
    for _ in range(3):
        future = request()
        deadline = time.monotonic() + 15.0
        while not future.done() and time.monotonic() < deadline:
            time.sleep(0.02)
        if future.done():
            return future.result()
    pytest.fail(f"no answer to {what}")


def set_parameters(client: Any, **values: Any) -> list[Any]:
    """Set parameters through ``client`` (an ``AsyncParameterClient``); the results
    (successful, reason) in order."""
    from rclpy.parameter import Parameter

    params = [Parameter(k, value=v) for k, v in values.items()]
    return list(call_service(lambda: client.set_parameters(params), "set_parameters").results)


@contextmanager
def parameter_client(node: Any, remote: str) -> Iterator[Any]:
    """rclpy's ``AsyncParameterClient`` of the node ``remote`` (its services ready); its
    clients destroyed afterwards (it has no ``destroy`` of its own)."""
    from rclpy.parameter_client import AsyncParameterClient

    client = AsyncParameterClient(node, remote)
    try:
        assert client.wait_for_services(timeout_sec=STARTUP_TIMEOUT), f"no {remote} services"
        yield client
    finally:
        for name, value in vars(client).items():
            if name.endswith("_client"):
                node.destroy_client(value)


def wait_matched(ros2: Ros2, name: str, proc: Any) -> None:
    """Wait until the node ``name``'s scan subscription and pose publisher are discovered."""
    subscribers, publishers = (ros2.topic(name, "scan"),), (ros2.topic(name, "pose"),)
    what = "the node's scan subscription and pose publisher"
    wait_discovered(ros2.node, proc, what, subscribers, publishers)


def call_trigger(ros2: Ros2, name: str, service: str, proc: Any) -> Any:
    """Call the node's ``std_srvs/Trigger`` service ``service``; the response."""
    from std_srvs.srv import Trigger

    client = ros2.node.create_client(Trigger, ros2.topic(name, service))
    try:
        wait_for(client.service_is_ready, STARTUP_TIMEOUT, f"the {service} service", proc)
        return call_service(lambda: client.call_async(Trigger.Request()), service)
    finally:
        ros2.node.destroy_client(client)


def summary_counts(log: str, signal_name: str) -> dict[str, int]:
    """The scan counts of the node's shutdown line."""
    line = re.search(rf"stopped by {signal_name}: .*", log)
    assert line, log
    names = ("scans", "processed", "without odometry", "malformed", "still waiting")
    found = {n: re.search(rf"(\d+) {n}\b", line.group(0)) for n in names}
    assert all(found.values()), line.group(0)
    return {n: int(m.group(1)) for n, m in found.items()}
