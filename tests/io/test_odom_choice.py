"""Choosing the odometry of a bag (``odom_topic``): the only Odometry topic, a named one,
``"tf"`` for ``/tf``; several and no choice ask (one line per topic), a wrong name is one line.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from laser_corners.errors import InputError
from laser_corners.eval.real import ODOMETRY_POSES, load_scans
from laser_corners.io import TopicChoiceError, open_scans
from laser_corners.pipeline import laser_topic_sources, open_recording
from laser_corners.pose import compose_many
from laser_corners.sim import World
from sim_drives import TF, write_drive_bag

MOUNT = (0.2, 0.0, 0.0)
SOURCES = {"/odom": (1.0, 0.0, 0.0), "/wheel_odom": (0.0, 0.0, 0.0), TF: (0.0, 2.0, 0.1)}
"""Three odometry sources of one drive, each with its own offset (so the poses tell them
apart); ``/odom`` is one of them, to show it is not preferred silently."""


def _drive(n: int = 30) -> np.ndarray:
    return np.array([(1.5 + 0.05 * i, 1.2 + 0.01 * i, 0.02 * i) for i in range(n)])


def _world() -> World:
    world = World().add_polygon([[0, 0], [8, 0], [8, 5], [0, 5]])
    return world.add_polygon([[3, 2], [3.8, 2], [3.8, 2.6], [3, 2.6]])


def write_bag(path: Path, sources: dict, ros2: bool = False) -> Path:
    """The drive with the odometry ``sources`` (name -> offset), ROS 1 or ROS 2/MCAP."""
    return write_drive_bag(path, _world(), _drive(), MOUNT, sources, ros2=ros2)


def _expected(offset) -> np.ndarray:
    """Laser poses of the drive when the odometry is the drive plus ``offset`` (without the
    first and last scan, whose odometry the writer clamps at the ends of the drive)."""
    return compose_many(_drive() + np.asarray(offset), np.asarray(MOUNT))[1:-1]


def _poses(source) -> np.ndarray:
    """The scan poses of ``source`` (all but the first and last scan, as :func:`_expected`)."""
    poses = np.array([s.pose for s in source])
    assert len(poses) == len(_drive())
    return poses[1:-1]


@pytest.fixture(params=[False, True], ids=["ros1", "ros2-mcap"])
def bag(request: pytest.FixtureRequest, tmp_path: Path) -> Path:
    name = "odom2" if request.param else "odom2.bag"
    return write_bag(tmp_path / name, SOURCES, ros2=request.param)


def test_several_odometry_topics_and_no_choice_ask(bag: Path) -> None:
    with pytest.raises(TopicChoiceError) as info:
        open_scans(bag)
    assert info.value.topics == ["/odom", "/wheel_odom"]
    assert info.value.option == "--odom-topic"
    assert str(bag) in str(info.value) and "Odometry topics" in str(info.value)
    with pytest.raises(TopicChoiceError):
        open_recording(bag)


@pytest.mark.parametrize("choice", ["/odom", "/wheel_odom", "tf"])
def test_odom_topic_picks_the_source_the_poses_follow(bag: Path, choice: str) -> None:
    source = open_scans(bag, odom_topic=choice)
    assert source.odom_topic == ("/tf" if choice == "tf" else choice)
    poses = _poses(source)
    np.testing.assert_allclose(
        poses, _expected(SOURCES[TF if choice == "tf" else choice]), atol=1e-6
    )
    if choice == "tf":
        assert source.tf_odometry == ("odom", "base_link")
    with open_recording(bag, odom_topic=choice) as rec:
        assert rec.source.odom_topic == source.odom_topic
        np.testing.assert_allclose(_poses(rec.scans()), poses)


def test_the_only_odometry_topic_is_used(tmp_path: Path) -> None:
    bag = write_bag(tmp_path / "one.bag", {"/wheel_odom": (0.5, 0.0, 0.0), TF: (0.0, 2.0, 0.0)})
    source = open_scans(bag)
    assert source.odom_topic == "/wheel_odom"
    np.testing.assert_allclose(_poses(source), _expected((0.5, 0.0, 0.0)), atol=1e-6)
    # /tf is still there to choose
    np.testing.assert_allclose(
        _poses(open_scans(bag, odom_topic="tf")), _expected((0.0, 2.0, 0.0)), atol=1e-6
    )


@pytest.mark.parametrize(
    ("choice", "needles"),
    [
        ("/nope", ["no odometry topic '/nope'", "Odometry topics: /odom, /wheel_odom"]),
        ("/scan", ["odometry topic /scan is a sensor_msgs/msg/LaserScan", "/wheel_odom"]),
    ],
)
def test_a_wrong_odom_topic_is_one_line(bag: Path, choice: str, needles: list[str]) -> None:
    with pytest.raises(InputError) as info:
        open_scans(bag, odom_topic=choice)
    message = str(info.value)
    assert (
        "\n" not in message and str(bag) in message and not isinstance(info.value, TopicChoiceError)
    )
    for needle in needles:
        assert needle in message, message


def test_tf_asked_without_tf_odometry_is_one_line(tmp_path: Path) -> None:
    bag = write_bag(tmp_path / "no_tf.bag", {"/odom": (0.0, 0.0, 0.0)})
    with pytest.raises(InputError, match="odometry 'tf': no /tf topic") as info:
        open_scans(bag, odom_topic="tf")
    assert "\n" not in str(info.value) and "Odometry topics: /odom" in str(info.value)


def test_odom_topic_for_a_file_without_topics_is_one_line(tmp_path: Path) -> None:
    log = tmp_path / "one.clf"
    ranges = " ".join(["2.0"] * 180)
    log.write_text(f"FLASER 180 {ranges} 1 2 0.1 1 2 0.1 5.0 host 5.0\n")
    assert open_scans(log).first_scan() is not None
    with pytest.raises(InputError, match="odometry topic applies to bags only") as info:
        open_scans(log, odom_topic="/odom")
    assert "\n" not in str(info.value) and "laser lines' poses" in str(info.value)


def test_listings_open_a_bag_with_several_odometry_topics(bag: Path) -> None:
    sources = laser_topic_sources(bag)
    assert len(sources) == 1 and sources[0].topic == "/scan"
    odometry = sources[0].describe()["odometry"]
    assert "/odom, /wheel_odom" in str(odometry) and "--odom-topic" in str(odometry)
    assert math.isfinite(sources[0].first_scan().ranges[0])


def test_load_scans_names_the_odometry_it_took(bag: Path) -> None:
    scans, label = load_scans(bag, odom_topic="/wheel_odom")
    assert label == "/wheel_odom + /tf"
    np.testing.assert_allclose(_poses(scans), _expected(SOURCES["/wheel_odom"]), atol=1e-6)
    assert load_scans(bag, odom_topic="/odom")[1] == ODOMETRY_POSES
    assert load_scans(bag, odom_topic="tf")[1] == "/tf"
