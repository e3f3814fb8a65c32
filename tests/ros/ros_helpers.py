"""Helpers shared by the ROS 1 and ROS 2 node tests (imported as ``ros_helpers``).

* :func:`skip_or_fail`: skip with a reason, but fail in CI (``CI=true``), where ``make test``
  installs ROS 1 (apt-get) and ROS 2 (the ``ros2`` extra), so a broken install step cannot
  hide behind a skip;
* :func:`spawn`: start a node (or roscore) in its own process group that dies with this
  process, also when pytest is killed with SIGKILL and no teardown runs;
* :func:`wait_for`, :func:`stop`: bounded waits and teardown of the processes a test started;
* :func:`check_poses`: a PoseArray (ROS 1 or ROS 2) carries the expected keypoints;
* :func:`publish_paced`: publish messages at a fixed rate, noting when each went out;
* :func:`isolated_message_packages`: ROS 1 (genpy) and ROS 2 (rosidl) message packages have the
  same names (``sensor_msgs``, ``geometry_msgs``, ...); a test module imports one family and
  hands ``sys.modules`` back without it, so both test modules can run in one pytest process.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from types import SimpleNamespace
from typing import IO, Any

import numpy as np
import pytest

from conftest import die_with_parent
from laser_corners import Keypoints, LaserScan
from laser_corners.sim import corner_scan

REPO_ROOT = Path(__file__).resolve().parents[2]
FR079 = (REPO_ROOT / ".." / "shared" / "data" / "real" / "fr079.bag").resolve()
MESSAGE_SUFFIXES = ("_msgs", "_srvs")  # the names ROS 1 and ROS 2 share


def skip_or_fail(reason: str) -> None:
    """Skip with ``reason``; in CI (``CI=true``) fail instead."""
    if os.environ.get("CI", "").lower() == "true":
        pytest.fail(f"expected in CI (make test installs it): {reason}")
    pytest.skip(reason)


def wait_for(
    predicate: Callable[[], object],
    timeout: float,
    what: str,
    proc: subprocess.Popen[bytes] | None = None,
) -> None:
    """Poll ``predicate`` every 50 ms; fail after ``timeout`` s or when ``proc`` exits."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if predicate():
            return
        if proc is not None and proc.poll() is not None:
            pytest.fail(f"{what}: process exited with code {proc.returncode}")
        time.sleep(0.05)
    pytest.fail(f"timed out after {timeout:.0f} s waiting for {what}")


def check_poses(msg: Any, kps: Keypoints, key: object) -> None:
    """The poses of the PoseArray ``msg`` (answering scan ``key``) are the keypoints ``kps``."""
    got = np.array([[p.position.x, p.position.y] for p in msg.poses]).reshape(-1, 2)
    assert got.shape == kps.xy.shape, f"scan {key}: {len(got)} poses, expected {len(kps)}"
    np.testing.assert_allclose(got, kps.xy, rtol=0, atol=1e-9)
    z = np.array([p.orientation.z for p in msg.poses])
    w = np.array([p.orientation.w for p in msg.poses])
    np.testing.assert_allclose(z, np.sin(kps.orientation / 2), rtol=0, atol=1e-9)
    np.testing.assert_allclose(w, np.cos(kps.orientation / 2), rtol=0, atol=1e-9)


def spawn(args: list[str], env: dict[str, str], log: IO[bytes]) -> subprocess.Popen[bytes]:
    """Start ``args`` in a new process group, output to ``log``; it gets SIGTERM when this
    process dies (``conftest.die_with_parent``), so no node outlives a killed pytest."""
    return subprocess.Popen(
        args,
        env=env,
        stdout=log,
        stderr=subprocess.STDOUT,
        start_new_session=True,
        preexec_fn=die_with_parent(),
    )


def stop(proc: subprocess.Popen[bytes], name: str) -> None:
    """SIGINT, then SIGKILL, the process group of ``proc`` (which the test started)."""
    if proc.poll() is not None:
        return
    for sig, wait in ((signal.SIGINT, 10.0), (signal.SIGKILL, 5.0)):
        try:
            os.killpg(proc.pid, sig)
        except ProcessLookupError:
            return
        try:
            proc.wait(timeout=wait)
            return
        except subprocess.TimeoutExpired:
            continue
    raise RuntimeError(f"{name} (pid {proc.pid}) did not stop")


def cli_command(*args: str) -> list[str]:
    """``laser-corners *args`` with this interpreter's environment."""
    script = Path(sys.executable).with_name("laser-corners")
    if script.is_file():
        return [str(script), *args]
    return [sys.executable, "-c", "from laser_corners.cli import main; main()", *args]


def _is_message_module(name: str) -> bool:
    return name.split(".", 1)[0].endswith(MESSAGE_SUFFIXES)


@contextmanager
def isolated_message_packages() -> Iterator[None]:
    """Run a block with no message package imported; afterwards restore the previous ones.

    ``sys.meta_path`` is restored too, and has no ROS 1 message finder inside the block (the
    ROS 1 node adds one for its message packages).
    """
    saved = {k: v for k, v in sys.modules.items() if _is_message_module(k)}
    for name in saved:
        del sys.modules[name]
    meta_path = list(sys.meta_path)
    sys.meta_path[:] = [f for f in meta_path if type(f).__name__ != "Ros1MessageFinder"]
    try:
        yield
    finally:
        for name in [k for k in sys.modules if _is_message_module(k)]:
            del sys.modules[name]
        sys.modules.update(saved)
        sys.meta_path[:] = meta_path


def scan_msg(scan: LaserScan, ros2: bool = False, angle_max: float | None = None) -> Any:
    """A sensor_msgs/LaserScan-like object with the fields of ``scan``."""
    stamp = scan.stamp or 0.0
    sec, nsec = int(stamp), round((stamp - int(stamp)) * 1e9)
    header_stamp = (
        SimpleNamespace(sec=sec, nanosec=nsec) if ros2 else SimpleNamespace(secs=sec, nsecs=nsec)
    )
    return SimpleNamespace(
        header=SimpleNamespace(stamp=header_stamp, frame_id=scan.frame_id),
        angle_min=scan.angle_min,
        angle_max=angle_max if angle_max is not None else float(scan.angles[-1]),
        angle_increment=scan.angle_increment,
        time_increment=0.0,
        scan_time=0.0,
        range_min=scan.range_min,
        range_max=scan.range_max,
        ranges=[float(r) for r in scan.ranges],
        intensities=[],
    )


def stamped_corner_scan() -> LaserScan:
    """The simulated corner scan, stamped 1234.5 s in frame ``laser``."""
    base = corner_scan()
    return LaserScan(
        base.ranges,
        base.angle_min,
        base.angle_increment,
        base.range_min,
        base.range_max,
        stamp=1234.5,
        frame_id="laser",
    )


def publish_paced(
    pub: Any,
    msgs: list[Any],
    published_at: dict[Any, float],
    key: Callable[[Any], Any],
    rate_hz: float,
) -> None:
    """Publish ``msgs`` on ``pub`` at ``rate_hz``, noting in ``published_at`` when each went
    out (``time.perf_counter()``) under ``key(msg.header.stamp)``."""
    period = 1.0 / rate_hz
    start = time.perf_counter()
    for i, msg in enumerate(msgs):
        delay = start + i * period - time.perf_counter()
        if delay > 0:
            time.sleep(delay)
        published_at[key(msg.header.stamp)] = time.perf_counter()
        pub.publish(msg)
