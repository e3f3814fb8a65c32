"""The ROS 2 node over real DDS (rclpy and FastDDS from PyPI), fed with real fr079 scans.

The node runs as a subprocess (``laser-corners ros2 --ros-args ...``); this process is an rclpy
node too (its executor spins in a background thread) that publishes scans of
``../shared/data/real/fr079.bag`` and listens to the outputs. Everything stays on this machine
and run: ``ROS_DOMAIN_ID`` is derived from the pid (1..101),
``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST``, and every node gets a namespace with the pid.
Discovery is awaited with probe scans (answered ones prove both directions matched), never
with fixed sleeps. ``make test`` installs rclpy (the ``ros2`` extra); without it these tests
skip, and fail in CI.
"""

from __future__ import annotations

import re
import signal
import time
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
import yaml
from ros2_replay import RATE_HZ, Key, Outputs, fr079_scans, key_of, probe, to_msg
from ros2_tools import (
    REAL_DDS_MARKS,
    STARTUP_TIMEOUT,
    Ros2,
    call_service,
    check_clean_exit,
    interrupt,
    isolated_ros2,
    one_error_line,
    wait_discovered,
    wait_exit,
)
from ros_helpers import (
    check_poses,
    publish_paced,
    stop,
    wait_for,
)

from laser_corners import CornerDetector, DetectorParams
from laser_corners.presets import get_preset

pytestmark = REAL_DDS_MARKS

N_SCANS = 400  # scans of fr079 played (the first ones)
NODE_OVERRIDES = {"merge_radius": 0.0, "min_points": 4}  # non-defaults: prove params flow


@pytest.fixture(scope="module")
def ros2(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Ros2]:
    """An rclpy context and node in this process, on a domain of its own."""
    yield from isolated_ros2(tmp_path_factory)


