"""A lean ROS 1 message path: whole chunks located and decoded with numpy, not per message.

rosbags' ROS 1 reader yields one message at a time through Python (an index entry, a seek, a
generic record-header parse, a copy): with the decoders of :mod:`laser_corners.io.ros1.decode`
that loop was most of the reader's time on scan bags. Here the order and places of the
messages still come from rosbags' index (``Reader.indexes``: every message's log time, chunk
and offset), so the order is exactly the one of ``AnyReader.messages`` (by time, ties by
connection then index order: a stable sort of the per-connection lists), but each run of
messages that lies in one chunk is handled at once:

* the order comes from :class:`~laser_corners.io.ros1.index.LeanPlan`;
* the chunk is decompressed once (bz2 and lz4 release the GIL, so a reader thread overlaps
  this with the detector) and kept while the run order comes back to it;
* the MESSAGE_DATA record headers (https://wiki.ros.org/Bags/Format/2.0, op 0x02) of the run
  are gathered into one byte matrix and checked against the first one (same fields, op 2,
  and the connection and time the index gives), which yields every message's bytes;
* messages of one type and one length whose non-value bytes (frame names, array lengths) equal
  the first one's, which the per-message decoder accepted, are decoded as a matrix.

Anything else (another header layout, a damaged record, another message length) goes through
rosbags' own record reading or the per-message decoders for that record, so the errors and
counted skips are the ones of the per-message path.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from io import BytesIO
from typing import Any

import numpy as np
from numpy.typing import NDArray
from rosbags.rosbag1 import ReaderError
from rosbags.rosbag1.reader import Header, RecordType, read_bytes, read_uint32

from laser_corners.io.poses import yaw_from_quaternion
from laser_corners.io.ros1.decode import (
    decode_ros1_laserscan,
    decode_ros1_odometry,
    decode_ros1_tf,
)

__all__ = [
    "ScanBlock",
    "decode_odometry_block",
    "decode_scan_block",
    "finite_pose",
    "locate",
    "tf_repeats",
]

_I64 = np.int64


def _gather(data: NDArray[np.uint8], starts: NDArray[np.int64], width: int) -> NDArray[np.uint8]:
    """Rows ``data[start : start + width]`` for each start (all in range)."""
    return data[starts[:, None] + np.arange(width, dtype=_I64)]


def _u32(columns: NDArray[np.uint8]) -> NDArray[np.int64]:
    """Little-endian uint32 of a ``(n, 4)`` byte matrix."""
    return np.ascontiguousarray(columns).view("<u4")[:, 0].astype(_I64)


def _slow_record(data: bytes, offset: int, conn: int, time: int) -> tuple[int, int]:
    """``(start, length)`` of the message bytes of the record at ``offset``, read as rosbags'
    ``Reader.messages`` reads it (its errors on damaged records)."""
    chunk = BytesIO(data)
    chunk.seek(offset)
    while True:
        header = Header.read(chunk)
        have = header.get_uint8("op")
        if have != RecordType.CONNECTION:
            break
        chunk.seek(read_uint32(chunk), 1)
    if have != RecordType.MSGDATA:
        raise ReaderError("Expected to find message data.")
    size = read_uint32(chunk)
    start = chunk.tell()
    read_bytes(chunk, size)  # raises on a record cut short
    if header.get_uint32("conn") != conn:
        raise ReaderError(f"record at offset {offset}: connection {header.get_uint32('conn')}")
    assert time == header.get_time("time")
    return start, size


def _template(data: bytes, offset: int) -> tuple[int, NDArray[np.bool_], int, int] | None:
    """Header length, constant-byte mask, conn and time columns of one MESSAGE_DATA header
    (columns from ``offset``, after the header's own length field); None if not such a
    header."""
    view = memoryview(data)
    if offset + 4 > len(data):
        return None
    size = int.from_bytes(view[offset : offset + 4], "little")
    end = offset + 4 + size
    if end + 4 > len(data):
        return None
    mask = np.ones(4 + size + 4, dtype=bool)
    mask[:4] = True
    mask[4 + size :] = False  # the data length
    at, fields = offset + 4, {}
    while at < end:
        length = int.from_bytes(view[at : at + 4], "little")
        field = bytes(view[at + 4 : at + 4 + length])
        name, sep, value = field.partition(b"=")
        if not sep or at + 4 + length > end:
            return None
        fields[name] = (at + 4 + len(name) + 1 - offset, value)
        at += 4 + length
    op, conn, time = fields.get(b"op"), fields.get(b"conn"), fields.get(b"time")
    if op is None or op[1] != b"\x02" or conn is None or time is None:
        return None
    if len(conn[1]) != 4 or len(time[1]) != 8:
        return None
    mask[conn[0] : conn[0] + 4] = False
    mask[time[0] : time[0] + 8] = False
    return size, mask, conn[0], time[0]


def locate(
    data: bytes, offsets: NDArray[np.int64], conns: NDArray[np.int64], times: NDArray[np.int64]
) -> tuple[NDArray[np.int64], NDArray[np.int64], BaseException | None]:
    """Start and length of the message bytes of each record, in bulk.

    Parameters
    ----------
    data : bytes
        The decompressed chunk.
    offsets, conns, times : ndarray of int64
        Each record's offset, connection id and log time (from the index).

    Returns
    -------
    starts, lengths : ndarray of int64
        Of the records before the first damaged one (all of them when none is).
    error : Exception or None
        What rosbags raises on the first damaged record.
    """
    n = offsets.size
    starts = np.empty(n, dtype=_I64)
    lengths = np.empty(n, dtype=_I64)
    good = np.zeros(n, dtype=bool)
    found = _template(data, int(offsets[0])) if n else None
    if found is not None:
        size, mask, conn_at, time_at = found
        width = 4 + size + 4
        fits = offsets + width <= len(data)
        buf = np.frombuffer(data, dtype=np.uint8)
        rows = _gather(buf, np.where(fits, offsets, 0), width)
        first = rows[0]
        good = fits & (rows[:, mask] == first[mask]).all(axis=1)
        good &= _u32(rows[:, conn_at : conn_at + 4]) == conns
        sec = _u32(rows[:, time_at : time_at + 4])
        nsec = _u32(rows[:, time_at + 4 : time_at + 8])
        good &= sec * 1_000_000_000 + nsec == times
        starts[:] = offsets + width
        lengths[:] = _u32(rows[:, width - 4 :])
        good &= starts + lengths <= len(data)
    for i in np.flatnonzero(~good).tolist():
        try:
            where = (data, int(offsets[i]), int(conns[i]), int(times[i]))
            starts[i], lengths[i] = _slow_record(*where)
        except Exception as exc:  # handed to the caller after the good prefix
            return starts[:i], lengths[:i], exc
    return starts, lengths, None


def _matrix(data: bytes, starts: NDArray[np.int64], length: int) -> NDArray[np.uint8]:
    """Rows ``data[start : start + length]`` (a copy; slices stacked: long rows)."""
    buf = np.frombuffer(data, dtype=np.uint8)
    return np.stack([buf[s : s + length] for s in starts.tolist()])


def _column(rows: NDArray[np.uint8], at: int, dtype: str) -> NDArray[Any]:
    width = np.dtype(dtype).itemsize
    return np.ascontiguousarray(rows[:, at : at + width]).view(dtype)[:, 0]


@dataclass
class ScanBlock:
    """LaserScan fields of several messages of one layout, decoded as a matrix.

    ``ranges`` is float64 and read-only; ``checked`` says which rows have valid geometry
    (finite angles, non-zero increment, ``range_min < range_max``).
    """

    stamps_ns: list[int]
    frame_id: str
    angle_min: list[float]
    angle_increment: list[float]
    range_min: list[float]
    range_max: list[float]
    ranges: NDArray[np.float64]
    checked: list[bool]


def decode_scan_block(data: bytes, starts: NDArray[np.int64], length: int) -> ScanBlock | None:
    """The LaserScan messages of ``length`` bytes at ``starts``, or None when they do not all
    share the first one's layout (frame name, beam and intensity counts)."""
    first = decode_ros1_laserscan(memoryview(data)[int(starts[0]) : int(starts[0]) + length])
    if first is None:
        return None
    frame_id, n_ranges = first[1], first[6].size
    name_end = 16 + len(frame_id.encode())
    ranges_at = name_end + 32
    rows = _matrix(data, starts, length)
    counts_at = ranges_at + 4 * n_ranges  # the intensity count
    fixed = np.r_[12:name_end, ranges_at - 4 : ranges_at, counts_at : counts_at + 4]
    if not (rows[:, fixed] == rows[0, fixed]).all():
        return None
    fields = np.ascontiguousarray(rows[:, name_end : name_end + 28]).view("<f4")
    angle_min, angle_increment = fields[:, 0], fields[:, 2]
    range_min, range_max = fields[:, 5], fields[:, 6]
    with np.errstate(invalid="ignore"):
        checked = (
            np.isfinite(angle_min)
            & np.isfinite(angle_increment)
            & (angle_increment != 0)
            & (range_min < range_max)
        )
    sec = _column(rows, 4, "<i4").astype(_I64)
    nsec = _column(rows, 8, "<u4").astype(_I64)
    ranges = np.ascontiguousarray(rows[:, ranges_at : ranges_at + 4 * n_ranges])
    ranges64 = ranges.view("<f4").astype(np.float64)
    ranges64.setflags(write=False)
    return ScanBlock(
        (sec * 1_000_000_000 + nsec).tolist(),
        frame_id,
        angle_min.astype(np.float64).tolist(),
        angle_increment.astype(np.float64).tolist(),
        range_min.astype(np.float64).tolist(),
        range_max.astype(np.float64).tolist(),
        ranges64,
        checked.tolist(),
    )


def decode_odometry_block(
    data: bytes, starts: NDArray[np.int64], length: int
) -> tuple[str, str, list[tuple[float, float, float, float]]] | None:
    """``(frame_id, child_frame_id, samples)`` of the Odometry messages of ``length`` bytes at
    ``starts`` (samples as :func:`decode_ros1_odometry` gives them), or None when they do not
    all share the first one's frame names."""
    first = decode_ros1_odometry(memoryview(data)[int(starts[0]) : int(starts[0]) + length])
    if first is None:
        return None
    frame, child, _ = first
    pose_at = 12 + 4 + len(frame.encode()) + 4 + len(child.encode())
    rows = _matrix(data, starts, length)
    if not (rows[:, 12:pose_at] == rows[0, 12:pose_at]).all():
        return None
    sec = _column(rows, 4, "<i4").astype(np.float64)
    nsec = _column(rows, 8, "<u4").astype(np.float64)
    stamps = sec + 1e-9 * nsec
    pose = np.ascontiguousarray(rows[:, pose_at : pose_at + 56]).view("<f8")
    x, y, qx, qy, qz, qw = (pose[:, i].tolist() for i in (0, 1, 3, 4, 5, 6))
    yaw: Callable[..., float] = yaw_from_quaternion
    samples = [
        (t, a, b, yaw(*q))
        for t, a, b, *q in zip(stamps.tolist(), x, y, qx, qy, qz, qw, strict=True)
    ]
    return frame, child, samples


def finite_pose(pose: tuple[float, float, float] | None) -> bool:
    """Whether ``pose`` is None or three finite numbers (what ``LaserScan`` accepts)."""
    return pose is None or all(math.isfinite(v) for v in pose)


def tf_repeats(data: bytes, starts: NDArray[np.int64], length: int) -> NDArray[np.bool_] | None:
    """Which TFMessages of ``length`` bytes at ``starts`` carry the transforms (count, frame
    names) of the first one, which the per-message decoder accepts; None when it does not."""
    first = decode_ros1_tf(memoryview(data)[int(starts[0]) : int(starts[0]) + length])
    if first is None:
        return None
    columns, at = list(range(4)), 4
    for parent, child, _ in first:
        at += 12  # header seq and stamp
        names = 8 + len(parent.encode()) + len(child.encode())
        columns.extend(range(at, at + names))
        at += names + 56  # translation and rotation
    rows = _matrix(data, starts, length)
    return (rows[:, columns] == rows[0, columns]).all(axis=1)
