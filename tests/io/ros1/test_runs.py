"""Runs of ROS 1 messages in one chunk (:mod:`laser_corners.io.ros1.runs`): decoded in blocks,
they give what the per-message decoders give; repeated tf messages are marked; message kinds."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from laser_corners.io.ros1.decode import (
    LASERSCAN,
    ODOMETRY,
    TFMESSAGE,
    decode_ros1_laserscan,
    decode_ros1_odometry,
)
from laser_corners.io.ros1.runs import ODOM, SCAN, TF, TF_STATIC, ChunkRun, kind_of
from laser_corners.scan import LaserScan
from sim_drives import BagMessages

ROS1 = BagMessages(ros2=False)


def scan_raw(i: int) -> bytes:
    ranges = 1.0 + 0.1 * np.arange(20) + i
    scan = LaserScan(ranges, -0.5, 0.05, 0.05, 30.0)
    return bytes(ROS1.ser(ROS1.scan(100.0 + 0.1 * i, scan), LASERSCAN))


def odom_raw(i: int) -> bytes:
    return bytes(ROS1.ser(ROS1.odometry(100.0 + 0.05 * i, (0.1 * i, 0.0, 0.01 * i)), ODOMETRY))


def tf_raw(stamp: float, pose, child: str = "base_link") -> bytes:
    msg = ROS1.t[TFMESSAGE](transforms=[ROS1.tf(stamp, "odom", child, pose)])
    return bytes(ROS1.ser(msg, TFMESSAGE))


def run_of(messages: list[tuple[int, bytes]]) -> ChunkRun:
    """A run over the messages laid one after the other with some bytes between them."""
    data, starts, lengths = b"", [], []
    for _, raw in messages:
        data += b"\xaa" * 13  # record headers in a real chunk
        starts.append(len(data))
        lengths.append(len(raw))
        data += raw
    kinds = [kind for kind, _ in messages]
    return ChunkRun(data, np.array(starts), np.array(lengths), kinds)


def test_a_run_gives_what_the_per_message_decoders_give() -> None:
    messages = [(SCAN, scan_raw(0)), (ODOM, odom_raw(0)), (SCAN, scan_raw(1)), (ODOM, odom_raw(1))]
    run = run_of(messages)
    run.decode()
    for j, (kind, raw) in enumerate(messages):
        assert run.raw(j) == raw
        if kind == SCAN:
            item = run.scan(j, f"message {j}", 7)
            fields = decode_ros1_laserscan(raw)
            assert (item.where, item.log_time_ns, item.stamp_ns, item.frame_id) == (
                f"message {j}",
                7,
                *fields[:2],
            )
            assert (item.angle_min, item.angle_increment) == pytest.approx(fields[2:4])
            np.testing.assert_array_equal(item.ranges, fields[6])
        else:
            assert run.odometry[j] == decode_ros1_odometry(raw)
            assert run.scan(j, "", 0) is None
    assert run.repeat == [False] * 4


def test_a_scan_of_another_length_is_left_to_the_per_message_path() -> None:
    longer = LaserScan(np.ones(30), -0.5, 0.05, 0.05, 30.0)
    other = bytes(ROS1.ser(ROS1.scan(101.0, longer), LASERSCAN))
    run = run_of([(SCAN, scan_raw(0)), (SCAN, other)])
    run.decode()
    assert run.scan(0, "", 0) is not None and run.scan(1, "", 0) is None


def test_tf_messages_that_change_nothing_are_marked_repeated() -> None:
    same = [tf_raw(100.0 + t, (0.0, 0.0, 0.0)) for t in range(3)]
    moved = tf_raw(104.0, (1.0, 0.0, 0.0))  # same frames, new value: still a repeat (first wins)
    other = tf_raw(105.0, (0.0, 0.0, 0.0), child="base_lonk")  # another frame, same length
    run = run_of([(TF, raw) for raw in [*same, moved, other]] + [(TF_STATIC, same[0])])
    run.decode()
    assert run.repeat == [False, True, True, True, False, False]


def test_kind_of_a_connection() -> None:
    def connection(topic: str, msgtype: str) -> SimpleNamespace:
        return SimpleNamespace(topic=topic, msgtype=msgtype)

    assert kind_of(connection("/scan", LASERSCAN), "/scan") == SCAN
    assert kind_of(connection("/odom", ODOMETRY), "/scan") == ODOM
    assert kind_of(connection("/tf", TFMESSAGE), "/scan") == TF
    assert kind_of(connection("/tf_static", TFMESSAGE), "/scan") == TF_STATIC
