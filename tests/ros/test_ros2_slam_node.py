"""The ROS 2 node's ``mode:=slam`` (and ``mode:=localise``) over real DDS, fed with fr079.

As ``test_ros2_node.py`` (same isolation: a domain from the pid, loopback discovery, a
namespace per node): the node runs as ``laser-corners ros2 --ros-args -p mode:=slam``; this
process replays the first scans of ``fr079.bag`` with the bag's odometry on ``/tf`` and the
laser mount on ``/tf_static`` (``tf2_msgs``, which ``make test`` builds from
``ros2/interfaces/tf2_msgs`` with ``ros2/build_tf2_msgs.sh``), and looks up ``map ->
base_link`` from the ``/tf`` messages it receives (a small buffer: the latest ``map -> odom``
composed with ``odom -> base_link`` interpolated at the stamp; ``tf2_ros`` is not on PyPI).
Without ``tf2_msgs`` (skipped, failed in CI) odometry goes over ``nav_msgs/Odometry`` and
``map -> odom`` comes back on ``map_to_odom``; that fallback also runs with ``tf2_msgs``
hidden from the node. The replay and the recorder of what comes back are ``ros2_replay``'s,
the node's process and services ``ros2_tools``'s (shared with the other ROS 2 tests).
"""

from __future__ import annotations

import os
import re
import signal
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from ros2_replay import (
    HAS_TF,
    RATE_HZ,
    Key,
    Received,
    Replay,
    Run,
    fr079_with_odometry,
    key_of,
    latched_map,
    offline_map,
    planar,
    play_rest,
    probe_first,
    running,
    tf_args,
    to_msg,
)
from ros2_tools import (
    REAL_DDS_MARKS,
    STARTUP_TIMEOUT,
    Ros2,
    call_trigger,
    check_clean_exit,
    interrupt,
    isolated_ros2,
    one_error_line,
    summary_counts,
    torn_down,
    wait_discovered,
    wait_exit,
    wait_matched,
)
from ros_helpers import isolated_message_packages, skip_or_fail, wait_for

from laser_corners.pose import compose_many, invert_many

pytest.importorskip("gtsam")

pytestmark = REAL_DDS_MARKS

N_SCANS = 300  # the first 64 s of fr079


@pytest.fixture(scope="module")
def ros2(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Ros2]:
    yield from isolated_ros2(tmp_path_factory)


def _reference_poses(scans: list[Any], mount) -> np.ndarray:
    """Offline SLAM on the same inputs (scans rounded to float32 as the messages carry them)."""
    import dataclasses

    from laser_corners.slam import Slam

    slam = Slam(mount=mount)
    undo = invert_many(np.asarray(mount))
    out = []
    for scan in scans:
        scan32 = dataclasses.replace(scan, ranges=scan.ranges.astype(np.float32).astype(float))
        pose, _ = slam.add(scan32, compose_many(np.asarray(scan.pose), undo), scan.stamp)
        out.append(pose)
    return np.array(out)


def _check_metadata(got: Received, grid: Any) -> None:
    """``map_metadata`` (latched) describes the latched grid, as map_server's does."""
    with got.lock:
        meta = got.metadata[-1]
    assert (meta.width, meta.height) == (grid.info.width, grid.info.height)
    assert meta.resolution == pytest.approx(grid.info.resolution)
    assert meta.origin.position.x == pytest.approx(grid.info.origin.position.x)
    assert meta.origin.position.y == pytest.approx(grid.info.origin.position.y)


def _play_all(ros2: Ros2, name: str, run: Run, scans, msgs, keys) -> None:
    """Wait for discovery, probe with the first scan, play the rest; wait for every pose."""
    wait_matched(ros2, name, run.proc)
    probe_first(run.replay, scans, msgs, keys, run.got, run.proc)
    play_rest(run.replay, scans, msgs, keys)
    wait_for(lambda: run.got.count(keys) == len(keys), 60.0, "a pose for every scan", run.proc)


