"""THE detect loop: scans -> keypoints -> writer, with timings, progress and a clean stop.

``detect``, ``batch`` and ``view`` all run :func:`detect_recording`. Scans are handled in
chunks of consecutive scans of one geometry (at most ``chunk_scans``). With ``prefetch`` a
reader thread (:mod:`laser_corners.pipeline.prefetch`) reads and decodes the next chunks while
this thread detects: the numba kernels release the GIL, and so does the decompression of bag
chunks, so reading and detecting overlap. Detection then goes through
:meth:`~laser_corners.CornerDetector.detect_many` in blocks of :data:`BLOCK_SCANS` scans (one
GIL release per block; the same keypoints as :meth:`~laser_corners.CornerDetector.detect`);
with more numba threads through ``detect_many`` per chunk (parallel over scans); with one
thread and no reader thread, scan by scan through ``detect``.

The time of each phase is recorded (:class:`RunSummary`): ``read_seconds`` (waiting for
scans: all of the reading without ``prefetch``, the part the reader thread could not hide
with it), ``detect_seconds``, ``write_seconds`` and ``reader_seconds`` (the reader thread's
own time). Ctrl-C, a read error or a writer error stop the loop; the writer is closed either
way (so what was written stays readable) and ``interrupted``/``position`` say how far it got.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass, field
from typing import Any

from laser_corners.detector import CornerDetector
from laser_corners.io import KeypointWriter
from laser_corners.keypoints import Keypoints
from laser_corners.pipeline.interrupt import stop_requests
from laser_corners.pipeline.prefetch import Chunk, chunked, prefetched
from laser_corners.pipeline.recording import Recording
from laser_corners.scan import LaserScan

__all__ = ["CHUNK_SCANS", "RunSummary", "detect_recording", "set_threads", "warm_up"]

CHUNK_SCANS = 256
"""Most scans read, detected and written at a time."""
PREFETCH_CHUNKS = 4
"""Chunks the reader thread may read ahead."""
BLOCK_SCANS = 32
"""Scans per ``detect_many`` call (at most this much work is lost to Ctrl-C)."""
# numba's fallback threading layer (workqueue) must not be entered by two threads at once;
# Dask workers may run several jobs in threads of one process
_PARALLEL_KERNEL_LOCK = threading.Lock()
_KERNELS_READY: set[int] = set()  # numba thread counts whose kernels this process has loaded


@dataclass
class RunSummary:
    """What a run of :func:`detect_recording` did.

    Attributes
    ----------
    n_scans, n_keypoints : int
        Scans processed and keypoints found (and handed to the writer).
    seconds : float
        Wall time of the loop (closing the writer included).
    read_seconds, detect_seconds, write_seconds : float
        Time this thread spent waiting for scans, detecting, and writing (closing included).
    reader_seconds : float
        Time the reader thread spent reading (``prefetch``; it overlaps the others).
    cpu_seconds, reader_cpu_seconds : float
        CPU time of this thread in the loop, and of the reader thread: with ``prefetch`` the
        loop cannot run faster than ``n_scans / max(cpu_seconds, reader_cpu_seconds)`` even
        on idle cores (an upper bound: the Python parts of both threads share the GIL).
    skipped : dict of str to int
        Bad records skipped, by reason.
    skip_examples : list of str
        Where the first skips happened.
    interrupted : bool
        Stopped by Ctrl-C (the exception is not re-raised).
    position : str
        Where reading stopped: the last scan processed (``"message 1200 of /scan"``,
        ``"line 345"``).
    """

    n_scans: int = 0
    n_keypoints: int = 0
    seconds: float = 0.0
    read_seconds: float = 0.0
    detect_seconds: float = 0.0
    write_seconds: float = 0.0
    reader_seconds: float = 0.0
    cpu_seconds: float = 0.0
    reader_cpu_seconds: float = 0.0
    skipped: dict[str, int] = field(default_factory=dict)
    skip_examples: list[str] = field(default_factory=list)
    interrupted: bool = False
    position: str = "start"

    @property
    def keypoints_per_scan(self) -> float:
        """Mean keypoints per scan (0 without scans)."""
        return self.n_keypoints / self.n_scans if self.n_scans else 0.0

    @property
    def scans_per_second(self) -> float:
        """Processing rate."""
        return self.n_scans / self.seconds if self.seconds > 0 else 0.0


def set_threads(threads: int | None) -> int:
    """Limit numba's threads (in this thread); returns the number in use."""
    import numba

    if threads is not None:
        numba.set_num_threads(max(1, min(int(threads), numba.config.NUMBA_NUM_THREADS)))
    return int(numba.get_num_threads())


