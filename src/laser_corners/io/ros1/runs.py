"""Runs of ROS 1 bag messages that lie in one chunk, decoded in blocks (the lean path).

:class:`ChunkRun` holds the messages of one run located by
:func:`~laser_corners.io.ros1.lean.locate`: scans and odometry decoded as matrices where their
layout allows, tf messages that repeat the transforms of an earlier one marked; the bag source
(:class:`~laser_corners.io.rosbag.BagSource`) walks the run in order.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray
from rosbags.rosbag1 import Reader as Reader1
from rosbags.rosbag1.reader import read_bytes

from laser_corners.io.ros1.decode import ODOMETRY
from laser_corners.io.ros1.lean import (
    ScanBlock,
    decode_odometry_block,
    decode_scan_block,
    tf_repeats,
)

__all__ = [
    "DAMAGED_CHUNK",
    "DAMAGED_RECORD",
    "LOST_SCANS",
    "ODOM",
    "SCAN",
    "TF",
    "TF_STATIC",
    "ChunkCache",
    "ChunkRun",
    "RawScan",
    "kind_of",
    "lean_readable",
]


@dataclass
class RawScan:
    """A decoded LaserScan message waiting for its pose."""

    where: str
    log_time_ns: int
    stamp_ns: int
    frame_id: str
    angle_min: float
    angle_increment: float
    range_min: float
    range_max: float
    ranges: NDArray[np.floating]
    checked: bool = False  # lean path: geometry checked, ranges float64 read-only


SCAN, ODOM, TF, TF_STATIC = range(4)
"""Message kinds of a run."""
DAMAGED_CHUNK = "damaged bag chunk"
"""Skip reason: a chunk that cannot be decompressed (its messages are lost)."""
DAMAGED_RECORD = "damaged message record"
"""Skip reason: a message record whose header or length does not add up."""
LOST_SCANS = "scans in damaged chunks or records"
"""Skip reason: the scans of the damaged chunks and records (counted from the bag's index)."""


def kind_of(connection: Any, scan_topic: str) -> int:
    """The kind of the messages of ``connection``."""
    if connection.topic == scan_topic:
        return SCAN
    if connection.msgtype == ODOMETRY:
        return ODOM
    return TF_STATIC if connection.topic == "/tf_static" else TF


def lean_readable(reader: Any, topics: list[str], fast: set[int]) -> bool:
    """Whether the lean path (:mod:`laser_corners.io.ros1.lean`) reads these topics: one
    ROS 1 bag read by rosbags' reader, standard message definitions only."""
    if reader.is2 or len(reader.readers) != 1 or not isinstance(reader.readers[0], Reader1):
        return False
    return all(c.id in fast for c in reader.connections if c.topic in topics)


class ChunkCache:
    """Decompressed chunks of a rosbags ROS 1 reader, the last few kept."""

    def __init__(self, owner: Any, keep: int = 3) -> None:
        self.owner = owner
        self.keep = keep
        self.data: dict[int, bytes] = {}

    def get(self, pos: int) -> bytes:
        found = self.data.pop(pos, None)
        if found is None:
            chunk = self.owner.chunks[pos]
            self.owner.bio.seek(chunk.datapos)
            found = chunk.decompressor(read_bytes(self.owner.bio, chunk.datasize))
            if len(self.data) >= self.keep:
                del self.data[next(iter(self.data))]
        self.data[pos] = found  # most recent last
        return found


class ChunkRun:
    """The located messages of one chunk run, decoded in blocks where their layout allows."""

    def __init__(
        self, data: bytes, starts: NDArray[np.int64], lengths: NDArray[np.int64], kinds: list[int]
    ) -> None:
        self.data = data
        self.starts = starts
        self.lengths = lengths
        self.kinds = kinds
        self.repeat = [False] * len(kinds)
        self.odometry: dict[int, tuple[str, str, tuple[float, float, float, float]]] = {}
        self.scans: dict[int, tuple[ScanBlock, int]] = {}

    def raw(self, j: int) -> bytes:
        start = int(self.starts[j])
        return self.data[start : start + int(self.lengths[j])]

    def _same_length(self, kind: int) -> NDArray[np.int64]:
        """Rows of ``kind`` with the length of its first message."""
        rows = np.flatnonzero(np.array(self.kinds, dtype=np.int64) == kind)
        if rows.size == 0:
            return rows
        return rows[self.lengths[rows] == self.lengths[rows[0]]]

    def decode(self) -> None:
        """Decode scans and odometry as matrices; mark repeated tf messages: after the first
        tf message of a layout, the others of that layout and topic name the same frames and
        change nothing (the first value of a transform wins, ``/tf_static`` over ``/tf``)."""
        rows = self._same_length(SCAN)
        if rows.size:
            block = decode_scan_block(self.data, self.starts[rows], int(self.lengths[rows[0]]))
            if block is not None:
                self.scans = {j: (block, r) for r, j in enumerate(rows.tolist())}
        rows = self._same_length(ODOM)
        if rows.size:
            odometry = decode_odometry_block(
                self.data, self.starts[rows], int(self.lengths[rows[0]])
            )
            if odometry is not None:
                frame, child, samples = odometry
                pairs = zip(rows.tolist(), samples, strict=True)
                self.odometry = {j: (frame, child, s) for j, s in pairs}
        for kind in (TF, TF_STATIC):
            rows = self._same_length(kind)
            if rows.size > 1:
                same = tf_repeats(self.data, self.starts[rows], int(self.lengths[rows[0]]))
                if same is not None:
                    for j in rows[1:][same[1:]].tolist():
                        self.repeat[j] = True

    def scan(self, j: int, where: str, log_time: int) -> RawScan | None:
        found = self.scans.get(j)
        if found is None:
            return None
        block, r = found
        return RawScan(
            where,
            log_time,
            block.stamps_ns[r],
            block.frame_id,
            block.angle_min[r],
            block.angle_increment[r],
            block.range_min[r],
            block.range_max[r],
            block.ranges[r],
            block.checked[r],
        )