def _check_pose_messages(got: Received, keys, scans, odometry) -> np.ndarray:
    """map -> base_link looked up from /tf = the published pose; frames; covariance. The
    poses."""
    poses = []
    for key, scan in zip(keys, scans, strict=True):
        pose = planar(got.poses[key].pose.pose)
        assert got.answered(key), f"scan {key}: no map -> odom stamped {got.tolerance} s later"
        # 5 mm: under load the node's odometry queue (keep last N) may drop a sample, so its
        # interpolation bracket can be wider than ours (0.5 mm seen); a wrong composition is
        # off by centimetres to metres
        np.testing.assert_allclose(got.lookup(scan.stamp, odometry)[:2], pose[:2], atol=5e-3)
        assert got.poses[key].header.frame_id == "map"
        cov = np.asarray(got.poses[key].pose.covariance).reshape(6, 6)
        assert cov[0, 0] > 0 and cov[1, 1] > 0 and cov[5, 5] > 0
        poses.append(pose)
    return np.array(poses).reshape(-1, 3)


def _latency(got: Received, published_at: dict[Key, float]) -> str:
    ms = np.array([got.received_at[k] - t for k, t in published_at.items() if k in got.poses])
    ms *= 1e3
    return (
        f"publish scan -> pose received over {ms.size} scans at {RATE_HZ:g} Hz: median "
        f"{np.median(ms):.2f} ms, p95 {np.percentile(ms, 95):.2f} ms, max {ms.max():.2f} ms"
    )


def test_slam_mode_end_to_end(ros2: Ros2, tmp_path: Path) -> None:
    """fr079 scans + odometry in: a pose and map -> odom per scan, /map latched, the map
    folder written at SIGINT."""
    scans, odometry, mount = fr079_with_odometry(N_SCANS)
    msgs = [to_msg(s) for s in scans]
    keys = [key_of(m.header.stamp) for m in msgs]
    name, output = "lc_slam", tmp_path / "map"
    args = ["-p", "mode:=slam", "-p", "map_period:=1.0", "-p", f"output:={output}"]
    args += ["-p", f"queue_size:={N_SCANS}", *tf_args(mount)]
    with running(ros2, name, args, odometry, mount) as run:
        got = run.got
        wait_matched(ros2, name, run.proc)
        probe_first(run.replay, scans, msgs, keys, got, run.proc)
        published_at = play_rest(run.replay, scans, msgs, keys)
        wait_for(lambda: got.count(keys) == N_SCANS, 60.0, "a pose for every scan", run.proc)
        time.sleep(1.5)  # one map_period after the last keyframe: the final grid
        run.subs += latched_map(ros2, name, got, run.proc)  # a late subscriber gets it
        returncode = interrupt(run.proc)

    log = ros2.log(name)
    check_clean_exit(returncode, log)
    summary = re.search(r"stopped by SIGINT: (\d+) scans, (\d+) processed, (\d+) without", log)
    assert summary, log
    assert int(summary.group(2)) >= N_SCANS and int(summary.group(3)) == 0, log
    assert f"map written to {output}" in log, log
    node_poses = _check_pose_messages(got, keys, scans, odometry)
    # the node's SLAM is the library's: same poses as an offline run on the same inputs
    reference = _reference_poses(scans, mount)
    err = np.hypot(*(node_poses[:, :2] - reference[:, :2]).T)
    assert np.percentile(err, 95) < 0.05, f"node vs offline SLAM: p95 {np.percentile(err, 95)}"
    # the latched map: frame, size of the first 64 s of fr079, walls and free space
    grid = got.grids[-1]
    assert grid.header.frame_id == "map"
    assert grid.info.resolution == pytest.approx(0.05)
    width, height = grid.info.width * 0.05, grid.info.height * 0.05
    assert 5.0 < width < 100.0 and 5.0 < height < 100.0, (width, height)
    data = np.asarray(grid.data, dtype=np.int8)
    assert data.size == grid.info.width * grid.info.height
    assert set(np.unique(data).tolist()) <= {-1, 0, 100}  # trinary, as map_server publishes
    assert (data == 100).sum() > 500 and (data == 0).sum() > 5000
    _check_metadata(got, grid)
    for file in ("map.yaml", "map.pgm", "trajectory.tum", "summary.json", "keyframes.npz"):
        assert (output / file).is_file(), file  # the folder of `laser-corners slam`
    print(
        f"\nROS 2 slam node, fr079: {_latency(got, published_at)}; node vs offline SLAM "
        f"median {np.median(err) * 1e3:.2f} mm; grid {grid.info.width} x {grid.info.height}; "
        f"node log: {re.search(r'stopped by SIGINT: .*', log).group(0)}"
    )


