"""rosbags' ROS 1 bag writer with the bag header record laid out exactly as rosbag lays it out.

Bag format 2.0 (https://wiki.ros.org/Bags/Format/2.0) starts with ``#ROSBAG V2.0\\n`` and the
bag header record (op 0x03: ``index_pos``, ``conn_count``, ``chunk_count``), which is
rewritten when the bag is closed, so it is padded to a fixed size. rosbag (``bag.py``,
``_write_file_header_record``; the C++ ``Bag::writeFileHeaderRecord`` alike) pads the record's
*data* with spaces so that header fields plus padding fill 4096 bytes: the first chunk starts at
byte 13 + 4 + 4096 + 4 = 4117. rosbags 0.11 counts the two length fields in the 4096, so its
first chunk starts at byte 4109; rosbags and rosbag read both (they follow the lengths), but
``rosbag reindex`` rewrites the header as rosbag lays it out, 8 bytes longer, over the start of
the first chunk. :class:`RosbagWriter` writes rosbag's layout.

Compression (``bz2``, ``lz4`` or ``none``) is rosbags' (``Writer.set_compression``), except
that ``lz4`` chunks are LZ4 frames as ``roslz4`` (rosbag's lz4) writes and reads them: 1 MB
independent blocks, a content checksum, no content size. rosbags 0.11 writes frames with the
content size and linked blocks, which ``roslz4`` refuses ("malformed data to decompress"), so
``rosbag play`` could not read its lz4 bags.
"""

from __future__ import annotations

from pathlib import Path
from typing import BinaryIO

import lz4.frame
from rosbags.rosbag1 import Writer, WriterError
from rosbags.rosbag1.writer import MAXSIZE, Header, RecordType, serialize_uint32

__all__ = ["BAG_HEADER_SIZE", "COMPRESSIONS", "RosbagWriter"]

BAG_HEADER_SIZE = 4096
"""Bytes of the bag header record's fields plus padding (rosbag's ``FILE_HEADER_LENGTH``)."""
_MAGIC = b"#ROSBAG V2.0\n"
COMPRESSIONS: tuple[str, ...] = ("none", "lz4", "bz2")
"""Chunk compressions of a ROS 1 bag (those ``rosbag record`` offers)."""


def roslz4_compress(data: bytes) -> bytes:
    """``data`` as one LZ4 frame laid out as ``roslz4`` lays it out (which it can read)."""
    return bytes(
        lz4.frame.compress(
            data,
            compression_level=0,
            block_size=lz4.frame.BLOCKSIZE_MAX1MB,
            block_linked=False,
            content_checksum=True,
            store_size=False,
        )
    )


def _write_bag_header(bio: BinaryIO, index_pos: int, conn_count: int, chunk_count: int) -> None:
    """The bag header record at byte 13, padded as rosbag pads it (ends at byte 4117)."""
    header = Header()
    header.set_uint64("index_pos", index_pos)
    header.set_uint32("conn_count", conn_count)
    header.set_uint32("chunk_count", chunk_count)
    bio.seek(len(_MAGIC))
    size = header.write(bio, RecordType.BAGHEADER) - 4  # the fields, without their length
    padding = BAG_HEADER_SIZE - size
    bio.write(serialize_uint32(padding) + b" " * padding)


class RosbagWriter(Writer):
    """rosbags' ROS 1 ``Writer`` whose bag header record is rosbag's (first chunk at 4117).

    Parameters
    ----------
    path : Path
        The bag to create (must not exist).
    compression : {"none", "lz4", "bz2"}
        Chunk compression.

    Raises
    ------
    ValueError
        An unknown compression.
    """

    def __init__(self, path: Path | str, compression: str = "none") -> None:
        super().__init__(path)
        if compression not in COMPRESSIONS:
            raise ValueError(f"compression must be one of {', '.join(COMPRESSIONS)}")
        if compression != "none":
            self.set_compression(Writer.CompressionFormat[compression.upper()])
        if compression == "lz4":
            self.compressor = roslz4_compress

    def open(self) -> None:
        """Create the bag and write its magic line and (empty) bag header record."""
        try:
            self.bio = self.path.open("xb")
        except FileExistsError:
            raise WriterError(f"{self.path} exists already, not overwriting.") from None
        self.bio.write(_MAGIC)
        _write_bag_header(self.bio, 0, 0, 0)

    def close(self) -> None:
        """Write the open chunk, the index (connections, chunk infos) and the bag header."""
        assert self.bio
        for chunk in self.chunks:
            if chunk.pos == -1:
                self.write_chunk(chunk)
        index_pos = self.bio.tell()
        for connection in self.connections:
            self.write_connection(connection, self.bio)
        written = [chunk for chunk in self.chunks if chunk.pos != -1]
        for chunk in written:
            header = Header()
            header.set_uint32("ver", 1)
            header.set_uint64("chunk_pos", chunk.pos)
            header.set_time("start_time", 0 if chunk.start == MAXSIZE else chunk.start)
            header.set_time("end_time", chunk.end)
            header.set_uint32("count", len(chunk.connections))
            header.write(self.bio, RecordType.CHUNK_INFO)
            self.bio.write(serialize_uint32(len(chunk.connections) * 8))
            for cid, items in chunk.connections.items():
                self.bio.write(serialize_uint32(cid) + serialize_uint32(len(items)))
        _write_bag_header(self.bio, index_pos, len(self.connections), len(written))
        self.bio.close()
        self.bio = None
