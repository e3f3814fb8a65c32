"""Open a bag with rosbags, and read its messages, with one-line errors for damaged files.

The bag source and the bag writer both read bags through :func:`open_bag_reader` and
:func:`iter_messages`. A ROS 1 bag whose index rosbags refuses is read from its chunk records
(:class:`~laser_corners.io.ros1.chunks.ChunkOrderReader`); only when that fails too is the
file blamed. In a ROS 1 bag, :func:`lean_pieces` locates the messages chunk by chunk and skips
(reporting them) the chunks that cannot be decompressed and the damaged message records, so
the source and the bag writer read on after damage.
"""

from __future__ import annotations

import struct
import zlib
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Protocol

import numpy as np
from numpy.typing import NDArray
from rosbags.highlevel import AnyReader, AnyReaderError
from rosbags.rosbag1 import ReaderError as Reader1Error
from rosbags.rosbag2 import ReaderError as Reader2Error
from rosbags.typesys import Stores, get_typestore

from laser_corners.errors import InputError, first_line
from laser_corners.io.ros1.chunks import ChunkOrderReader
from laser_corners.io.ros1.index import LeanIndexReader, LeanPlan, ModernNamesReader
from laser_corners.io.ros1.lean import locate
from laser_corners.io.ros1.runs import DAMAGED_CHUNK, DAMAGED_RECORD, ChunkCache

__all__ = [
    "CHUNK_ERRORS",
    "CORRUPT_ERRORS",
    "BagInput",
    "Damage",
    "Piece",
    "iter_messages",
    "lean_pieces",
    "open_bag_reader",
    "read_from_chunks",
]

CORRUPT_ERRORS: tuple[type[BaseException], ...] = (
    AnyReaderError,
    Reader1Error,
    Reader2Error,
    AssertionError,
    OSError,
    EOFError,
    struct.error,
    zlib.error,
    UnicodeDecodeError,
    ValueError,
    IndexError,
    KeyError,
)
"""What rosbags lets through on damaged bags (it asserts on some, real or damaged)."""
CHUNK_ERRORS = (*CORRUPT_ERRORS, RuntimeError)  # lz4 raises RuntimeError on bad frames


class BagInput(Protocol):
    """What the bag writer needs of the bag being read (a ``BagSource``)."""

    path: Path
    kind: str
    topic: str | None
    topics: dict[str, tuple[str, int]]
    stamps_ns: list[int]
    log_times_ns: list[int]


def stock_typestore(kind: str) -> Any:
    """The rosbags typestore of the ROS distribution a bag of ``kind`` most likely uses."""
    return get_typestore(Stores.ROS1_NOETIC if kind == "ros1" else Stores.ROS2_HUMBLE)


def _chunk_reader(path: Path, refused: BaseException) -> AnyReader:
    """An open ``AnyReader`` over the chunk records of ROS 1 bag ``path``."""
    reader = AnyReader([path], default_typestore=stock_typestore("ros1"))
    reader.readers = [ChunkOrderReader(path)]
    try:
        reader.open()
    except CHUNK_ERRORS as exc:
        raise InputError(
            f"{path}: cannot open the ros1 bag, damaged or truncated? ({first_line(exc)}; "
            f"rosbags: {type(refused).__name__}: {first_line(refused)})"
        ) from None
    return reader


@contextmanager
def open_bag_reader(path: Path, kind: str, lean: bool = True) -> Iterator[AnyReader]:
    """An open rosbags ``AnyReader`` of the bag ``path`` of ``kind`` (closed on exit).

    A ROS 1 bag is read by :class:`~laser_corners.io.ros1.index.LeanIndexReader` (rosbags'
    reader, its index read with numpy; ``lean=False``: rosbags' own), with today's names for
    the types of bags recorded before ROS Electric (``roslib/Header``); one whose index
    rosbags refuses is read from its chunk records instead.

    Raises
    ------
    InputError
        The bag cannot be read (damaged or truncated).
    """
    if kind == "ros1" and path.suffix != ".bag":
        raise InputError(
            f"{path}: a ROS 1 bag is read only under a name ending in .bag (rosbags' rule); "
            "rename or link it"
        )
    try:
        reader = AnyReader([path], default_typestore=stock_typestore(kind))
        if kind == "ros1":  # rosbags' reader: old type names renamed, the index read with numpy
            reader.readers = [LeanIndexReader(path) if lean else ModernNamesReader(path)]
        reader.open()
    except CORRUPT_ERRORS as exc:
        if kind != "ros1" or isinstance(exc, (FileNotFoundError, PermissionError)):
            raise InputError(
                f"{path}: cannot open the {kind} bag, damaged or truncated? "
                f"({type(exc).__name__}: {first_line(exc)})"
            ) from None
        reader = _chunk_reader(path, exc)
    try:
        yield reader
    finally:
        reader.close()