def test_node_answers_every_scan_with_library_keypoints(ros2: Ros2, tmp_path: Path) -> None:
    """400 fr079 scans in, one PoseArray per scan out; markers only while subscribed."""
    from geometry_msgs.msg import PoseArray
    from sensor_msgs.msg import LaserScan as LaserScanMsg
    from visualization_msgs.msg import MarkerArray

    scans = fr079_scans(N_SCANS)
    msgs = [to_msg(s) for s in scans]
    keys = [key_of(m.header.stamp) for m in msgs]
    assert len(set(keys)) == N_SCANS, "fr079 stamps are not unique"
    detector, default = CornerDetector(DetectorParams(**NODE_OVERRIDES)), CornerDetector()
    expected = {k: detector.detect(s) for k, s in zip(keys, scans, strict=True)}
    assert any(
        len(default.detect(s)) != len(expected[k]) for k, s in zip(keys, scans, strict=True)
    ), "the overrides do not change the output: the test could not see them ignored"
    params_file = tmp_path / "corners.yaml"  # the detector overrides come from a file
    params_file.write_text(yaml.safe_dump({"/**": {"ros__parameters": NODE_OVERRIDES}}))

    name = "lc_main"
    proc = ros2.start(
        name,
        "-r",
        "scan:=front/scan",
        "--params-file",
        str(params_file),
        "-p",
        f"queue_size:={N_SCANS}",
    )
    out = Outputs()
    node = ros2.node
    corners_sub = node.create_subscription(
        PoseArray, ros2.topic(name, "corners"), out.on_corners, 2 * N_SCANS
    )
    pub = node.create_publisher(LaserScanMsg, ros2.topic(name, "front/scan"), 2 * N_SCANS)
    marker_sub = None
    published_at: dict[Key, float] = {}
    try:
        probe(pub, scans[0], 3, lambda k: k in out.corners, proc, "a PoseArray (discovery)")
        bad = to_msg(scans[0], (1, 0))  # a malformed scan: logged, skipped, the node carries on
        bad.angle_increment = 0.0
        pub.publish(bad)
        half = N_SCANS // 2
        # 1) nobody subscribes corner_markers: the node must not build them
        publish_paced(pub, msgs[:half], published_at, key_of, RATE_HZ)
        wait_for(lambda: out.count(keys[:half]) == half, 30.0, "PoseArrays of phase 1", proc)
        # 2) with a marker subscriber
        marker_sub = node.create_subscription(
            MarkerArray, ros2.topic(name, "corner_markers"), out.on_markers, 2 * N_SCANS
        )
        n_probes = probe(pub, scans[0], 4, lambda k: k in out.markers, proc, "a MarkerArray")
        publish_paced(pub, msgs[half:], published_at, key_of, RATE_HZ)
        wait_for(
            lambda: out.count(keys) == N_SCANS and out.count(keys[half:], True) == half,
            30.0,
            "PoseArrays and MarkerArrays of phase 2",
            proc,
        )
        returncode = interrupt(proc)
    finally:
        node.destroy_subscription(corners_sub)
        if marker_sub is not None:
            node.destroy_subscription(marker_sub)
        node.destroy_publisher(pub)
        stop(proc, name)

    log = ros2.log(name)
    check_clean_exit(returncode, log)
    assert re.search(r"skipped a malformed scan: .*angle_increment", log), log
    assert (1, 0) not in out.corners, "the malformed scan produced output"
    summary = re.search(
        r"stopped by SIGINT: (\d+) scans processed, (\d+) skipped, "
        r"markers published for (\d+)",
        log,
    )
    assert summary, log
    n_processed, n_skipped, n_markers = map(int, summary.groups())
    assert n_skipped == 1
    assert n_processed >= N_SCANS  # plus the probes that reached the node
    # the node built marker arrays for the phase-2 scans and (some of) the marker probes only,
    # none in phase 1 (that would add 200); all the ones built after discovery reached us
    assert out.n_marker_arrays <= n_markers <= half + n_probes, (n_markers, n_probes)
    assert out.n_marker_arrays >= half
    assert not set(keys[:half]) & set(out.markers), "markers for a scan nobody listened to"

    assert all(len(out.corners[k]) == 1 for k in keys), "a scan was answered more than once"
    order = [k for k in out.order if k in expected]
    assert order == keys, "outputs arrived out of order"
    for key, scan in zip(keys, scans, strict=True):
        (msg,) = out.corners[key]
        assert msg.header.frame_id == scan.frame_id
        check_poses(msg, expected[key], key)
    for key in keys[half:]:
        (markers,) = out.markers[key]
        arrows = [m for m in markers.markers if m.type == 0 and m.action == 0]
        assert len(arrows) == len(expected[key])
        assert all(m.header.frame_id == scans[0].frame_id for m in markers.markers)

    lat_ms = np.array([out.received_at[k] - published_at[k] for k in keys]) * 1e3
    print(
        f"\nROS 2 end-to-end latency over {lat_ms.size} fr079 scans at {RATE_HZ:g} Hz "
        f"(publish -> PoseArray received): median {np.median(lat_ms):.2f} ms, "
        f"p95 {np.percentile(lat_ms, 95):.2f} ms, max {lat_ms.max():.2f} ms "
        f"(medians without / with a marker subscriber: {np.median(lat_ms[:half]):.2f} / "
        f"{np.median(lat_ms[half:]):.2f} ms); {sum(len(k) for k in expected.values())} keypoints"
    )