def warm_up(detector: CornerDetector, scan: LaserScan, threads: int = 1) -> float:
    """Load (or compile) the kernels ``detect_recording`` will call; seconds it took.

    Done once per process and thread count (0.0 afterwards), so callers can time it apart.
    """
    if threads in _KERNELS_READY:
        return 0.0
    start = time.perf_counter()
    detector.detect(scan)
    if threads > 1:
        with _PARALLEL_KERNEL_LOCK:
            detector.detect_many([scan, scan])
    _KERNELS_READY.add(threads)
    return time.perf_counter() - start


def _detect_chunk(
    detector: CornerDetector, scans: list[LaserScan], block: int, found: list[Keypoints]
) -> None:
    """Append the keypoints of each scan to ``found``.

    ``block`` 0: scan by scan through ``detect``; else through ``detect_many`` in blocks of
    ``block`` scans (one GIL release per block instead of several per scan, which matters when
    a reader thread wants the GIL). Ctrl-C keeps the scans (blocks) done.
    """
    if not block or len(scans) == 1:
        for scan in scans:
            found.append(detector.detect(scan))
        return
    for start in range(0, len(scans), block):
        part = scans[start : start + block]
        with _PARALLEL_KERNEL_LOCK:
            found.extend(
                detector.detect_many(part) if len(part) > 1 else [detector.detect(part[0])]
            )


def _write_chunk(writer: KeypointWriter, chunk: Chunk, found: list[Keypoints]) -> None:
    first = chunk.indices[0]
    if chunk.indices[-1] - first == len(chunk.indices) - 1:  # consecutive: one block
        writer.write_many(first, chunk.scans, found)
    else:
        for index, scan, keypoints in zip(chunk.indices, chunk.scans, found, strict=True):
            writer.write(index, scan, keypoints)


def detect_recording(
    source: Recording | Iterable[LaserScan],
    detector: CornerDetector | None = None,
    writer: KeypointWriter | None = None,
    progress: Callable[[RunSummary], None] | None = None,
    every: int = 25,
    *,
    threads: int | None = 1,
    chunk_scans: int = CHUNK_SCANS,
    prefetch: bool = True,
    step: int = 1,
    max_scans: int | None = None,
) -> RunSummary:
    """Detect keypoints in every scan of ``source`` and hand them to ``writer``.

    Parameters
    ----------
    source : Recording or iterable of LaserScan
        An opened :class:`~laser_corners.pipeline.Recording` (its first scan is not read
        twice), a :class:`~laser_corners.io.ScanSource`, or any iterable of scans.
    detector : CornerDetector, optional
        The detector (default: the recording's).
    writer : KeypointWriter, optional
        Where keypoints go (default: nowhere); closed before returning, also on errors and
        Ctrl-C.
    progress : callable, optional
        Called with the running summary after a chunk once ``every`` more scans are done, and
        at the end.
    every : int
        Progress period in scans.
    threads : int, optional
        numba threads of this thread during the loop (restored after); None: leave numba's
        setting. With 1 and no ``prefetch`` scans go one by one through ``detect``;
        otherwise through ``detect_many`` in blocks (parallel over scans with more threads).
    chunk_scans : int
        Most scans per chunk.
    prefetch : bool
        Read in a separate thread, overlapping the kernels.
    step : int
        Detect only every ``step``-th scan (indices keep counting every scan).
    max_scans : int, optional
        Stop after this many scans detected.

    Returns
    -------
    RunSummary
        ``interrupted`` is True after Ctrl-C (the exception is not re-raised).

    Raises
    ------
    InputError
        A read error in the middle of the recording (after closing the writer; the scans read
        before it are written).
    """
    if detector is None:
        if not isinstance(source, Recording):
            raise TypeError("detect_recording needs a detector unless given a Recording")
        detector = source.detector
    writer = writer if writer is not None else KeypointWriter()
    holder, chunks = _chunks(source, chunk_scans, step, max_scans)
    summary = RunSummary()
    report = progress or (lambda _: None)
    start, cpu_start = time.perf_counter(), time.thread_time()
    previous = set_threads(None)
    n_threads = set_threads(threads)
    reader = prefetched(chunks, PREFETCH_CHUNKS) if prefetch else None
    stream: Iterator[Chunk] = iter(reader) if reader is not None else chunks
    try:
        block = _block_scans(n_threads, chunk_scans, prefetch)
        with stop_requests() as stop:
            _run(stream, detector, writer, summary, report, every, block, start, stop)
    except KeyboardInterrupt:
        _interrupted(summary, writer)
    finally:
        _stop_reading(reader, chunks, summary)
        set_threads(previous)
        _close_writer(writer, summary)
        _totals(summary, holder, start, cpu_start)
    report(summary)
    return summary


