"""Processes the ROS tests start die with their parent, even a SIGKILLed one (issue 21, 16).

A small parent process starts a node (or roscore) with :func:`ros_helpers.spawn`, as the node
tests do, and is then killed with SIGKILL, so no teardown runs (a CI timeout kills pytest so):
the node, and the processes it started (roscore's rosmaster and rosout), must be gone within
a few seconds.
"""

from __future__ import annotations

import importlib.util
import json
import os
import shutil
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest
from ros_helpers import REPO_ROOT, cli_command, skip_or_fail

GONE_WITHIN = 20.0  # seconds for a node to shut down on SIGTERM (rclpy, roslaunch)
_PARENT = """
import json, os, sys, time
sys.path[:0] = [os.path.join(sys.argv[1], "tests"), os.path.join(sys.argv[1], "tests", "ros")]
from ros_helpers import spawn
with open(sys.argv[2], "wb") as log:
    child = spawn(json.loads(sys.argv[3]), dict(os.environ), log)
print(child.pid, flush=True)
time.sleep(600)
"""


def _free_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])


def _alive(pid: int) -> bool:
    """Running (a zombie no one reaps, as under a container's init, counts as gone)."""
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return False
    return stat.rsplit(")", 1)[1].split()[0] != "Z"


def _descendants(pid: int) -> dict[int, str]:
    """Every running process below ``pid``, with its command line."""
    parents: dict[int, list[int]] = {}
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                ppid = int((entry / "stat").read_text().rsplit(")", 1)[1].split()[1])
            except (OSError, IndexError, ValueError):
                continue
            parents.setdefault(ppid, []).append(int(entry.name))
    found: dict[int, str] = {}
    todo = list(parents.get(pid, []))
    while todo:
        child = todo.pop()
        try:
            found[child] = (
                Path(f"/proc/{child}/cmdline").read_bytes().replace(b"\0", b" ")
            ).decode()
        except OSError:
            continue
        todo.extend(parents.get(child, []))
    return found


def _command(what: str, tmp: Path) -> tuple[list[str], dict[str, str], str]:
    """Command, environment, and a word the processes it starts must show before the kill."""
    env = dict(os.environ, ROS_HOME=str(tmp), ROS_LOG_DIR=str(tmp / "log"), PYTHONUNBUFFERED="1")
    env["PYTHONPATH"] = os.pathsep.join([str(REPO_ROOT / "src"), env.get("PYTHONPATH", "")])
    if what.startswith("ros2"):
        if importlib.util.find_spec("rclpy") is None:  # not imported here: the node imports it
            skip_or_fail("rclpy not installed; install with: pip install -e '.[ros2]'")
        domain = 1 + (os.getpid() + 50) % 101  # not the domain of ros2_tools.DOMAIN_ID
        env.update(ROS_DOMAIN_ID=str(domain), ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST")
        if what == "ros2 slam node":  # the mapping mode (gtsam, a timer, more subscriptions)
            mode = ["--ros-args", "-p", "mode:=slam", "-p", "odom_topic:=odom"]
            return cli_command("ros2", *mode), env, ""
        return cli_command("ros2"), env, ""
    if shutil.which("roscore") is None:
        skip_or_fail("ROS 1 not installed (no roscore on PATH): `make test` installs it")
    port = _free_port()
    env.update(ROS_MASTER_URI=f"http://127.0.0.1:{port}", ROS_IP="127.0.0.1")
    env.pop("ROS_HOSTNAME", None)
    if what == "ros1 node":  # no master: it waits for one
        return cli_command("ros1"), env, ""
    return ["roscore", "-p", str(port)], env, "rosmaster"


@pytest.mark.parametrize("what", ["ros2 node", "ros2 slam node", "ros1 node", "roscore"])
def test_started_processes_die_with_their_sigkilled_parent(tmp_path: Path, what: str) -> None:
    command, env, wait_for_child = _command(what, tmp_path)
    parent = subprocess.Popen(
        [
            sys.executable,
            "-c",
            _PARENT,
            str(REPO_ROOT),
            str(tmp_path / "node.log"),
            json.dumps(command),
        ],
        env=env,
        stdout=subprocess.PIPE,
        text=True,
        start_new_session=True,
    )
    node = 0
    try:
        assert parent.stdout is not None
        node = int(parent.stdout.readline())
        deadline = time.monotonic() + 30.0
        started: dict[int, str] = {}
        while time.monotonic() < deadline:  # let it start what it starts (roscore: rosmaster)
            started = _descendants(node)
            if not wait_for_child or any(wait_for_child in c for c in started.values()):
                break
            time.sleep(0.2)
        time.sleep(2.0)  # the node's own start-up (imports, signal handlers)
        started = _descendants(node)
        assert _alive(node), (tmp_path / "node.log").read_text(errors="replace")
        if wait_for_child:
            assert any(wait_for_child in c for c in started.values()), started
        parent.send_signal(signal.SIGKILL)
        parent.wait(timeout=10)
        watched = [node, *started]
        deadline = time.monotonic() + GONE_WITHIN
        while time.monotonic() < deadline and any(_alive(pid) for pid in watched):
            time.sleep(0.1)
        left = {pid: started.get(pid, what) for pid in watched if _alive(pid)}
        assert not left, f"still running {GONE_WITHIN:.0f} s after the parent was killed: {left}"
    finally:
        if parent.poll() is None:
            parent.kill()
            parent.wait(timeout=10)
        for pid in [node, *_descendants(node)] if node else []:
            if _alive(pid):
                os.kill(pid, signal.SIGKILL)