def test_parameters_set_at_run_time(ros2: Ros2) -> None:
    """A parameter client: valid changes apply to the next scans, invalid ones are refused."""
    from geometry_msgs.msg import PoseArray
    from rclpy.parameter import Parameter
    from rclpy.parameter_client import AsyncParameterClient
    from sensor_msgs.msg import LaserScan as LaserScanMsg

    scans = fr079_scans(40)
    changed = {"min_points": 6}
    expected = [get_preset("auto", s).with_overrides(changed) for s in scans]
    before = [get_preset("auto", s) for s in scans]
    assert any(
        len(CornerDetector(p).detect(s)) != len(CornerDetector(b).detect(s))
        for p, b, s in zip(expected, before, scans, strict=True)
    ), "min_points=6 changes nothing on these scans: the test could not see it ignored"

    name = "lc_params"
    proc = ros2.start(name, "-p", "preset:=auto")
    out = Outputs()
    node = ros2.node
    sub = node.create_subscription(PoseArray, ros2.topic(name, "corners"), out.on_corners, 100)
    pub = node.create_publisher(LaserScanMsg, ros2.topic(name, "scan"), 100)
    client = AsyncParameterClient(node, ros2.node_path(name))
    try:
        assert client.wait_for_services(timeout_sec=STARTUP_TIMEOUT), "no parameter services"
        refused = {"min_points": 1, "preset": "no_such_preset", "max_angle_deg": "wide"}
        for pname, value in refused.items():
            param = Parameter(pname, value=value)
            result = call_service(lambda p=param: client.set_parameters([p]), pname)
            (res,) = result.results
            assert not res.successful, f"{pname}={value!r} was accepted"
            assert pname in res.reason, res.reason
        result = call_service(
            lambda: client.set_parameters([Parameter("min_points", value=6)]), "set"
        )
        assert result.results[0].successful, result.results[0].reason
        got = call_service(
            lambda: client.get_parameters(["preset", "min_points"]), "get_parameters"
        )
        assert got.values[0].string_value == "auto"
        assert got.values[1].integer_value == 6

        probe(pub, scans[0], 5, lambda k: k in out.corners, proc, "a PoseArray (discovery)")
        msgs = [to_msg(s) for s in scans]
        keys = [key_of(m.header.stamp) for m in msgs]
        for msg in msgs:
            pub.publish(msg)
            time.sleep(1.0 / RATE_HZ)
        wait_for(lambda: out.count(keys) == len(keys), 30.0, "PoseArrays", proc)
    finally:
        node.destroy_subscription(sub)
        node.destroy_publisher(pub)
        stop(proc, name)
    for key, scan, params in zip(keys, scans, expected, strict=True):
        check_poses(out.corners[key][0], CornerDetector(params).detect(scan), key)
    assert "Traceback" not in ros2.log(name)


@pytest.mark.parametrize(
    ("arg", "message"),
    [
        ("min_points:=1", "min_points: must be in [2, 10000]"),
        ("min_pionts:=4", "ROS 2 parameters: unknown parameter 'min_pionts'"),
        ("preset:=nope", "ROS 2 parameter preset: unknown preset 'nope'"),
    ],
)
def test_invalid_parameter_stops_node_with_one_line_error(
    ros2: Ros2, arg: str, message: str
) -> None:
    name = f"lc_bad_{arg.split(':')[0]}"
    proc = ros2.start(name, "-p", arg)
    returncode = wait_exit(proc, f"an invalid parameter ({arg})")
    log = ros2.log(name)
    assert returncode == 2, log
    assert "Traceback" not in log, log
    assert message in one_error_line(log), log


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM], ids=["SIGINT", "SIGTERM"])
def test_signal_stops_node_cleanly(ros2: Ros2, sig: signal.Signals) -> None:
    """Ctrl-C or SIGTERM (ros2 launch, systemd, docker stop): exit 0, summary, no traceback."""
    name = f"lc_{sig.name.lower()}"
    proc = ros2.start(name)
    wait_discovered(ros2.node, proc, "the node's scan subscription", (ros2.topic(name, "scan"),))
    returncode = interrupt(proc, sig)
    log = ros2.log(name)
    assert returncode == 0, log
    assert "Traceback" not in log and "Exception" not in log, log
    assert f"stopped by {sig.name}: 0 scans processed, 0 skipped" in log, log


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["-r", "scan:=/x"], "unexpected argument(s) -r: ROS arguments go after --ros-args"),
        (["--ros-args", "-p", "min_points"], "ROS 2 arguments: Failed to parse ROS arguments"),
        (["--ros-args", "--params-file", "/nonexistent/c.yaml"], "Couldn't parse params file"),
    ],
)
def test_bad_arguments_give_one_line_error(
    ros2: Ros2, capsys: pytest.CaptureFixture[str], args: list[str], message: str
) -> None:
    from laser_corners.ros.ros2_node import main

    assert main(args) == 2
    ours = [line for line in capsys.readouterr().err.splitlines() if "laser_corners" in line]
    assert len(ours) == 1 and ours[0].startswith("laser_corners: error: "), ours
    assert message in ours[0], ours
