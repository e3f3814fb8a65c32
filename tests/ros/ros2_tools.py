"""Helpers of the ROS 2 node test (imported as ``ros2_tools``; rclpy is imported lazily).

Message building from :class:`~laser_corners.LaserScan`, an output recorder, discovery probes,
paced publishing, pose checks and bounded waits for processes and service answers.
"""

from __future__ import annotations

import subprocess
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from itertools import islice
from typing import Any

import numpy as np
import pytest
from ros_helpers import FR079

from laser_corners import Keypoints, LaserScan
from laser_corners.ros.convert import seconds_to_sec_nanosec

RATE_HZ = 40.0  # publishing rate (as in the ROS 1 test)
STARTUP_TIMEOUT = 45.0  # a loaded 2-core machine: python start, numba load, DDS discovery
Key = tuple[int, int]


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


def check_poses(msg: Any, kps: Keypoints, key: Key) -> None:
    got = np.array([[p.position.x, p.position.y] for p in msg.poses]).reshape(-1, 2)
    assert got.shape == kps.xy.shape, f"scan {key}: {len(got)} poses, expected {len(kps)}"
    np.testing.assert_allclose(got, kps.xy, rtol=0, atol=1e-9)
    z = np.array([p.orientation.z for p in msg.poses])
    w = np.array([p.orientation.w for p in msg.poses])
    np.testing.assert_allclose(z, np.sin(kps.orientation / 2), rtol=0, atol=1e-9)
    np.testing.assert_allclose(w, np.cos(kps.orientation / 2), rtol=0, atol=1e-9)


def wait_exit(proc: subprocess.Popen[bytes], what: str) -> int:
    try:
        return proc.wait(timeout=STARTUP_TIMEOUT)
    except subprocess.TimeoutExpired:
        pytest.fail(f"the node kept running after {what}")


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
