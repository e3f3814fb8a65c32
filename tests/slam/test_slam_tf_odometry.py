"""Odometry from ``/tf`` alone: a bag with no Odometry topic but an ``odom -> base_link``
``/tf`` (and ``/tf_static`` ``base_link -> laser``) maps as the same bag with the Odometry."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("gtsam")

from laser_corners.errors import InputError
from laser_corners.io import open_scans
from laser_corners.io.rosbag import tf_odometry
from laser_corners.sim import World
from laser_corners.slam import LoopOptions, SlamOptions, run_slam
from sim_drives import TF, write_drive_bag

RATE = 10.0
MOUNT = (0.2, 0.0, 0.0)


def _world() -> World:
    world = World().add_polygon([[0, 0], [10, 0], [10, 6], [0, 6]])
    world.add_polygon([[3, 2], [3.8, 2], [3.8, 2.6], [3, 2.6]])
    world.add_polygon([[7, 3.5], [7.6, 3.5], [7.3, 4.3]])
    return world


def _drive() -> np.ndarray:
    """Base poses: along a room, a turn, back (0.4 m/s)."""
    out = [(1.5 + 0.04 * i, 1.2, 0.0) for i in range(150)]
    out += [(7.5, 1.2, 0.1 * k) for k in range(1, 16)]
    out += [(7.5 - 0.04 * i * math.cos(0.0), 1.2 + 0.03 * i, 1.5) for i in range(60)]
    return np.array(out)


def _write(path: Path, odometry: str, ros2: bool = False, tf_map: bool = False) -> Path:
    """A bag of the drive: ``odometry`` is ``topic`` (nav_msgs/Odometry on /odom), ``tf``
    (odom -> base_link on /tf) or ``none``; ``tf_map`` adds a moving map -> odom above it.
    The odometry is noise-free (the same in every bag)."""
    sources = {"topic": {"/odom": (0.0, 0.0, 0.0)}, "tf": {TF: (0.0, 0.0, 0.0)}, "none": {}}
    return write_drive_bag(
        path, _world(), _drive(), MOUNT, sources[odometry], ros2=ros2, tf_map=tf_map, rate=RATE
    )


@pytest.mark.parametrize("ros2", [False, True], ids=["ros1", "ros2-mcap"])
def test_slam_from_tf_odometry_equals_the_odometry_topic_run(tmp_path: Path, ros2) -> None:
    ext = "" if ros2 else ".bag"
    with_topic = _write(tmp_path / f"topic{ext}", "topic", ros2)
    with_tf = _write(tmp_path / f"tf{ext}", "tf", ros2, tf_map=True)
    source = open_scans(with_tf)
    scans = list(source)
    assert source.odom_topic == "/tf" and source.tf_odometry == ("odom", "base_link")
    assert all(s.pose is not None for s in scans)
    options = SlamOptions(loop=LoopOptions(enabled=False))
    a = run_slam(with_topic, options)
    b = run_slam(with_tf, options)
    assert a.counts["scans"] == b.counts["scans"] == len(_drive())
    np.testing.assert_allclose(b.odometry, a.odometry, atol=1e-9)
    np.testing.assert_allclose(b.poses, a.poses, atol=1e-9)
    np.testing.assert_allclose(b.mount, MOUNT)
    # and the trajectory is the true one (noise-free odometry, a good map)
    assert np.abs(b.poses[:, :2] - _drive()[:, :2]).max() < 0.05


def test_bag_with_neither_odometry_nor_tf_is_one_line(tmp_path: Path) -> None:
    path = _write(tmp_path / "none.bag", "none")
    with pytest.raises(InputError, match="no odometry") as info:
        run_slam(path)
    assert "\n" not in str(info.value) and str(path) in str(info.value)


def test_tf_odometry_picks_the_moving_transform_nearest_above_the_laser() -> None:
    moving = {
        ("map", "odom"): [(0.0, 0.0, 0.0, 0.0), (1.0, 0.1, 0.0, 0.0)],
        ("odom", "base_link"): [(1.0, 1.0, 0.0, 0.0), (0.0, 0.0, 0.0, 0.0)],
        ("base_link", "wheel"): [(0.0, 0.1, 0.0, 0.0), (1.0, 0.1, 0.0, 0.0)],  # constant
    }
    static = {"laser": "base_link", "base_link": "odom", "odom": "map", "wheel": "base_link"}
    found = tf_odometry("/laser", static, moving, Path("x.bag"))
    assert found is not None
    edge, samples = found
    assert edge == ("odom", "base_link") and [s[0] for s in samples] == [0.0, 1.0]
    # the laser not linked: the only moving transform, or one line naming the candidates
    only = {("odom", "base_link"): moving[("odom", "base_link")]}
    found = tf_odometry("other", static, only, Path("x.bag"))
    assert found is not None and found[0] == ("odom", "base_link")
    with pytest.raises(InputError, match=r"map -> odom, odom -> base_link.*'other'") as info:
        tf_odometry("other", static, moving, Path("x.bag"))
    assert "\n" not in str(info.value) and "x.bag" in str(info.value)
    # nothing moves: no odometry
    still = {("base_link", "wheel"): moving[("base_link", "wheel")]}
    assert tf_odometry("laser", static, still, Path("x.bag")) is None
