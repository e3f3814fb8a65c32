"""The later visit through the ROS 2 node's core (``benchmarks/localise_ros2.py``): options
become the node's parameters, and a bag replayed through the core publishes what the CLI's
localiser (``run_localise``) estimates for the same scans."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("gtsam")

from benchmark_modules import load
from laser_corners.io import open_scans
from laser_corners.localise import LocaliseOptions, SmoothOptions
from laser_corners.localise.run import run_localise
from laser_corners.pose import between_many, compose_many, invert_many
from laser_corners.ros.mapping_config import MappingConfig
from laser_corners.slam import run_slam
from laser_corners.slam.output import SlamRunInfo, write_slam_map
from sim_drives import legs, marked_building, write_drive_bag

_replay = load("localise_ros2")
node_parameters, parse_parameters = _replay.node_parameters, _replay.parse_parameters

MOUNT = (0.2, 0.0, 0.0)
OFFSET = (0.3, -0.2, 0.05)  # added to the odometry: map -> odom is not the identity
OPTIONS = LocaliseOptions(
    fix_scans=5,
    point_spacing=0.15,
    icp=LocaliseOptions().icp.model_copy(update={"iterations": 9}),
    smooth=SmoothOptions(enabled=False),
)


def test_node_parameters_carry_every_non_default_option(tmp_path: Path) -> None:
    params = node_parameters(tmp_path, OPTIONS, "/odom")
    assert params == {
        "mode": "localise",
        "map": str(tmp_path),
        "odom_topic": "/odom",
        "fix_scans": 5,
        "point_spacing": 0.15,
        "icp.iterations": 9,
        "smooth.enabled": False,
    }
    assert MappingConfig.from_mapping(params).localise_options() == OPTIONS
    assert node_parameters(tmp_path, LocaliseOptions(), "tf") == {
        "mode": "localise",
        "map": str(tmp_path),
    }
    with_mount = node_parameters(tmp_path, LocaliseOptions(mount=(0.1, 0.0, 0.2)), None)
    assert with_mount["mount"] == [0.1, 0.0, 0.2]
    assert parse_parameters(["tf_wait=5", "odom_topic=tf"]) == {"tf_wait": 5, "odom_topic": "tf"}
    with pytest.raises(SystemExit, match="expected NAME=VALUE"):
        parse_parameters(["tf_wait"])


def test_replay_publishes_what_the_cli_localiser_estimates(tmp_path: Path) -> None:
    """Map the drive out, localise the whole drive, out and back (no initial pose), through
    the node's core and through ``run_localise``: the same scans, the same poses and
    map -> odom (1e-9), none wrong. Facing back, the 180° scanner sees mostly what the map
    never saw: until the global search judged such a pose on the part the map could have seen
    (``hypotheses.seen_share``), a pose turned 180° 3-9 m off was fixed and tracked there."""
    base = legs([(1.5, 4.0), (10.5, 4.0), (1.5, 4.2)])
    bag = write_drive_bag(tmp_path / "drive.bag", marked_building(), base, MOUNT, {"/odom": OFFSET})
    half, start = len(base) // 2, 0
    folder = tmp_path / "map"
    write_slam_map(run_slam(bag, stop_scan=half), folder, SlamRunInfo(str(bag), 1.0, 0.0))
    cli = run_localise(folder, bag, OPTIONS, start_scan=start)
    stamps = np.array([scan.stamp for scan in open_scans(bag)])
    run = _replay.replay(bag, folder, OPTIONS, float(stamps[start]))
    out = _replay.published(run, stamps)
    assert run.parameters["odom_topic"] == "/odom" and run.core.estimator.options == OPTIONS
    assert run.scans_given == len(base) - start == len(out["given"])  # none dropped
    assert run.core.counts.no_odometry == 0 and not run.core.pending
    assert len(cli.estimates) > 0.4 * (len(base) - start)  # found itself, then tracked
    # the map's frame is the SLAM's: its first pose is the first odometry pose
    first_odometry = np.asarray(base[0]) + np.asarray(OFFSET)
    truth = compose_many(compose_many(first_odometry, invert_many(base[0])), base)
    off = between_many(truth[[start + p for p in cli.positions]], np.asarray(cli.poses))
    assert np.hypot(off[:, 0], off[:, 1]).max() < 0.5, "an estimate more than 0.5 m off"
    assert np.abs(np.arctan2(np.sin(off[:, 2]), np.cos(off[:, 2]))).max() < np.radians(5.0)
    np.testing.assert_array_equal(out["est_i"], [start + p for p in cli.positions])
    np.testing.assert_allclose(out["est_p"], cli.poses, rtol=0, atol=1e-9)
    last = run.core.processed_scans[-1].update
    np.testing.assert_allclose(last.map_to_odom, cli.estimates[-1].map_to_odom, atol=1e-9)
    assert np.abs(last.map_to_odom).max() > 0.05  # the odometry's offset, taken out
