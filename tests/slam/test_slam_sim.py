"""SLAM on simulated recordings with known poses: the trajectory beats the noisy odometry."""

from __future__ import annotations

import math

import numpy as np
import pytest

pytest.importorskip("gtsam")

from laser_corners.errors import InputError, InvalidParamsError
from laser_corners.eval.relations import closure_consistency, relation_metrics
from laser_corners.pose import between_many, compose_many
from laser_corners.scan import LaserScan
from laser_corners.sim import SICK_LMS_1DEG
from laser_corners.slam import LoopOptions, Slam, SlamOptions, run_slam
from sim_drives import drive_slam, noisy_odometry, straight, two_rooms

RATE = 10.0


def _loop_path(laps: int = 2) -> np.ndarray:
    """Poses at RATE Hz driving a rectangle through both rooms ``laps`` times at 0.5 m/s."""
    corners = np.array([[1.5, 1.5], [10.5, 1.5], [10.5, 6.5], [1.5, 6.5]])
    poses = []
    for _ in range(laps):
        for a, b in zip(corners, np.roll(corners, -1, axis=0), strict=True):
            heading = math.atan2(b[1] - a[1], b[0] - a[0])
            poses += straight(a, b)
            # turn in place to the next leg
            poses.extend((b[0], b[1], heading + k * 0.15) for k in range(1, 11))
    return np.array(poses)


def _run(truth: np.ndarray, odo: np.ndarray, options: SlamOptions, mount=(0.0, 0.0, 0.0)):
    slam = Slam(options, mount)
    laser = compose_many(truth, np.asarray(mount, dtype=float))
    stamps = np.arange(len(truth)) / RATE
    drive_slam(slam, two_rooms(), laser, odo, stamps, np.random.default_rng(3))
    return slam.result()