def read_from_chunks(reader: AnyReader) -> bool:
    """Whether ``reader`` reads a ROS 1 bag from its chunks (its index was refused)."""
    return any(isinstance(r, ChunkOrderReader) for r in reader.readers)


Damage = Callable[[slice, "str | None", str, str], None]
"""``damage(rows, reason, where, detail)``: plan rows lost to a damaged chunk or record
(``reason`` None: a chunk already reported, met again)."""


@dataclass
class Piece:
    """The located messages of plan rows ``first .. first + starts.size`` (one chunk)."""

    data: bytes
    first: int
    starts: NDArray[np.int64]
    lengths: NDArray[np.int64]


def lean_pieces(plan: LeanPlan, damage: Damage) -> Iterator[Piece]:
    """The messages of ``plan`` (one rosbags ROS 1 reader) located chunk run by chunk run.

    A chunk that cannot be decompressed, and a message record that does not add up, are
    handed to ``damage`` and skipped; the rest is read.
    """
    if not plan.connections:
        return
    chunks = ChunkCache(plan.connections[0].owner)
    ids = np.array([c.id for c in plan.connections], dtype=np.int64)
    damaged: set[int] = set()
    for start, stop in plan.runs():
        pos = int(plan.chunks[start])
        if pos in damaged:
            damage(slice(start, stop), None, "", "")
            continue
        try:
            data = chunks.get(pos)
        except CHUNK_ERRORS as exc:
            damaged.add(pos)
            damage(slice(start, stop), DAMAGED_CHUNK, f"chunk at byte {pos}", first_line(exc))
            continue
        while start < stop:
            rows = slice(start, stop)
            conns = ids[plan.ranks[rows]]
            starts, lengths, error = locate(data, plan.offsets[rows], conns, plan.times[rows])
            yield Piece(data, start, starts, lengths)
            if error is None:
                break
            start += starts.size
            where = f"chunk at byte {pos}, record at offset {int(plan.offsets[start])}"
            damage(slice(start, start + 1), DAMAGED_RECORD, where, first_line(error))
            start += 1


def _ros1_messages(connections: list[Any], damage: Damage) -> Iterator[tuple[Any, int, bytes]]:
    plan = LeanPlan.of(connections)
    for piece in lean_pieces(plan, damage):
        ends = piece.starts + piece.lengths
        rows = range(piece.first, piece.first + piece.starts.size)
        for i, start, end in zip(rows, piece.starts.tolist(), ends.tolist(), strict=True):
            yield connections[plan.ranks[i]], int(plan.times[i]), piece.data[start:end]


def iter_messages(
    reader: AnyReader,
    topics: list[str],
    error: Callable[[str], InputError],
    damage: Damage | None = None,
) -> Iterator[tuple[Any, int, bytes]]:
    """``(connection, log_time_ns, raw)`` of the messages of ``topics`` in log-time order.

    Damaged data raises ``error(message)`` (an :class:`InputError` naming the file and the
    position of the caller); with ``damage``, the damaged chunks and records of a ROS 1 bag
    are handed to it and skipped instead (:func:`lean_pieces`).
    """
    connections = [c for c in reader.connections if c.topic in topics]
    if damage is not None and not reader.is2 and len(reader.readers) == 1:
        yield from _ros1_messages(connections, damage)
        return
    iterator = reader.messages(connections=connections)
    while True:
        try:
            item = next(iterator)
        except StopIteration:
            return
        except CHUNK_ERRORS as exc:
            raise error(f"damaged bag data ({type(exc).__name__}: {first_line(exc)})") from None
        yield item