def test_localise_mode_end_to_end(ros2: Ros2, tmp_path: Path) -> None:
    """The same fr079 scans localised in their map: /initialpose starts tracking, the poses
    stay on the map's trajectory, the saved map is latched on /map."""
    from geometry_msgs.msg import PoseWithCovarianceStamped

    from laser_corners.ros.nav_convert import fill_pose_with_covariance

    scans, odometry, mount = fr079_with_odometry(N_SCANS)
    truth = offline_map(scans, tmp_path / "map")
    msgs = [to_msg(s) for s in scans]
    keys = [key_of(m.header.stamp) for m in msgs]
    name = "lc_localise"
    args = ["-p", "mode:=localise", "-p", f"map:={tmp_path / 'map'}"]
    args += ["-p", f"queue_size:={N_SCANS}", "-p", "transform_tolerance:=0.25"]
    args += tf_args(mount)
    initial = fill_pose_with_covariance(
        PoseWithCovarianceStamped(), truth[0], np.diag([0.01, 0.01, 0.003])
    )
    initial.header.frame_id = "map"
    with running(ros2, name, args, odometry, mount, tolerance=0.25) as run:
        got, proc, replay = run.got, run.proc, run.replay
        initial_pub = ros2.node.create_publisher(PoseWithCovarianceStamped, "/initialpose", 10)
        run.destroy.append(lambda: ros2.node.destroy_publisher(initial_pub))
        run.subs += latched_map(ros2, name, got, proc)  # at start: the saved map.pgm
        wait_matched(ros2, name, proc)
        # no fix without it on the first scan: an answer proves /initialpose arrived
        probe_first(replay, scans, msgs, keys, got, proc, lambda: initial_pub.publish(initial))
        published_at = play_rest(replay, scans, msgs, keys)
        wait_for(lambda: got.count(keys[-1:]) == 1, 60.0, "a pose for the last scan", proc)
        restarted = call_trigger(ros2, name, "reinitialize_global_localization", proc)
        assert restarted.success, restarted.message
        refused = call_trigger(ros2, name, "serialize_map", proc)  # the map is the input here
        assert not refused.success and "mode slam" in refused.message, refused.message
        returncode = interrupt(proc, signal.SIGTERM)

    log = ros2.log(name)
    check_clean_exit(returncode, log)
    assert re.search(r"initial pose \[.*\] applied", log), log
    assert "reinitialize_global_localization: global search from the next scan" in log, log
    # every step of the core runs on the worker: no callback waits for it
    longest = re.search(r"longest callback ([\d.]+) ms", log)
    assert longest and float(longest.group(1)) < 50.0, log
    answered = [i for i, k in enumerate(keys) if k in got.poses and got.answered(k)]
    assert len(answered) >= 0.95 * N_SCANS, f"{len(answered)} of {N_SCANS} scans got a pose"
    poses = _check_pose_messages(
        got, [keys[i] for i in answered], [scans[i] for i in answered], odometry
    )
    err = np.hypot(*(poses[:, :2] - truth[answered, :2]).T)
    dyaw = np.degrees(np.abs(np.angle(np.exp(1j * (poses[:, 2] - truth[answered, 2])))))
    assert err.max() < 0.3 and dyaw.max() < 3.0, (err.max(), dyaw.max())
    grid = got.grids[0]
    saved = (tmp_path / "map" / "map.pgm").read_bytes()
    assert grid.info.width * grid.info.height == len(grid.data) and len(grid.data) < len(saved)
    data = np.asarray(grid.data, dtype=np.int8)
    assert set(np.unique(data).tolist()) == {-1, 0, 100}  # the same convention as slam's
    _check_metadata(got, grid)
    print(
        f"\nROS 2 localise node, fr079 in its own map: {_latency(got, published_at)}; "
        f"{len(answered)} of {N_SCANS} scans localised, max error {err.max() * 100:.1f} cm / "
        f"{dyaw.max():.2f} deg; node log: {re.search(r'stopped by SIGTERM: .*', log).group(0)}"
    )


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["-p", "mode:=mapping"], "ROS 2 parameter mode: unknown mode 'mapping'"),
        (["-p", "mode:=slam", "-p", "mape:=x"], "ROS 2 parameters: unknown parameter 'mape'"),
        (["-p", "mode:=localise"], "map: mode localise needs -p map:=DIR"),
        (["-p", "mode:=localise", "-p", "map:=/nonexistent/map"], "/nonexistent/map: no such"),
        (["-p", "mode:=slam", "-p", "map_period:=-1.0"], "ROS 2 parameters: map_period"),
    ],
)
def test_mapping_modes_refuse_bad_parameters(ros2: Ros2, args: list[str], message: str) -> None:
    name = f"lc_bad_{abs(hash(tuple(args))) % 10**6}"
    proc = ros2.start(name, *args)
    returncode = wait_exit(proc, f"bad parameters ({args})")
    log = ros2.log(name)
    assert returncode == 2, log
    assert "Traceback" not in log, log
    assert message in one_error_line(log), log


