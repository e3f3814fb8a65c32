"""Chunks of scans, and a reader thread that reads them ahead of the detector.

:func:`chunked` groups consecutive scans of one geometry (what ``detect_many`` needs) and
records, per chunk, where the reader stood after its last scan, so messages about an
interruption name the last scan *processed*, not the last one read ahead. :func:`prefetched`
runs such a chunk iterator in a daemon thread behind a bounded queue: reading (bag chunk
decompression, which releases the GIL, message decoding, poses) overlaps the numba kernels,
which release the GIL too. An exception of the reader (a damaged file, a KeyboardInterrupt
raised by a source) is handed over in order, after the chunks read before it.
"""

from __future__ import annotations

import queue
import threading
import time
from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any

from laser_corners.scan import LaserScan

__all__ = ["Chunk", "Prefetcher", "chunked", "prefetched", "same_geometry"]


@dataclass
class Chunk:
    """Consecutive scans of one geometry.

    Attributes
    ----------
    indices : list of int
        Index of each scan in the recording.
    scans : list of LaserScan
        The scans.
    positions : list of str
        Where the reader stood after each scan (``ScanSource.position``).
    """

    indices: list[int]
    scans: list[LaserScan]
    positions: list[str]

    @property
    def position(self) -> str:
        """Where the reader stood after the last scan."""
        return self.positions[-1]

    def head(self, count: int) -> Chunk:
        """The first ``count`` scans of the chunk."""
        return Chunk(self.indices[:count], self.scans[:count], self.positions[:count])


def same_geometry(a: LaserScan, b: LaserScan) -> bool:
    """Whether two scans can go through one ``detect_many`` call."""
    return a.geometry == b.geometry


def chunked(
    scans: Iterator[LaserScan],
    holder: Any,
    size: int,
    step: int = 1,
    max_scans: int | None = None,
) -> Iterator[Chunk]:
    """Chunks of at most ``size`` consecutive same-geometry scans of ``scans``.

    ``holder`` is the source whose ``position`` is recorded (any object; without a
    ``position`` the scan index is used). Only every ``step``-th scan is kept, and at most
    ``max_scans`` in all. When reading fails (or is interrupted) the scans read so far are
    yielded first, then the exception propagates.
    """
    indices: list[int] = []
    batch: list[LaserScan] = []
    positions: list[str] = []
    kept = 0
    try:
        for index, scan in enumerate(scans):
            if index % step:
                continue
            if max_scans is not None and kept >= max_scans:
                break
            if batch and (len(batch) >= size or not same_geometry(scan, batch[0])):
                yield Chunk(indices, batch, positions)
                indices, batch, positions = [], [], []
            indices.append(index)
            batch.append(scan)
            kept += 1
            positions.append(getattr(holder, "position", None) or f"scan {index}")
    except GeneratorExit:
        raise
    except BaseException:
        if batch:
            yield Chunk(indices, batch, positions)
        raise
    finally:
        close = getattr(scans, "close", None)
        if close is not None:
            close()
    if batch:
        yield Chunk(indices, batch, positions)


@dataclass
class _Failed:
    error: BaseException


_END = object()


class Prefetcher:
    """Runs a chunk iterator in a daemon thread, at most ``depth`` chunks ahead.

    Iterate it for the chunks (in order); call :meth:`stop` when done (also after an error
    or Ctrl-C): it tells the thread to stop, closes the iterator in that thread and waits
    for it.

    Attributes
    ----------
    busy_seconds : float
        Time the thread spent producing chunks.
    cpu_seconds : float
        CPU time of the thread (``time.thread_time``).
    """

    def __init__(self, chunks: Iterator[Chunk], depth: int = 4) -> None:
        self._chunks = chunks
        self._queue: queue.Queue[Any] = queue.Queue(maxsize=max(1, depth))
        self._stop = threading.Event()
        self.busy_seconds = 0.0
        self.cpu_seconds = 0.0
        self._thread = threading.Thread(target=self._run, name="laser-corners-reader", daemon=True)
        self._thread.start()

    def _put(self, item: Any) -> bool:
        while not self._stop.is_set():
            try:
                self._queue.put(item, timeout=0.05)
                return True
            except queue.Full:
                continue
        return False

    def _run(self) -> None:
        cpu_start = time.thread_time()
        try:
            while not self._stop.is_set():
                start = time.perf_counter()
                try:
                    item: Any = next(self._chunks)
                except StopIteration:
                    item = _END
                except BaseException as exc:  # handed to the consumer, raised there
                    item = _Failed(exc)
                self.busy_seconds += time.perf_counter() - start
                if not self._put(item) or item is _END or isinstance(item, _Failed):
                    return
        finally:
            self._chunks.close()  # type: ignore[attr-defined]
            self.cpu_seconds = time.thread_time() - cpu_start

    def __iter__(self) -> Iterator[Chunk]:
        while True:
            item = self._queue.get()
            if item is _END:
                return
            if isinstance(item, _Failed):
                raise item.error
            yield item

    def stop(self, timeout: float = 10.0) -> None:
        """Stop the thread (it finishes the chunk it is reading) and wait for it."""
        self._stop.set()
        while True:  # unblock a thread waiting to put
            try:
                self._queue.get_nowait()
            except queue.Empty:
                break
        self._thread.join(timeout)


def prefetched(chunks: Iterator[Chunk], depth: int = 4) -> Prefetcher:
    """Start reading ``chunks`` in a thread (see :class:`Prefetcher`)."""
    return Prefetcher(chunks, depth)
