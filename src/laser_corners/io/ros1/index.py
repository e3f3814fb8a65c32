"""The message index of a ROS 1 bag read with numpy, and the reading order of its messages.

rosbags' ROS 1 reader (``Reader.open``) turns every INDEX_DATA entry (bag format 2.0,
https://wiki.ros.org/Bags/Format/2.0, op 0x04: log time and offset in the chunk of each message
of one connection in one chunk) into a Python tuple, one at a time; on scan bags that was about
an eighth of the reader's time. :class:`LeanIndexReader` reads each record as one numpy array
and :class:`LeanPlan` orders the messages as ``AnyReader.messages`` does.
"""

from __future__ import annotations

import itertools
from collections import defaultdict
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray
from rosbags.rosbag1 import Reader, ReaderError
from rosbags.rosbag1.reader import IndexData, deserialize_uint32

from laser_corners.io.ros1.legacy import modern_connection

__all__ = ["LeanIndexReader", "LeanPlan", "ModernNamesReader"]

_I64 = np.int64
_ENTRY = np.dtype([("sec", "<u4"), ("nsec", "<u4"), ("offset", "<u4")])  # INDEX_DATA v1


class ModernNamesReader(Reader):
    """rosbags' ROS 1 reader whose connections carry today's type names (bags recorded before
    ROS Electric, :mod:`laser_corners.io.ros1.legacy`)."""

    def open(self) -> None:
        """Open the bag and read its index (as ``Reader.open``), then rename old types."""
        super().open()
        self.connections = [modern_connection(c) for c in self.connections]


class LeanIndexReader(ModernNamesReader):
    """rosbags' ROS 1 reader whose message index is read with numpy.

    ``Reader.open`` turns every INDEX_DATA entry into an ``IndexData`` tuple; here each
    record becomes one structured array (:attr:`index_arrays`), and the tuples
    (``indexes``, what ``Reader.messages`` uses) are built only when first asked for.
    Records are checked as rosbags checks them (same errors).
    """

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        self.index_arrays: dict[int, list[tuple[int, NDArray[Any]]]] = defaultdict(list)
        self._assigned: dict[int, list[IndexData]] = {}
        self._built: dict[int, list[IndexData]] | None = None
        self._lazy = False
        super().__init__(*args, **kwargs)

    def open(self) -> None:
        """Open the bag and read its index (as ``Reader.open``)."""
        self._lazy = False  # Reader.open counts the placeholders
        super().open()
        self._lazy = bool(self.index_arrays)

    @property  # type: ignore[override]
    def indexes(self) -> dict[int, list[IndexData]]:
        """Every connection's ``IndexData`` list sorted by time (built on first use)."""
        if not self._lazy:
            return self._assigned
        if self._built is None:
            built = {}
            for connection in self.connections:
                entries = [
                    IndexData(int(t), pos, int(o))
                    for pos, array in self.index_arrays.get(connection.id, [])
                    for t, o in zip(_times(array).tolist(), array["offset"].tolist(), strict=True)
                ]
                entries.sort()  # by time only, stable: as rosbags' sorted()
                built[connection.id] = entries
            self._built = built
        return self._built

    @indexes.setter
    def indexes(self, value: dict[int, list[IndexData]]) -> None:
        self._assigned = value
        self._built = None

    def close(self) -> None:
        """Close the bag (and forget the index)."""
        self.index_arrays = defaultdict(list)
        self._lazy = False
        super().close()

    def read_index_data(self, pos: int, indexes: dict[int, list[IndexData]]) -> None:
        """Read the INDEX_DATA record here into :attr:`index_arrays`.

        The record header is read as ``Reader.read_index_data`` reads it (the field layout
        of the first record assumed for all, the same checks and errors), so the same bags
        are refused (and then read from their chunks, :mod:`laser_corners.io.ros1.chunks`).
        """
        assert self.bio
        buf = self.bio.read(55)
        if not self.index_data_header_offsets:
            (size,) = deserialize_uint32(buf, 0)
            assert size == 47
            idx, connpos, countpos = 4, -1, -1
            while idx < size:
                char = buf[idx + 6]
                if char == 61:  # ord(b'=')
                    assert buf[idx + 7] == 4
                    idx += 8
                elif char == 114:  # ord(b'r')
                    if (ver := buf[idx + 8]) != 1:
                        raise ReaderError(f"IDXDATA version {ver} is not supported.")
                    idx += 12
                elif char == 110:  # ord(b'n')
                    connpos = idx + 9
                    idx += 13
                else:
                    assert char == 117  # ord(b'u')
                    countpos = idx + 10
                    idx += 14
            self.index_data_header_offsets = (connpos, countpos)
        connpos, countpos = self.index_data_header_offsets
        (conn,) = deserialize_uint32(buf, connpos)
        (count,) = deserialize_uint32(buf, countpos)
        (size,) = deserialize_uint32(buf, 51)
        assert size == count * 12
        array = np.frombuffer(self.bio.read(size), dtype=_ENTRY)
        self.index_arrays[conn].append((pos, array))
        indexes[conn].extend(itertools.repeat(0, count))  # placeholders: counted, sorted fast