def test_tf2_msgs_is_importable() -> None:
    """``make test`` builds tf2_msgs into the venv (ros2/build_tf2_msgs.sh): /tf works."""
    if not HAS_TF:
        skip_or_fail("tf2_msgs is not importable: run ros2/build_tf2_msgs.sh .venv/bin/python")
    with isolated_message_packages():  # ROS 2's geometry_msgs, gone again afterwards
        from geometry_msgs.msg import TransformStamped
        from tf2_msgs.msg import TF2Error, TFMessage

        msg = TFMessage(transforms=[TransformStamped(child_frame_id="odom")])
        assert msg.transforms[0].child_frame_id == "odom" and TF2Error.LOOKUP_ERROR == 1


@pytest.fixture
def hidden_tf2_msgs(tmp_path: Path) -> dict[str, str]:
    """Environment of a node that cannot import tf2_msgs (a package on PYTHONPATH that raises
    ImportError shadows the built one), as with the PyPI wheels alone."""
    shadow = tmp_path / "shadow" / "tf2_msgs"
    shadow.mkdir(parents=True)
    (shadow / "__init__.py").write_text('raise ImportError("tf2_msgs hidden by the test")\n')
    path = os.pathsep.join(p for p in (str(shadow.parent), os.environ.get("PYTHONPATH")) if p)
    return {"PYTHONPATH": path}


def test_without_tf2_msgs_slam_mode_needs_an_odometry_topic(
    ros2: Ros2, hidden_tf2_msgs: dict[str, str]
) -> None:
    """Without tf2_msgs and without odom_topic: one line saying what to do, exit code 2."""
    name = "lc_no_tf"
    proc = ros2.start(name, "-p", "mode:=slam", env=hidden_tf2_msgs)
    returncode = wait_exit(proc, "mode slam without tf2_msgs")
    log = ros2.log(name)
    assert returncode == 2, log
    error = one_error_line(log)
    assert "-p odom_topic:=/odom" in error and "build_tf2_msgs.sh" in error, log


def test_without_tf2_msgs_map_to_odom_goes_to_a_topic(
    ros2: Ros2, hidden_tf2_msgs: dict[str, str]
) -> None:
    """The fallback: odometry from nav_msgs/Odometry, map -> odom (future-dated) on
    ``map_to_odom``, and one warning saying so."""
    n = 40
    scans, odometry, mount = fr079_with_odometry(n)
    msgs = [to_msg(s) for s in scans]
    keys = [key_of(m.header.stamp) for m in msgs]
    name = "lc_fallback"
    args = ["-p", "mode:=slam", "-p", f"queue_size:={n}", *tf_args(mount, tf=False)]
    with running(ros2, name, args, odometry, mount, env=hidden_tf2_msgs, tf=False) as run:
        got = run.got
        _play_all(ros2, name, run, scans, msgs, keys)
        returncode = interrupt(run.proc)
    log = ros2.log(name)
    check_clean_exit(returncode, log)
    assert log.count("tf2_msgs is not importable") == 1, log
    assert "map -> odom goes to" in log and "map_to_odom" in log, log
    _check_pose_messages(got, keys, scans, odometry)


