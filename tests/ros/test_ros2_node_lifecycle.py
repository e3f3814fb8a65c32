"""The ROS 2 node as a managed (lifecycle) node for nav2's lifecycle manager, over real DDS
(issue 33): ``-p lifecycle:=true``, transitions driven with ``lifecycle_msgs/srv/ChangeState``
as nav2's lifecycle manager sends them; scans are processed only while active.

Set-up and replay helpers of ``ros2_tools`` and ``ros2_replay`` (fr079's scans, its odometry on
``/tf``, the node as a ``laser-corners ros2`` subprocess).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest
from ros2_replay import Replay, fr079_with_odometry, key_of, running, tf_args, to_msg
from ros2_tools import (
    REAL_DDS_MARKS,
    STARTUP_TIMEOUT,
    Ros2,
    call_service,
    check_clean_exit,
    interrupt,
    isolated_ros2,
    parameter_client,
    set_parameters,
    torn_down,
    wait_discovered,
)
from ros_helpers import wait_for

pytest.importorskip("gtsam")

pytestmark = REAL_DDS_MARKS


@pytest.fixture(scope="module")
def ros2(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Ros2]:
    yield from isolated_ros2(tmp_path_factory)


class Lifecycle:
    """ChangeState / GetState clients of the node ``name`` (what nav2's lifecycle manager
    calls)."""

    def __init__(self, ros2: Ros2, name: str, proc: Any) -> None:
        from lifecycle_msgs.srv import ChangeState, GetState

        self.node, self.ChangeState, self.GetState = ros2.node, ChangeState, GetState
        base = ros2.node_path(name)
        self.change = ros2.node.create_client(ChangeState, f"{base}/change_state")
        self.get = ros2.node.create_client(GetState, f"{base}/get_state")
        for client in (self.change, self.get):
            wait_for(client.service_is_ready, STARTUP_TIMEOUT, "the lifecycle services", proc)

    def state(self) -> str:
        request = self.GetState.Request()
        answer = call_service(lambda: self.get.call_async(request), "get_state")
        return str(answer.current_state.label)

    def transition(self, label: str) -> bool:
        """Request the transition ``label`` (configure, activate, ...); its success."""
        from lifecycle_msgs.msg import Transition

        ids = {
            "configure": Transition.TRANSITION_CONFIGURE,
            "activate": Transition.TRANSITION_ACTIVATE,
            "deactivate": Transition.TRANSITION_DEACTIVATE,
            "cleanup": Transition.TRANSITION_CLEANUP,
            "shutdown": Transition.TRANSITION_INACTIVE_SHUTDOWN,
        }
        request = self.ChangeState.Request()
        request.transition.id = ids[label]
        return bool(call_service(lambda: self.change.call_async(request), label).success)

    def destroy(self) -> None:
        self.node.destroy_client(self.change)
        self.node.destroy_client(self.get)


def _set(ros2: Ros2, name: str, **values: Any) -> None:
    with parameter_client(ros2.node, ros2.node_path(name)) as client:
        results = set_parameters(client, **values)
        assert all(r.successful for r in results), results


def _send(replay: Replay, scans: list[Any], msgs: list[Any], indices: range) -> None:
    for i in indices:
        replay.odometry_until(scans[i].stamp + 0.5)
        replay.scan_pub.publish(msgs[i])
        time.sleep(0.05)


def test_a_managed_node_processes_scans_only_while_active(ros2: Ros2, tmp_path: Path) -> None:
    """unconfigured -> (configure fails on a bad output, stays) -> configure -> inactive ->
    activate -> active -> deactivate -> inactive -> shutdown (the map folder written); scans
    sent while not active give no pose, nor does the node subscribe them then."""
    scans, odometry, mount = fr079_with_odometry(60)
    msgs = [to_msg(s) for s in scans]
    keys = [key_of(m.header.stamp) for m in msgs]
    blocker = tmp_path / "a_file"
    blocker.write_text("not a folder")
    name, output = "lc_managed", tmp_path / "map"
    args = ["-p", "mode:=slam", "-p", "lifecycle:=true", "-p", f"output:={blocker / 'x'}"]
    args += tf_args(mount)
    scan_topic = ros2.topic(name, "scan")
    with running(ros2, name, args, odometry, mount) as run:
        got, proc, replay = run.got, run.proc, run.replay
        lifecycle = Lifecycle(ros2, name, proc)
        run.destroy.append(lifecycle.destroy)
        states = [lifecycle.state()]
        _send(replay, scans, msgs, range(0, 10))  # unconfigured: nobody takes them
        assert not lifecycle.transition("configure")  # output checked at configure: refused
        states.append(lifecycle.state())
        _set(ros2, name, output=str(output))  # unconfigured: taken, checked at configure
        assert lifecycle.transition("configure")
        states.append(lifecycle.state())
        _send(replay, scans, msgs, range(10, 20))  # inactive: not taken
        time.sleep(1.0)
        assert not got.poses and ros2.node.count_subscribers(scan_topic) == 0
        assert lifecycle.transition("activate")
        states.append(lifecycle.state())
        wait_discovered(ros2.node, proc, "the subscription", (scan_topic,), timeout=10.0)
        time.sleep(1.0)  # the node's side of it matches too
        replay.next_odom = 0
        _send(replay, scans, msgs, range(20, 40))  # active: mapped
        wait_for(lambda: got.count(keys[25:40]) == 15, 30.0, "poses while active", proc)
        assert lifecycle.transition("deactivate")
        states.append(lifecycle.state())
        before = len(got.poses)
        _send(replay, scans, msgs, range(40, 60))  # inactive again: not taken
        time.sleep(1.5)
        assert len(got.poses) == before and ros2.node.count_subscribers(scan_topic) == 0
        assert lifecycle.transition("shutdown")  # summary, the map folder written
        states.append(lifecycle.state())
        returncode = interrupt(proc)
    log = ros2.log(name)
    check_clean_exit(returncode, log)
    assert states == [
        "unconfigured",
        "unconfigured",
        "inactive",
        "active",
        "inactive",
        "finalized",
    ], log
    assert f"configure failed: output {blocker / 'x'}: not writable" in log, log
    assert not any(k in got.poses for k in keys[:20] + keys[40:]), "a scan taken while inactive"
    assert f"map written to {output}" in log and (output / "map.yaml").is_file(), log
    assert "lifecycle shutdown: " in log, log


def test_without_lifecycle_the_node_configures_and_activates_itself(ros2: Ros2) -> None:
    """The default (``lifecycle:=false``): active at once, as before; the lifecycle services
    say so (nav2's autostart)."""
    name = "lc_autostart"
    proc = ros2.start(name, "-p", "mode:=detector")
    destroy: list[Callable[[], object]] = []
    with torn_down(ros2.node, proc, name, [], destroy):
        lifecycle = Lifecycle(ros2, name, proc)
        destroy.append(lifecycle.destroy)
        assert lifecycle.state() == "active"
        wait_discovered(ros2.node, proc, "the scan subscription", (ros2.topic(name, "scan"),))
