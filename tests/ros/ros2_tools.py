"""Helpers of the ROS 2 node test (imported as ``ros2_tools``; rclpy is imported lazily).

Message building from :class:`~laser_corners.LaserScan`, an output recorder, discovery probes,
paced publishing, pose checks, bounded waits for processes, discovery and service answers,
parameter calls, and the teardown and exit checks of a node a test started.
"""

from __future__ import annotations

import os
import signal
import subprocess
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from itertools import islice
from typing import Any

import numpy as np
import pytest
from ros_helpers import FR079, stop, wait_for

from laser_corners import LaserScan
from laser_corners.ros.convert import seconds_to_sec_nanosec

RATE_HZ = 40.0  # publishing rate (as in the ROS 1 test)
STARTUP_TIMEOUT = 45.0  # a loaded 2-core machine: python start, numba load, DDS discovery
Key = tuple[int, int]
REAL_DDS_MARKS = [  # the pytestmark of the tests over real DDS with fr079
    pytest.mark.ros2,
    pytest.mark.real,
    pytest.mark.filterwarnings("ignore:module 'sre_:DeprecationWarning"),  # lark, via rosidl
]


def fr079_scans(n: int) -> list[LaserScan]:
    from laser_corners.io import open_scans

    return list(islice(open_scans(FR079), n))


def to_msg(scan: LaserScan, stamp: Key | None = None) -> Any:
    """A ROS 2 sensor_msgs/LaserScan with the scan's fields (stamp overridable)."""
    from sensor_msgs.msg import LaserScan as LaserScanMsg

    msg = LaserScanMsg()
    sec, nanosec = stamp if stamp is not None else seconds_to_sec_nanosec(scan.stamp)
    msg.header.stamp.sec, msg.header.stamp.nanosec = sec, nanosec
    msg.header.frame_id = scan.frame_id
    msg.angle_min = float(scan.angle_min)
    msg.angle_increment = float(scan.angle_increment)
    msg.angle_max = float(scan.angle_min + (scan.n_beams - 1) * scan.angle_increment)
    msg.range_min, msg.range_max = float(scan.range_min), float(scan.range_max)
    msg.ranges = np.asarray(scan.ranges, dtype=np.float32).tolist()
    return msg


def key_of(stamp: Any) -> Key:
    return (int(stamp.sec), int(stamp.nanosec))


class Outputs:
    """What the node published, by input stamp, with receive times (thread-safe)."""

    def __init__(self) -> None:
        self.lock = threading.Lock()
        self.corners: dict[Key, list[Any]] = {}
        self.order: list[Key] = []
        self.markers: dict[Key, list[Any]] = {}
        self.n_marker_arrays = 0
        self.received_at: dict[Key, float] = {}

    def on_corners(self, msg: Any) -> None:
        now = time.perf_counter()
        key = key_of(msg.header.stamp)
        with self.lock:
            self.corners.setdefault(key, []).append(msg)
            self.order.append(key)
            self.received_at.setdefault(key, now)

    def on_markers(self, msg: Any) -> None:
        with self.lock:
            self.n_marker_arrays += 1
            if msg.markers:
                self.markers.setdefault(key_of(msg.markers[0].header.stamp), []).append(msg)

    def count(self, keys: list[Key], markers: bool = False) -> int:
        table = self.markers if markers else self.corners
        with self.lock:
            return sum(k in table for k in keys)


def probe(
    pub: Any, scan: LaserScan, sec: int, answered: Callable[[Key], bool], proc: Any, what: str
) -> int:
    """Publish copies of ``scan`` stamped ``(sec, k)`` until one is ``answered``; return how
    many were sent.

    An answer proves the whole path is matched: our publisher -> the node's subscription, and
    the node's publisher -> our subscription (DDS discovery is asynchronous on each side).
    """
    deadline = time.monotonic() + STARTUP_TIMEOUT
    k = 0
    while time.monotonic() < deadline:
        pub.publish(to_msg(scan, (sec, k)))
        k += 1
        inner = time.monotonic() + 0.2
        while time.monotonic() < inner:
            if any(answered((sec, i)) for i in range(k)):
                return k
            time.sleep(0.01)
        if proc.poll() is not None:
            pytest.fail(f"{what}: the node exited with code {proc.returncode}")
    pytest.fail(f"timed out after {STARTUP_TIMEOUT:.0f} s waiting for {what}")


def publish_paced(pub: Any, msgs: list[Any], published_at: dict[Key, float]) -> None:
    period = 1.0 / RATE_HZ
    start = time.perf_counter()
    for i, msg in enumerate(msgs):
        delay = start + i * period - time.perf_counter()
        if delay > 0:
            time.sleep(delay)
        published_at[key_of(msg.header.stamp)] = time.perf_counter()
        pub.publish(msg)


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
