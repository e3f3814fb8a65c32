"""The mapping modes are never blocked, measured over real DDS (issue 33 "Done when"):
fr079 replayed at 5x real time (a slice of the bag), parameter calls answered while the node
relocalises, every scan sent processed or counted, the callbacks' worst case.

Same set-up as ``test_ros2_slam_node.py`` (the replay helpers of ``ros2_replay``): the node
runs as a ``laser-corners ros2`` subprocess, this process publishes the bag's scans and its
odometry on ``/tf`` (``nav_msgs/Odometry`` without ``tf2_msgs``).
"""

from __future__ import annotations

import re
import threading
import time
from collections.abc import Iterator
from contextlib import ExitStack
from pathlib import Path
from typing import Any

import pytest
from ros2_replay import (
    Replay,
    fr079_with_odometry,
    key_of,
    offline_map,
    probe_first,
    running,
    tf_args,
    to_msg,
)
from ros2_tools import (
    REAL_DDS_MARKS,
    STARTUP_TIMEOUT,
    Ros2,
    call_service,
    check_clean_exit,
    interrupt,
    isolated_ros2,
    parameter_client,
    summary_counts,
    wait_matched,
)
from ros_helpers import wait_for

pytest.importorskip("gtsam")

pytestmark = REAL_DDS_MARKS

SPEED = 5.0  # times real time
N_SCANS = 200  # 43 s of fr079: 8.6 s at 5x


@pytest.fixture(scope="module")
def ros2(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Ros2]:
    yield from isolated_ros2(tmp_path_factory)


def _play(replay: Replay, scans: list[Any], msgs: list[Any], first: int = 0) -> int:
    """Scans ``first..`` at SPEED times their bag timing, the odometry 0.5 s (bag time)
    ahead; the number published."""
    start, t0 = time.perf_counter(), scans[first].stamp
    for i in range(first, len(scans)):
        delay = start + (scans[i].stamp - t0) / SPEED - time.perf_counter()
        if delay > 0:
            time.sleep(delay)
        replay.odometry_until(scans[i].stamp + 0.5)
        replay.scan_pub.publish(msgs[i])
    replay.odometry_until(float("inf"))
    return len(scans) - first


def _summary(log: str, signal_name: str) -> dict[str, float]:
    """Every count of the node's shutdown line."""
    counts: dict[str, float] = dict(summary_counts(log, signal_name))
    line = re.search(rf"stopped by {signal_name}: .*", log).group(0)
    for name, pattern in {
        "before a fix": r"(\d+) before a fix",
        "busy": r"(\d+) scans dropped while the worker was busy",
        "lost": r"(\d+) scans lost before the node",
        "longest callback": r"longest callback ([\d.]+) ms",
    }.items():
        found = re.search(pattern, line)
        assert found, line
        counts[name] = float(found.group(1))
    return counts


def test_parameter_calls_are_answered_while_it_relocalises(ros2: Ros2, tmp_path: Path) -> None:
    """localise, no initial pose: the node searches the whole map while fr079 comes at 5x;
    GetParameters calls meanwhile are answered within 200 ms each (the issue measured
    0.5-2.4 s when the search ran in the callback). ``fix_scans:=150`` (a LocaliseOptions
    field as a parameter) keeps it searching for the first 150 scans at least."""
    scans, odometry, mount = fr079_with_odometry(N_SCANS)
    offline_map(scans, tmp_path / "map")
    msgs = [to_msg(s) for s in scans]
    name = "lc_busy"
    args = ["-p", "mode:=localise", "-p", f"map:={tmp_path / 'map'}", "-p", "fix_scans:=150"]
    args += ["-p", "places.min_votes:=2", "-p", "queue_size:=1000", *tf_args(mount)]
    latencies: list[float] = []
    remote = ros2.node_path(name)
    with running(ros2, name, args, odometry, mount) as run, ExitStack() as stack:
        got, proc, replay = run.got, run.proc, run.replay
        wait_matched(ros2, name, proc)
        client = stack.enter_context(parameter_client(ros2.node, remote))
        names = ["fix_scans", "places.min_votes", "map"]
        values = call_service(lambda: client.get_parameters(names), "get_parameters").values
        assert [values[0].integer_value, values[1].integer_value] == [150, 2]
        assert values[2].string_value == str(tmp_path / "map")
        time.sleep(1.0)  # the node's side of the scan subscription (best effort) matches too
        player = threading.Thread(target=_play, args=(replay, scans, msgs), daemon=True)
        player.start()
        time.sleep(0.3)  # the search is under way
        while player.is_alive() and not got.poses:  # relocalising: no pose yet
            began = time.perf_counter()
            future = client.get_parameters(names)
            while not future.done() and time.perf_counter() - began < 5.0:
                time.sleep(0.002)
            assert future.done(), "a parameter call not answered in 5 s"
            latencies.append((time.perf_counter() - began) * 1e3)
            time.sleep(0.2)
        player.join(timeout=60.0)
        time.sleep(2.0)
        returncode = interrupt(proc)
    log = ros2.log(name)
    check_clean_exit(returncode, log)
    counts = _summary(log, "SIGINT")
    assert counts["before a fix"] >= 150, log  # it searched (fix_scans reached the localiser)
    assert len(latencies) >= 10, f"{len(latencies)} calls while relocalising: {log}"
    assert max(latencies) <= 200.0, f"parameter calls while relocalising: {latencies} ms"
    print(
        f"\n{len(latencies)} GetParameters calls while relocalising at {SPEED:g}x: max "
        f"{max(latencies):.1f} ms, median {sorted(latencies)[len(latencies) // 2]:.1f} ms; "
        f"node: {re.search(r'stopped by SIGINT: .*', log).group(0)}"
    )