def _warnings(log: str) -> list[str]:
    return [line for line in log.splitlines() if line.startswith("[WARN]")]


@pytest.mark.parametrize("case", ["wrong base_frame", "no odometry"])
def test_missing_odometry_is_never_silent(ros2: Ros2, case: str) -> None:
    """Scans with odometry in other frames, or none at all: throttled warnings on stderr
    naming the frames and topics seen, and every scan counted in the summary."""
    n = 60  # 3 s at 20 Hz: past odom_timeout (2 s)
    scans, odometry, mount = fr079_with_odometry(n)
    msgs = [to_msg(s) for s in scans]
    name = "lc_wrong_frame" if case == "wrong base_frame" else "lc_no_odom"
    args = ["-p", "mode:=slam", "-p", f"queue_size:={n}", "-p", "tf_wait:=0.5"]
    if case == "wrong base_frame":
        args += ["-p", "base_frame:=base_footprint"]
    proc = ros2.start(name, *args)
    destroy: list[Callable[[], object]] = []
    with torn_down(ros2.node, proc, name, [], destroy):
        replay = Replay(ros2, name, odometry, mount)
        destroy.append(replay.destroy)
        topics = (ros2.topic(name, "scan"), "/tf")
        wait_discovered(ros2.node, proc, "the node's scan and /tf subscriptions", topics)
        time.sleep(0.5)  # our side matched; give the node's side a moment (best effort)
        start = time.perf_counter()
        for i, msg in enumerate(msgs):
            time.sleep(max(0.0, start + i / 20.0 - time.perf_counter()))
            if case == "wrong base_frame":
                replay.odometry_until(scans[i].stamp + 0.5)
            replay.scan_pub.publish(msg)
        wait_for(lambda: "no odometry for" in ros2.log(name), 10.0, "the warning", proc)
        time.sleep(1.0)  # the last scans' tf_wait: dropped, not waiting
        returncode = interrupt(proc)
    log = ros2.log(name)
    check_clean_exit(returncode, log)
    warnings = _warnings(log)
    topic = ros2.topic(name, "scan")
    lost = [w for w in warnings if "no odometry for" in w]
    assert len(lost) == 1, log  # throttled: one in 3 s (every 5 s)
    assert f"while scans arrive on {topic}" in lost[0], lost
    dropped = [w for w in warnings if "dropped so far without odometry" in w]
    assert dropped and topic in dropped[0], log
    if case == "wrong base_frame":
        frames = [w for w in warnings if "no odometry in frames odom -> base_footprint" in w]
        assert frames and re.search(r"seen there: odom -> base_link \(\d+\)", frames[0]), log
        assert re.search(r"seen there: odom -> base_link \(\d+\)", lost[0]), lost
    else:
        assert "expecting odom -> (any child) on /tf (none yet); seen there: nothing" in lost[0]
    counts = summary_counts(log, "SIGINT")
    assert counts["processed"] == 0 and counts["malformed"] == 0, log
    assert counts["without odometry"] + counts["still waiting"] == counts["scans"], log
    assert 0.9 * n <= counts["scans"] <= n and counts["without odometry"] >= 0.9 * n, log
    assert "0 odometry samples" in log, log