def _relations(truth: np.ndarray, step: int = 15) -> np.ndarray:
    t = np.arange(len(truth)) / RATE
    idx = np.arange(0, len(truth) - step, 5)
    rel = between_many(truth[idx], truth[idx + step])
    far = np.arange(0, len(truth) // 2, 40)  # loop-spanning pairs: a lap apart
    rel_far = between_many(truth[far], truth[far + len(truth) // 2])
    return np.vstack(
        [
            np.column_stack([t[idx], t[idx + step], rel]),
            np.column_stack([t[far], t[far + len(truth) // 2], rel_far]),
        ]
    )


@pytest.fixture(scope="module")
def drive() -> tuple[np.ndarray, np.ndarray]:
    truth = _loop_path()
    return truth, noisy_odometry(truth, np.random.default_rng(7))


def test_slam_beats_noisy_odometry(drive) -> None:
    truth, odo = drive
    result = _run(truth, odo, SlamOptions())
    rel = _relations(truth)
    t = np.arange(len(truth)) / RATE
    ours = relation_metrics(result.stamps, result.poses, rel)
    odom = relation_metrics(t, odo, rel)
    assert ours.n_covered == odom.n_covered == len(rel)
    assert odom.trans_mean > 0.2  # the odometry really drifts
    assert ours.trans_mean < 0.03 and ours.trans_mean < odom.trans_mean / 8
    assert ours.rot_deg_mean < 0.4
    # one pose per scan, keyframes indexing them, closures found and consistent
    assert result.poses.shape == (len(truth), 3) and result.counts["scans"] == len(truth)
    assert 0 < result.counts["keyframes"] < len(truth)
    assert result.counts["closures_accepted"] >= 1
    assert closure_consistency(result) <= 0.01
    assert result.ms_per_scan.shape == (len(truth),)


def test_mount_is_applied(drive) -> None:
    # the laser 0.3 m ahead of the base: the base trajectory is still the truth
    truth, odo = drive
    n = len(truth) // 2
    options = SlamOptions(loop=LoopOptions(enabled=False))
    result = _run(truth[:n], odo[:n], options, mount=(0.3, 0.0, 0.0))
    rel = _relations(truth[:n])[:-10]
    assert relation_metrics(result.stamps, result.poses, rel).trans_mean < 0.05
    assert np.allclose(result.mount, [0.3, 0.0, 0.0])


def test_beam_count_change_and_time_jump_do_not_crash() -> None:
    world = two_rooms()
    slam = Slam(SlamOptions())
    rng = np.random.default_rng(0)
    poses = [(1.5 + 0.05 * i, 1.5, 0.0) for i in range(40)]
    for i, pose in enumerate(poses):
        scan = world.scan(pose, SICK_LMS_1DEG, noise_sigma=0.01, rng=rng, stamp=i / RATE)
        if i % 2:  # every other scan: half the beams
            scan = LaserScan(
                scan.ranges[::2],
                scan.angle_min,
                2 * scan.angle_increment,
                scan.range_min,
                scan.range_max,
                scan.stamp,
            )
        stamp = i / RATE + (100.0 if i >= 20 else 0.0)  # a 100 s gap
        stamp -= 0.15 if i == 10 else 0.0  # a stamp 0.05 s behind the previous: jitter
        pose_out, cov = slam.add(scan, pose, stamp)
        assert np.all(np.isfinite(pose_out)) and cov.shape == (3, 3)
        assert np.all(np.linalg.eigvalsh(cov) > 0)
        if i == 25:  # the scans after the gap aligned to the map: the graph is not cut
            assert cov[0, 0] < 0.01
    result = slam.result()
    assert result.counts["time_jumps"] == 1
    assert result.poses.shape == (40, 3)
    assert np.hypot(*(result.poses[-1, :2] - poses[-1][:2])) < 0.1


def test_options_overrides_and_validation() -> None:
    opts = SlamOptions().with_overrides(["keyframe_distance=0.5", "mount=-0.04,0,0"])
    assert opts.keyframe_distance == 0.5 and opts.mount == (-0.04, 0.0, 0.0)
    with pytest.raises(InvalidParamsError, match="keyframe_distance"):
        SlamOptions(keyframe_distance=-1.0)
    with pytest.raises(InvalidParamsError, match="unknown option"):
        SlamOptions().with_overrides(["no_such=1"])
    with pytest.raises(InvalidParamsError):
        opts.keyframe_distance = 2.0  # frozen


def test_write_g2o(drive, tmp_path) -> None:
    truth, odo = drive
    result = _run(truth[:200], odo[:200], SlamOptions())
    path = tmp_path / "graph.g2o"
    result.write_g2o(path)
    text = path.read_text()
    assert text.count("VERTEX_SE2") == result.counts["keyframes"]
    assert "EDGE_SE2" in text


def test_write_g2o_with_robust_loop_closures(drive, tmp_path) -> None:
    # gtsam's writeG2o refuses robust noise models; loop closures are Huber factors
    import dataclasses

    import gtsam

    truth, odo = drive
    result = _run(truth[:200], odo[:200], SlamOptions())
    graph = gtsam.NonlinearFactorGraph(result.graph)
    huber = gtsam.noiseModel.mEstimator.Huber.Create(1.345)
    base = gtsam.noiseModel.Diagonal.Sigmas(np.array([0.05, 0.05, 0.02]))
    robust = gtsam.noiseModel.Robust.Create(huber, base)
    keys = sorted(result.values.keys())
    graph.add(gtsam.BetweenFactorPose2(keys[-1], keys[0], gtsam.Pose2(0.1, 0.0, 0.0), robust))
    path = tmp_path / "graph.g2o"
    dataclasses.replace(result, graph=graph).write_g2o(path)
    edges = [line.split() for line in path.read_text().splitlines() if line.startswith("EDGE_SE2")]
    ends = [gtsam.Symbol(keys[-1]).index(), gtsam.Symbol(keys[0]).index()]
    assert [int(edges[-1][1]), int(edges[-1][2])] == ends
    assert float(edges[-1][6]) == pytest.approx(1 / 0.05**2)  # information of the Gaussian base


def test_recording_without_odometry_is_one_line(tmp_path) -> None:
    path = tmp_path / "scans.clf"
    line = "RAWLASER1 0 -1.5708 3.1416 0.7854 50 0.01 0 5 1 1 1 1 1 0 {t} host {t}\n"
    path.write_text("".join(line.format(t=float(i)) for i in range(3)))
    with pytest.raises(InputError, match="odometry") as info:
        run_slam(path)
    assert "\n" not in str(info.value) and str(path) in str(info.value)
