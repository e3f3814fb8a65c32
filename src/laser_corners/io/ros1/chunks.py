"""Read a ROS 1 bag from its chunk records when rosbags cannot parse its index.

rosbags' ROS 1 reader builds its message index from the bag's INDEX_DATA records and stops on
any surprise there: it assumes every INDEX_DATA header has the field layout of the first one
and asserts ``size == count * 12`` (a bare ``AssertionError``), so some valid bags that
``rosbag info`` reads are refused (e.g. ``laser_scan_matcher/demo/demo.bag`` of
CCNYRoboticsLab/scan_tools). It also refuses bags whose index was never written (a recorder
that was killed: ``index_pos`` 0).

The chunk records carry every message (bag format 2.0, https://wiki.ros.org/Bags/Format/2.0:
a CHUNK record, op 0x05, holds CONNECTION records, op 0x07, and MESSAGE_DATA records, op 0x02,
compressed with ``none``, ``bz2`` or ``lz4``). :class:`ChunkOrderReader` is rosbags' reader
with its index built from the chunks themselves, read in file order: the chunk positions come
from the CHUNK_INFO records (op 0x06) when they can be read, else from walking the records
from the bag header (op 0x03) on, skipping INDEX_DATA records (op 0x04). Everything else
(decompression, message order by time, deserialization) is rosbags' own. A chunk that ends
after the end of the file, or records that do not add up, are damage: ``ReaderError``.
"""

from __future__ import annotations

import os
import re
from collections import defaultdict
from io import BytesIO
from typing import BinaryIO

from rosbags.interfaces import (
    Connection,
    ConnectionExtRosbag1,
    MessageDefinition,
    MessageDefinitionFormat,
)
from rosbags.rosbag1 import Reader, ReaderError
from rosbags.rosbag1.reader import (
    Chunk,
    ChunkInfo,
    Header,
    IndexData,
    RecordType,
    decompressors,
    normalize,
    read_uint32,
)
from rosbags.typesys.msg import normalize_msgtype

from laser_corners.io.ros1.legacy import modern_connection

__all__ = ["ChunkOrderReader"]

_MAGIC = re.compile(rb"#ROSBAG V2\.0\n")


def _connection(header: Header, data: Header, owner: Reader) -> Connection:
    """A rosbags ``Connection`` from the two headers of a CONNECTION record (count 0)."""
    latching = data.get_string("latching") if "latching" in data else None
    connection = Connection(
        header.get_uint32("conn"),
        normalize(header.get_string("topic")),
        normalize_msgtype(data.get_string("type")),
        MessageDefinition(MessageDefinitionFormat.MSG, data.get_string("message_definition")),
        data.get_string("md5sum"),
        0,
        ConnectionExtRosbag1(
            data.get_string("callerid") if "callerid" in data else None,
            int(latching) if latching not in (None, "") else None,
        ),
        owner,
    )
    return modern_connection(connection)


