"""The localise mode's run-time map and pose over real DDS (issue 33 item 3): the ``map``
parameter set while running + the ``deserialize_map`` Trigger load another map (slam_toolbox's
deserialize_map, map_server's load_map); AMCL's ``set_initial_pose`` / ``initial_pose.*``
parameters set the pose. Set-up and replay helpers as ``test_ros2_slam_node.py``.
"""

from __future__ import annotations

import os
import re
import signal
import time
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
from ros2_tools import call_service, key_of, parameter_client, to_msg, wait_exit
from ros_helpers import isolated_message_packages, stop, wait_for
from test_ros2_node import NAMESPACE, Ros2, _run_ros2
from test_ros2_slam_node import (
    HAS_TF,
    Received,
    Replay,
    _fr079,
    _latched_map,
    _offline_map,
    _play_rest,
    _probe_first,
    _subscribe,
    _trigger,
    _wait_matched,
)

pytest.importorskip("gtsam")

pytestmark = [
    pytest.mark.ros2,
    pytest.mark.real,
    pytest.mark.filterwarnings("ignore:module 'sre_:DeprecationWarning"),
]

N_SCANS = 100


@pytest.fixture(scope="module")
def ros2(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Ros2]:
    with isolated_message_packages():
        yield from _run_ros2(tmp_path_factory)


def _set(client, **values) -> list:
    """Set parameters; the results (successful, reason) in order."""
    from rclpy.parameter import Parameter

    params = [Parameter(k, value=v) for k, v in values.items()]
    return list(call_service(lambda: client.set_parameters(params), "set_parameters").results)


def test_a_map_loaded_and_a_pose_set_while_running(ros2: Ros2, tmp_path: Path) -> None:
    """localise in map A: ``map`` set to a missing folder -> deserialize_map refuses with one
    line and A stays; ``map`` set to a map_server map.yaml -> deserialize_map loads it and
    /map is republished; set_initial_pose + initial_pose.* -> the localiser tracks from there
    (no pose on the first scan otherwise); a start-only parameter is refused at run time."""
    scans, odometry, mount = _fr079(N_SCANS)
    truth = _offline_map(scans, tmp_path / "a")
    msgs = [to_msg(s) for s in scans]
    keys = [key_of(m.header.stamp) for m in msgs]
    name, other = "lc_load", tmp_path / "a" / "map.yaml"
    args = ["-p", "mode:=localise", "-p", f"map:={tmp_path / 'a'}", "-p", "queue_size:=200"]
    if not HAS_TF:
        args += ["-p", "odom_topic:=odom", "-p", f"mount:=[{', '.join(map(str, mount))}]"]
    proc = ros2.start(name, *args)
    got = Received()
    subs = _subscribe(ros2, name, got)
    replay = Replay(ros2, name, odometry, mount)
    try:
        subs += _latched_map(ros2, name, got, proc)  # map A, at start
        _wait_matched(ros2, name, proc)
        with parameter_client(ros2.node, f"{NAMESPACE}/{name}/{name}") as client:
            (refused,) = _set(client, fix_scans=3)
            assert not refused.successful and "read at start only" in refused.reason
            assert all(r.successful for r in _set(client, map="/nonexistent/b"))
            missing = _trigger(ros2, name, "deserialize_map", proc)
            assert not missing.success and "/nonexistent/b" in missing.message, missing
            assert "\n" not in missing.message
            assert all(r.successful for r in _set(client, map=str(other)))
            loaded = _trigger(ros2, name, "deserialize_map", proc)
            assert loaded.success and f"loaded {other}" in loaded.message, loaded.message
            wait_for(lambda: len(got.grids) >= 2, 10.0, "the loaded map on /map", proc)
            x, y, yaw = (float(v) for v in truth[0])
            pose = {"initial_pose.x": x, "initial_pose.y": y, "initial_pose.yaw": yaw}
            results = _set(client, **pose, set_initial_pose=True)
            assert all(r.successful for r in results), results
        _probe_first(replay, scans, msgs, keys, got, proc)  # a pose at once: from the params
        _play_rest(replay, scans, msgs, keys)
        wait_for(lambda: got.count(keys[-1:]) == 1, 60.0, "a pose for the last scan", proc)
        time.sleep(0.5)
        os.kill(proc.pid, signal.SIGINT)
        returncode = wait_exit(proc, "SIGINT")
    finally:
        for sub in subs:
            ros2.node.destroy_subscription(sub)
        replay.destroy()
        stop(proc, name)
    log = ros2.log(name)
    assert returncode == 0 and "Traceback" not in log, log
    assert re.search(r"deserialize_map: loaded .*map\.yaml \(\d+ keyframes\)", log), log
    assert re.search(r"initial_pose \[.*\] applied", log), log
    answered = [i for i, k in enumerate(keys) if k in got.poses]
    assert len(answered) >= 0.9 * N_SCANS, f"{len(answered)} of {N_SCANS} scans got a pose"
    poses = np.array([_xy(got.poses[keys[i]]) for i in answered])
    err = np.hypot(*(poses - truth[answered, :2]).T)
    assert err.max() < 0.3, err.max()


def _xy(msg) -> tuple[float, float]:
    p = msg.pose.pose.position
    return (p.x, p.y)
