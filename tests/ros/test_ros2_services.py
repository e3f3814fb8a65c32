"""The localise mode's run-time map and pose over real DDS (issue 33 item 3): the ``map``
parameter set while running + the ``deserialize_map`` Trigger load another map (slam_toolbox's
deserialize_map, map_server's load_map); AMCL's ``set_initial_pose`` / ``initial_pose.*``
parameters set the pose. Set-up and replay helpers of ``ros2_tools`` and ``ros2_replay``.
"""

from __future__ import annotations

import re
import time
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
from ros2_replay import (
    fr079_with_odometry,
    key_of,
    latched_map,
    offline_map,
    play_rest,
    probe_first,
    running,
    tf_args,
    to_msg,
)
from ros2_tools import (
    REAL_DDS_MARKS,
    Ros2,
    call_trigger,
    check_clean_exit,
    interrupt,
    isolated_ros2,
    parameter_client,
    set_parameters,
    wait_matched,
)
from ros_helpers import wait_for

pytest.importorskip("gtsam")

pytestmark = REAL_DDS_MARKS

N_SCANS = 100


@pytest.fixture(scope="module")
def ros2(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Ros2]:
    yield from isolated_ros2(tmp_path_factory)


def test_a_map_loaded_and_a_pose_set_while_running(ros2: Ros2, tmp_path: Path) -> None:
    """localise in map A: ``map`` set to a missing folder -> deserialize_map refuses with one
    line and A stays; ``map`` set to a map_server map.yaml -> deserialize_map loads it and
    /map is republished; set_initial_pose + initial_pose.* -> the localiser tracks from there
    (no pose on the first scan otherwise); a start-only parameter is refused at run time."""
    scans, odometry, mount = fr079_with_odometry(N_SCANS)
    truth = offline_map(scans, tmp_path / "a")
    msgs = [to_msg(s) for s in scans]
    keys = [key_of(m.header.stamp) for m in msgs]
    name, other = "lc_load", tmp_path / "a" / "map.yaml"
    args = ["-p", "mode:=localise", "-p", f"map:={tmp_path / 'a'}", "-p", "queue_size:=200"]
    args += tf_args(mount)
    with running(ros2, name, args, odometry, mount) as run:
        got, proc, replay = run.got, run.proc, run.replay
        run.subs += latched_map(ros2, name, got, proc)  # map A, at start
        wait_matched(ros2, name, proc)
        with parameter_client(ros2.node, ros2.node_path(name)) as client:
            (refused,) = set_parameters(client, fix_scans=3)
            assert not refused.successful and "read at start only" in refused.reason
            assert all(r.successful for r in set_parameters(client, map="/nonexistent/b"))
            missing = call_trigger(ros2, name, "deserialize_map", proc)
            assert not missing.success and "/nonexistent/b" in missing.message, missing
            assert "\n" not in missing.message
            assert all(r.successful for r in set_parameters(client, map=str(other)))
            loaded = call_trigger(ros2, name, "deserialize_map", proc)
            assert loaded.success and f"loaded {other}" in loaded.message, loaded.message
            wait_for(lambda: len(got.grids) >= 2, 10.0, "the loaded map on /map", proc)
            x, y, yaw = (float(v) for v in truth[0])
            pose = {"initial_pose.x": x, "initial_pose.y": y, "initial_pose.yaw": yaw}
            results = set_parameters(client, **pose, set_initial_pose=True)
            assert all(r.successful for r in results), results
        probe_first(replay, scans, msgs, keys, got, proc)  # a pose at once: from the params
        play_rest(replay, scans, msgs, keys)
        wait_for(lambda: got.count(keys[-1:]) == 1, 60.0, "a pose for the last scan", proc)
        time.sleep(0.5)
        returncode = interrupt(proc)
    log = ros2.log(name)
    check_clean_exit(returncode, log)
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