class ChunkOrderReader(Reader):
    """rosbags' ROS 1 reader whose index is built from the chunk records, not INDEX_DATA.

    Use it in place of ``rosbags.rosbag1.Reader`` (e.g. as the only reader of an
    ``AnyReader``); ``messages()``, ``connections``, ``topics`` and the time span behave the
    same. Opening decompresses every chunk once to find its messages.
    """

    def open(self) -> None:
        """Open the bag and index the messages of its chunks.

        Raises
        ------
        ReaderError
            Not a ROS 1 v2.0 bag, a truncated chunk, or chunk records that do not add up.
        """
        if self.bio is not None:
            raise ReaderError("Reader is already open.")
        try:
            self.bio = self.path.open("rb")
        except OSError as err:
            raise ReaderError(f"cannot open: {err.strerror}") from None
        try:
            self._index_chunks()
        except BaseException:
            self.close()
            raise

    def _index_chunks(self) -> None:
        bio = self.bio
        assert bio is not None
        if not _MAGIC.fullmatch(bio.readline()):
            raise ReaderError("not a ROS bag of format version 2.0")
        header = Header.read(bio, RecordType.BAGHEADER)
        index_pos = header.get_uint64("index_pos")
        bio.seek(read_uint32(bio), os.SEEK_CUR)  # the bag header's padding
        size = os.fstat(bio.fileno()).st_size
        first_record = bio.tell()
        positions = self._positions_from_index(header, index_pos, size)
        if positions is None:
            bio.seek(first_record)
            positions = self._walk(index_pos if 0 < index_pos <= size else size, size)
        connections: dict[int, Connection] = {}
        indexes: dict[int, list[IndexData]] = defaultdict(list)
        for pos in positions:
            self._read_chunk(pos, size, connections, indexes)
        unknown = set(indexes) - set(connections)
        if unknown:
            raise ReaderError(f"messages of connection {min(unknown)}, which no record defines")
        self.indexes = {cid: sorted(indexes[cid]) for cid in connections}
        self.connections = [
            Connection(*c[0:5], len(self.indexes[cid]), *c[6:]) for cid, c in connections.items()
        ]

    def _positions_from_index(self, header: Header, index_pos: int, size: int) -> list[int] | None:
        """Chunk positions from the CHUNK_INFO records, or None when they cannot be read."""
        if not 0 < index_pos < size:
            return None
        bio = self.bio
        assert bio is not None
        try:
            bio.seek(index_pos)
            for _ in range(header.get_uint32("conn_count")):
                Header.read(bio, RecordType.CONNECTION)
                Header.read(bio)
            infos = [self.read_chunk_info() for _ in range(header.get_uint32("chunk_count"))]
        except (ReaderError, ValueError, OSError):
            return None
        positions = [info.pos for info in infos]
        return positions if all(0 < p < size for p in positions) else None

    def _walk(self, end: int, size: int) -> list[int]:
        """Chunk positions found by reading the records from here up to ``end``."""
        bio = self.bio
        assert bio is not None
        positions = []
        while (pos := bio.tell()) < end:
            header = Header.read(bio)
            op = header.get_uint8("op")
            length = read_uint32(bio)
            if (end_of_record := bio.tell() + length) > size:
                name = "chunk" if op == RecordType.CHUNK else "record"
                raise ReaderError(
                    f"{name} at byte {pos} ends at byte {end_of_record}, after the end of the "
                    f"file ({size} bytes): truncated"
                )
            if op == RecordType.CHUNK:
                positions.append(pos)
            elif op in (RecordType.CONNECTION, RecordType.CHUNK_INFO):
                break  # the index section of a bag whose header does not point to it
            elif op != RecordType.IDXDATA:
                raise ReaderError(f"unexpected record op {op} at byte {pos}")
            bio.seek(length, os.SEEK_CUR)
        return positions

    def _read_chunk(
        self,
        pos: int,
        size: int,
        connections: dict[int, Connection],
        indexes: dict[int, list[IndexData]],
    ) -> None:
        """Index the connection and message records of the chunk at ``pos``."""
        bio = self.bio
        assert bio is not None
        bio.seek(pos)
        header = Header.read(bio, RecordType.CHUNK)
        compression = header.get_string("compression")
        if compression not in decompressors:
            raise ReaderError(f"chunk at byte {pos}: unknown compression {compression!r}")
        datasize = read_uint32(bio)
        datapos = bio.tell()
        if datapos + datasize > size:
            raise ReaderError(
                f"chunk at byte {pos} ends at byte {datapos + datasize}, after the end of the "
                f"file ({size} bytes): truncated"
            )
        data = decompressors[compression](bio.read(datasize))
        counts, start, end = self._records(BytesIO(data), len(data), pos, connections, indexes)
        self.chunks[pos] = Chunk(datasize, datapos, decompressors[compression])
        self.chunk_infos.append(ChunkInfo(pos, start, end + 1, counts))

    def _records(
        self,
        chunk: BinaryIO,
        length: int,
        pos: int,
        connections: dict[int, Connection],
        indexes: dict[int, list[IndexData]],
    ) -> tuple[dict[int, int], int, int]:
        """Walk the records of one decompressed chunk: message counts by connection, first
        and last message time (ns)."""
        counts: dict[int, int] = defaultdict(int)
        start, end = 2**63 - 1, -1
        while (offset := chunk.tell()) < length:
            header = Header.read(chunk)
            op = header.get_uint8("op")
            if op == RecordType.CONNECTION:
                data = Header.read(chunk)
                connection = _connection(header, data, self)
                connections.setdefault(connection.id, connection)
                continue
            size = read_uint32(chunk)
            if op != RecordType.MSGDATA or chunk.tell() + size > length:
                raise ReaderError(f"chunk at byte {pos}: bad record at offset {offset}")
            cid, time = header.get_uint32("conn"), header.get_time("time")
            indexes[cid].append(IndexData(time, pos, offset))
            counts[cid] += 1
            start, end = min(start, time), max(end, time)
            chunk.seek(size, os.SEEK_CUR)
        return dict(counts), start, end