def test_slam_services_write_the_map_while_running(ros2: Ros2, tmp_path: Path) -> None:
    """save_map writes map_server's files, serialize_map the folder `localise` reads, while
    the node runs; reinitialize_global_localization is refused in slam mode."""
    from laser_corners.io.occupancy import read_map
    from laser_corners.registration.mapfolder import load_map

    n = 60
    scans, odometry, mount = fr079_with_odometry(n)
    msgs = [to_msg(s) for s in scans]
    keys = [key_of(m.header.stamp) for m in msgs]
    name, output = "lc_services", tmp_path / "live"
    args = ["-p", "mode:=slam", "-p", f"output:={output}", "-p", "queue_size:=60"]
    first = 40  # then the services; then the rest: mapping goes on after serialize_map
    with running(ros2, name, args, odometry, mount) as run:
        got, proc, replay = run.got, run.proc, run.replay
        wait_matched(ros2, name, proc)
        probe_first(replay, scans, msgs, keys, got, proc)
        play_rest(replay, scans[:first], msgs[:first], keys[:first])
        wait_for(lambda: got.count(keys[:first]) == first, 60.0, "the first poses", proc)
        assert not (output / "map.yaml").exists()
        saved = call_trigger(ros2, name, "save_map", proc)
        assert saved.success and str(output / "map.yaml") in saved.message, saved.message
        grid = read_map(output / "map.yaml")
        assert (grid.occupancy == 100).sum() > 100 and (grid.occupancy == 0).sum() > 1000
        folder = call_trigger(ros2, name, "serialize_map", proc)
        assert folder.success and str(output) in folder.message, folder.message
        saved_map = load_map(output)  # what `laser-corners localise` and mode:=localise read
        assert len(saved_map) >= 5 and saved_map.grid is not None
        refused = call_trigger(ros2, name, "reinitialize_global_localization", proc)
        assert not refused.success and "mode localise" in refused.message, refused.message
        for i in range(first, n):
            replay.odometry_until(scans[i].stamp + 0.5)
            replay.scan_pub.publish(msgs[i])
            time.sleep(1.0 / RATE_HZ)
        replay.odometry_until(np.inf)
        wait_for(lambda: got.count(keys) == n, 60.0, "poses after serialize_map", proc)
        returncode = interrupt(proc)
    log = ros2.log(name)
    check_clean_exit(returncode, log)
    assert f"save_map: wrote {output / 'map.yaml'}" in log, log
    _check_pose_messages(got, keys, scans, odometry)  # the poses after it still fit the tf
    assert len(load_map(output)) > len(saved_map)  # the folder of the whole run at SIGINT


def test_an_unwritable_output_stops_the_node_at_start(ros2: Ros2, tmp_path: Path) -> None:
    """`output` is checked at start (not at shutdown, after the run): one line, exit 2."""
    blocker = tmp_path / "a_file"
    blocker.write_text("not a folder")
    name = "lc_bad_output"
    started = time.monotonic()
    proc = ros2.start(name, "-p", "mode:=slam", "-p", f"output:={blocker / 'map'}")
    returncode = wait_exit(proc, "an unwritable output")
    log = ros2.log(name)
    assert returncode == 2 and "Traceback" not in log, log
    assert f"output {blocker / 'map'}" in one_error_line(log), log
    assert time.monotonic() - started < STARTUP_TIMEOUT


def test_an_odometry_jump_is_never_silent(ros2: Ros2) -> None:
    """slam: the odometry teleports 5 m (a reset, a wrong message): a warning naming it and
    the count in the summary; the scans are still mapped."""
    n = 40
    scans, odometry, mount = fr079_with_odometry(n)
    msgs = [to_msg(s) for s in scans]
    keys = [key_of(m.header.stamp) for m in msgs]
    name = "lc_jump"
    args = ["-p", "mode:=slam", "-p", f"queue_size:={n}"]
    with running(ros2, name, args, odometry, mount) as run:
        run.replay.jump = ((scans[19].stamp + scans[20].stamp) / 2.0, 5.0)
        _play_all(ros2, name, run, scans, msgs, keys)
        returncode = interrupt(run.proc)
    log = ros2.log(name)
    check_clean_exit(returncode, log)
    jumps = [w for w in _warnings(log) if "odometry jumped" in w]
    assert len(jumps) == 1 and "odom -> base_link from /tf; max_odom_jump 1 m" in jumps[0], log
    found = re.search(r"odometry jumped (\d+\.\d+) m", jumps[0])
    assert found and 1.0 < float(found.group(1)) < 6.0, jumps
    summary = re.search(r"stopped by SIGINT: .*", log).group(0)
    found = re.search(r"(\d+) odometry jumps", summary)
    assert found and 1 <= int(found.group(1)) <= 2, summary  # the scan straddling it: 2
    assert summary_counts(log, "SIGINT")["processed"] >= n, log  # + repeated probes