def _chunks(
    source: Recording | Iterable[LaserScan], chunk_scans: int, step: int, max_scans: int | None
) -> tuple[Any, Iterator[Chunk]]:
    """The object that counts skipped messages, and the chunks of scans to detect in."""
    holder: Any = source.source if isinstance(source, Recording) else source
    scans = source.scans() if isinstance(source, Recording) else iter(source)
    return holder, chunked(scans, holder, max(1, chunk_scans), max(1, step), max_scans)


def _block_scans(n_threads: int, chunk_scans: int, prefetch: bool) -> int:
    """Scans per ``detect_many`` call (0: scan by scan with ``detect``).

    Several numba threads: whole chunks (a parallel launch per block costs); one thread and
    a reader thread: blocks; one thread alone: scan by scan.
    """
    return max(1, chunk_scans) if n_threads > 1 else (BLOCK_SCANS if prefetch else 0)


def _interrupted(summary: RunSummary, writer: KeypointWriter) -> None:
    """Mark the run interrupted; after Ctrl-C inside a chunk's writing, the writer knows how
    many of its scans it took."""
    summary.interrupted = True
    written = getattr(writer, "n_scans", 0)
    if written > summary.n_scans:
        summary.n_scans = written
        summary.n_keypoints = getattr(writer, "n_keypoints", summary.n_keypoints)


def _stop_reading(reader: Any, chunks: Any, summary: RunSummary) -> None:
    """Stop the reader thread (its times into ``summary``), or close the chunk generator."""
    if reader is not None:
        reader.stop()
        summary.reader_seconds = reader.busy_seconds
        summary.reader_cpu_seconds = reader.cpu_seconds
    else:
        chunks.close()


def _totals(summary: RunSummary, holder: Any, start: float, cpu_start: float) -> None:
    """The run's wall and CPU time, and the messages the source skipped."""
    summary.seconds = time.perf_counter() - start
    summary.cpu_seconds = time.thread_time() - cpu_start
    summary.skipped = dict(getattr(holder, "skipped", {}))
    summary.skip_examples = list(getattr(holder, "skip_examples", []))


def _close_writer(writer: KeypointWriter, summary: RunSummary) -> None:
    """Close the writer, its time counted as writing."""
    t0 = time.perf_counter()
    writer.close()
    summary.write_seconds += time.perf_counter() - t0


def _run(
    stream: Iterator[Chunk],
    detector: CornerDetector,
    writer: KeypointWriter,
    summary: RunSummary,
    report: Callable[[RunSummary], None],
    every: int,
    block: int,
    start: float,
    stop: threading.Event,
) -> None:
    reported = 0
    while True:
        if stop.is_set():  # Ctrl-C (pipeline.interrupt): stop before the next chunk
            raise KeyboardInterrupt
        t0 = time.perf_counter()
        chunk = next(stream, None)
        t1 = time.perf_counter()
        summary.read_seconds += t1 - t0
        if chunk is None:
            return
        found: list[Keypoints] = []
        try:
            _detect_chunk(detector, chunk.scans, block, found)
        except KeyboardInterrupt:  # keep the scans of the chunk done so far
            if found:
                _finish_chunk(writer, chunk.head(len(found)), found, summary)
            raise
        t2 = time.perf_counter()
        summary.detect_seconds += t2 - t1
        _finish_chunk(writer, chunk, found, summary)
        summary.write_seconds += time.perf_counter() - t2
        if summary.n_scans - reported >= every:
            reported = summary.n_scans
            summary.seconds = time.perf_counter() - start
            report(summary)


def _finish_chunk(
    writer: KeypointWriter, chunk: Chunk, found: list[Keypoints], summary: RunSummary
) -> None:
    """Hand a detected chunk to the writer and count it."""
    _write_chunk(writer, chunk, found)
    summary.n_scans += len(chunk.scans)
    summary.n_keypoints += sum(len(k) for k in found)
    summary.position = chunk.position
