"""Opening bags (:mod:`laser_corners.io.bagfile`): the reader of a ROS 1 bag, the stock typestore
of each kind, and damaged or misnamed bags as one :class:`InputError` line."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from laser_corners.errors import InputError
from laser_corners.io.bagfile import open_bag_reader, read_from_chunks, stock_typestore
from laser_corners.io.ros1.decode import LASERSCAN
from laser_corners.io.ros1.index import LeanIndexReader
from laser_corners.sim import UST_10LX, rectangular_room, trajectory
from laser_corners.sim.export import simulate_sequence, write_sequence


@pytest.fixture(scope="module")
def bag(tmp_path_factory: pytest.TempPathFactory) -> Path:
    rng = np.random.default_rng(1)
    world = rectangular_room()
    poses = trajectory(world, 5, rng, rate_hz=UST_10LX.rate_hz)
    sequence = simulate_sequence(world, UST_10LX, poses, 0.0, rng)
    return write_sequence(sequence, tmp_path_factory.mktemp("sim") / "room")["bag"]


@pytest.mark.parametrize("lean", [True, False])
def test_a_ros1_bag_opens_with_its_index(bag: Path, lean: bool) -> None:
    with open_bag_reader(bag, "ros1", lean=lean) as reader:
        assert isinstance(reader.readers[0], LeanIndexReader) == lean
        assert not read_from_chunks(reader)
        scans = [c for c in reader.connections if c.msgtype == LASERSCAN]
        assert sum(c.msgcount for c in scans) == 5


def test_the_stock_typestores() -> None:
    assert "sensor_msgs/msg/LaserScan" in stock_typestore("ros1").types
    header = stock_typestore("ros1").types["std_msgs/msg/Header"]
    assert "seq" in header.__dataclass_fields__  # ROS 1 headers count
    assert "seq" not in stock_typestore("mcap").types["std_msgs/msg/Header"].__dataclass_fields__


def test_a_ros1_bag_must_be_named_bag(bag: Path, tmp_path: Path) -> None:
    renamed = tmp_path / "room.rosbag"
    renamed.write_bytes(bag.read_bytes())
    with pytest.raises(InputError, match=r"ending in \.bag \(rosbags' rule\)") as info:
        with open_bag_reader(renamed, "ros1"):
            pass
    assert str(renamed) in str(info.value)


@pytest.mark.parametrize(
    ("name", "kind", "content"),
    [
        ("garbage.bag", "ros1", b"#ROSBAG V2.0\n" + b"\x07" * 40),
        ("empty.bag", "ros1", b""),
        ("garbage.mcap", "mcap", b"\x89MCAP0\r\n" + b"\x00" * 20),
        ("missing.bag", "ros1", None),
    ],
)
def test_unreadable_bags_are_one_line(tmp_path: Path, name: str, kind: str, content) -> None:
    path = tmp_path / name
    if content is not None:
        path.write_bytes(content)
    with pytest.raises(InputError, match=f"cannot open the {kind} bag") as info:
        with open_bag_reader(path, kind):
            pass
    assert str(path) in str(info.value) and "\n" not in str(info.value)
