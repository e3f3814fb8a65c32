"""The ROS 1 fast decoders (:mod:`laser_corners.io.ros1.decode`) give exactly what rosbags'
deserializer gives, on messages serialized here; bytes that are not one message give None."""

from __future__ import annotations

import math

import numpy as np
import pytest

from laser_corners.io.ros1.decode import (
    LASERSCAN,
    ODOMETRY,
    ROS1_DIGESTS,
    decode_ros1_laserscan,
    decode_ros1_odometry,
    decode_ros1_tf,
    laserscan_fields,
    odometry_of,
    transforms_of,
)
from laser_corners.scan import LaserScan
from sim_drives import TF_TYPE, BagMessages

ROS1 = BagMessages(ros2=False)


def _scan_bytes(frame: str = "laser") -> bytes:
    ranges = np.array([1.0, 2.5, np.nan, np.inf, 0.25], dtype=np.float64)
    scan = LaserScan(ranges, -0.3, 0.15, 0.05, 20.0)
    msg = ROS1.scan(1_700_000_000.5, scan, frame)
    return bytes(ROS1.ser(msg, LASERSCAN))


def test_laserscan_decodes_as_the_deserializer() -> None:
    raw = _scan_bytes("base_laser")
    fields = decode_ros1_laserscan(raw)
    assert fields is not None
    expected = laserscan_fields(ROS1.store.deserialize_ros1(raw, LASERSCAN))
    assert fields[:6] == expected[:6]
    np.testing.assert_array_equal(fields[6], expected[6])
    assert fields[1] == "base_laser" and fields[0] == 1_700_000_000_500_000_000
    assert fields[2] == pytest.approx(-0.3) and fields[6].dtype == np.float32


def test_odometry_and_tf_decode_as_the_deserializer() -> None:
    raw = bytes(ROS1.ser(ROS1.odometry(12.5, (1.0, -2.0, 0.75)), ODOMETRY))
    frame, child, sample = decode_ros1_odometry(raw)
    assert (frame, child) == ("odom", "base_link")
    assert sample == pytest.approx((12.5, 1.0, -2.0, 0.75))
    assert (frame, child, sample) == odometry_of(ROS1.store.deserialize_ros1(raw, ODOMETRY))

    tf = ROS1.t[TF_TYPE](
        transforms=[
            ROS1.tf(3.0, "odom", "base_link", (0.5, 0.0, math.pi / 2)),
            ROS1.tf(3.0, "base_link", "laser", (0.2, 0.1, -0.1)),
        ]
    )
    raw = bytes(ROS1.ser(tf, TF_TYPE))
    transforms = decode_ros1_tf(raw)
    assert transforms == transforms_of(ROS1.store.deserialize_ros1(raw, TF_TYPE))
    assert [(p, c) for p, c, _ in transforms] == [("odom", "base_link"), ("base_link", "laser")]
    assert transforms[0][2] == pytest.approx((0.5, 0.0, math.pi / 2))


@pytest.mark.parametrize("cut", [1, 7, 40])
def test_bytes_that_are_not_one_message_give_none(cut: int) -> None:
    raw = _scan_bytes()
    assert decode_ros1_laserscan(raw[:-cut]) is None
    assert decode_ros1_laserscan(raw + b"\0" * cut) is None
    odometry = bytes(ROS1.ser(ROS1.odometry(1.0, (0.0, 0.0, 0.0)), ODOMETRY))
    assert decode_ros1_odometry(odometry[:-cut]) is None
    tf = bytes(ROS1.ser(ROS1.t[TF_TYPE](transforms=[ROS1.tf(1.0, "a", "b", (0, 0, 0))]), TF_TYPE))
    assert decode_ros1_tf(tf[:-cut]) is None and decode_ros1_tf(tf + b"\0" * cut) is None
    assert decode_ros1_laserscan(b"") is None and decode_ros1_tf(b"") is None


def test_a_frame_name_that_is_not_utf8_gives_none() -> None:
    raw = _scan_bytes("laser")
    bad = raw.replace(b"laser", b"las\xffr")
    assert decode_ros1_laserscan(bad) is None


def test_the_digests_are_those_of_the_stock_definitions() -> None:
    # rosbags computes the ROS 1 MD5 of its own (Noetic) definitions
    for msgtype in (LASERSCAN, ODOMETRY, TF_TYPE):
        assert ROS1.store.generate_msgdef(msgtype)[1] == ROS1_DIGESTS[msgtype]