def _times(array: NDArray[Any]) -> NDArray[np.int64]:
    return array["sec"].astype(_I64) * 1_000_000_000 + array["nsec"].astype(_I64)


def _index_table(connection: Any) -> NDArray[np.int64]:
    """``(n, 3)`` time, chunk position, offset of the messages of ``connection``, sorted by
    time (stable), as its rosbags index list."""
    owner = connection.owner
    lean = isinstance(owner, LeanIndexReader) and owner._lazy
    parts = owner.index_arrays.get(connection.id, []) if lean else None
    if parts is None:
        flat = itertools.chain.from_iterable(owner.indexes[connection.id])
        count = 3 * len(owner.indexes[connection.id])
        return np.fromiter(flat, dtype=_I64, count=count).reshape(-1, 3)
    if not parts:
        return np.empty((0, 3), dtype=_I64)
    table = np.concatenate(
        [
            np.stack(
                [_times(a), np.full(a.size, pos, dtype=_I64), a["offset"].astype(_I64)], axis=1
            )
            for pos, a in parts
        ]
    )
    return table[np.argsort(table[:, 0], kind="stable")]


@dataclass
class LeanPlan:
    """Every message to read, in ``AnyReader.messages`` order.

    Attributes
    ----------
    times : ndarray of int64
        Log times (ns).
    chunks : ndarray of int64
        Position of each message's chunk in the file.
    offsets : ndarray of int64
        Offset of its record in the decompressed chunk.
    ranks : ndarray of int64
        Index of its connection in ``connections``.
    connections : list
        The rosbags connections read.
    """

    times: NDArray[np.int64]
    chunks: NDArray[np.int64]
    offsets: NDArray[np.int64]
    ranks: NDArray[np.int64]
    connections: list[Any]

    @classmethod
    def of(cls, connections: list[Any]) -> LeanPlan:
        """The plan of ``connections`` (all owned by one plain rosbags ROS 1 ``Reader``)."""
        parts = [_index_table(c) for c in connections]
        ranks = np.concatenate(
            [np.full(len(p), rank, dtype=_I64) for rank, p in enumerate(parts)] or [[]]
        ).astype(_I64)
        table = np.concatenate(parts) if parts else np.empty((0, 3), dtype=_I64)
        order = np.argsort(table[:, 0], kind="stable")  # heapq.merge of time-sorted lists
        table, ranks = table[order], ranks[order]
        return cls(table[:, 0].copy(), table[:, 1].copy(), table[:, 2].copy(), ranks, connections)

    def runs(self) -> list[tuple[int, int]]:
        """``(start, stop)`` of each maximal run of consecutive messages in one chunk."""
        if self.chunks.size == 0:
            return []
        cuts = np.flatnonzero(np.diff(self.chunks)) + 1
        bounds = [0, *cuts.tolist(), int(self.chunks.size)]
        return list(itertools.pairwise(bounds))