def test_at_5x_every_scan_sent_is_processed_or_counted(ros2: Ros2, tmp_path: Path) -> None:
    """slam, fr079 at 5x real time: sent = arrived + dropped while busy + lost on the way,
    arrived = processed + without odometry + malformed + waiting + before a fix, and no
    callback took over 50 ms."""
    scans, odometry, mount = fr079_with_odometry(N_SCANS)
    msgs = [to_msg(s) for s in scans]
    keys = [key_of(m.header.stamp) for m in msgs]
    name = "lc_fast"
    args = ["-p", "mode:=slam", *tf_args(mount)]  # queue_size 50 (default)
    probes = 0
    with running(ros2, name, args, odometry, mount) as run:
        got, proc, replay = run.got, run.proc, run.replay
        wait_matched(ros2, name, proc)
        time.sleep(1.0)  # the node's side of the scan subscription (best effort) matches too
        while not got.count(keys[:1]):  # the first scan, until answered (discovery)
            assert probes < 10 and proc.poll() is None, "no pose for the first scan"
            replay.next_odom = 0
            replay.odometry_until(scans[0].stamp + 0.5)
            replay.scan_pub.publish(msgs[0])
            probes += 1
            deadline = time.monotonic() + 3.0
            while not got.count(keys[:1]) and time.monotonic() < deadline:
                time.sleep(0.05)
        sent = probes + _play(replay, scans, msgs, first=1)
        time.sleep(3.0)  # the last scans' tf_wait and the worker's queue
        returncode = interrupt(proc)
    log = ros2.log(name)
    check_clean_exit(returncode, log)
    c = _summary(log, "SIGINT")
    arrived = c["scans"]
    # probes sent before the node's side matched never arrived (and are not DDS's losses)
    assert sent - (probes - 1) <= arrived + c["busy"] + c["lost"] <= sent, (sent, log)
    accounted = c["processed"] + c["without odometry"] + c["malformed"] + c["still waiting"]
    assert accounted + c["before a fix"] == arrived, log
    assert c["still waiting"] == 0 and c["processed"] >= 0.9 * N_SCANS, log
    assert c["longest callback"] <= 50.0, log
    print(
        f"\nfr079 at {SPEED:g}x: {sent} scans sent ({probes} probe(s)); node: "
        f"{re.search(r'stopped by SIGINT: .*', log).group(0)}"
    )


def test_parameter_calls_are_answered_while_a_service_runs(ros2: Ros2, tmp_path: Path) -> None:
    """slam: serialize_map writes the map folder of fr079's first 300 scans (the final
    optimisation: about a second) on the worker; GetParameters calls meanwhile are answered
    within 200 ms each (the service's wait for the worker no longer holds the executor)."""
    from std_srvs.srv import Trigger

    scans, odometry, mount = fr079_with_odometry(300)
    msgs = [to_msg(s) for s in scans]
    keys = [key_of(m.header.stamp) for m in msgs]
    name, output = "lc_serialize", tmp_path / "map"
    args = ["-p", "mode:=slam", "-p", f"output:={output}", "-p", "queue_size:=1000"]
    args += tf_args(mount)
    latencies: list[float] = []
    with running(ros2, name, args, odometry, mount) as run, ExitStack() as stack:
        got, proc, replay = run.got, run.proc, run.replay
        wait_matched(ros2, name, proc)
        probe_first(replay, scans, msgs, keys, got, proc)
        _play(replay, scans, msgs, first=1)
        wait_for(lambda: got.count(keys[-1:]) == 1, 60.0, "a pose for the last scan", proc)
        client = stack.enter_context(parameter_client(ros2.node, ros2.node_path(name)))
        trigger = ros2.node.create_client(Trigger, ros2.topic(name, "serialize_map"))
        stack.callback(ros2.node.destroy_client, trigger)
        wait_for(trigger.service_is_ready, STARTUP_TIMEOUT, "serialize_map", proc)
        began = time.perf_counter()
        serialized = trigger.call_async(Trigger.Request())
        while not serialized.done() and time.perf_counter() - began < 60.0:
            asked = time.perf_counter()
            future = client.get_parameters(["output"])
            while not future.done() and time.perf_counter() - asked < 10.0:
                time.sleep(0.002)
            latencies.append((time.perf_counter() - asked) * 1e3)  # asked while it ran
            time.sleep(0.05)
        took = time.perf_counter() - began
        assert serialized.done() and serialized.result().success, "serialize_map"
        returncode = interrupt(proc)
    log = ros2.log(name)
    check_clean_exit(returncode, log)
    assert took > 0.3, f"serialize_map took {took:.2f} s, too short to show anything: {latencies}"
    assert max(latencies) <= 200.0, f"parameter calls during serialize_map: {latencies} ms"
    assert len(latencies) >= 3, f"{len(latencies)} calls during serialize_map ({took:.2f} s)"
    print(
        f"\n{len(latencies)} GetParameters calls during serialize_map ({took:.2f} s): max "
        f"{max(latencies):.1f} ms"
    )
