"""Chunks of scans and the reader thread (:mod:`laser_corners.pipeline.prefetch`): chunks keep
one geometry and the reader's position, a reading error comes after the scans read before it,
and the thread stops and closes its iterator."""

from __future__ import annotations

import math
from collections.abc import Iterator

import numpy as np
import pytest

from laser_corners.errors import InputError
from laser_corners.pipeline.prefetch import chunked, prefetched, same_geometry
from laser_corners.scan import LaserScan


def scan(n_beams: int = 10) -> LaserScan:
    return LaserScan(np.ones(n_beams), -0.5, 1.0 / n_beams, 0.05, 10.0)


class Source:
    """Yields scans of the given beam counts, recording its position; may fail at the end."""

    def __init__(self, beams: list[int], error: BaseException | None = None) -> None:
        self.beams, self.error = beams, error
        self.position = ""
        self.closed = False

    def scans(self) -> Iterator[LaserScan]:
        try:
            for i, n in enumerate(self.beams):
                self.position = f"message {i}"
                yield scan(n)
            if self.error is not None:
                raise self.error
        finally:
            self.closed = True


def test_chunks_keep_one_geometry_and_at_most_size_scans() -> None:
    source = Source([10, 10, 10, 20, 20, 10])
    chunks = list(chunked(source.scans(), source, size=2))
    assert [c.indices for c in chunks] == [[0, 1], [2], [3, 4], [5]]
    assert all(same_geometry(c.scans[0], s) for c in chunks for s in c.scans)
    assert not same_geometry(scan(10), scan(20))
    assert [c.position for c in chunks] == ["message 1", "message 2", "message 4", "message 5"]
    assert chunks[0].head(1).indices == [0] and chunks[0].head(1).positions == ["message 0"]
    assert source.closed


def test_step_and_max_scans_and_a_holder_without_position() -> None:
    source = Source([10] * 9)
    chunks = list(chunked(source.scans(), object(), size=10, step=2, max_scans=3))
    assert [c.indices for c in chunks] == [[0, 2, 4]]
    assert chunks[0].positions == ["scan 0", "scan 2", "scan 4"]
    assert source.closed  # stopped early: the scan iterator is closed


def test_a_reading_error_comes_after_the_scans_read_before_it() -> None:
    source = Source([10, 10, 10], error=InputError("a.bag: truncated"))
    chunks = chunked(source.scans(), source, size=2)
    assert next(chunks).indices == [0, 1]
    assert next(chunks).indices == [2]  # the partial chunk first
    with pytest.raises(InputError, match="truncated"):
        next(chunks)


def test_the_reader_thread_hands_over_chunks_then_the_error_in_order() -> None:
    source = Source([10] * 5, error=KeyboardInterrupt())
    reader = prefetched(chunked(source.scans(), source, size=2), depth=1)
    seen = []
    with pytest.raises(KeyboardInterrupt):
        for chunk in reader:
            seen.append(chunk.indices)
    reader.stop()
    assert seen == [[0, 1], [2, 3], [4]]
    assert source.closed and reader.busy_seconds >= 0.0 and reader.cpu_seconds >= 0.0


def test_stop_ends_a_reader_blocked_on_a_full_queue_and_closes_its_iterator() -> None:
    source = Source([10] * 1000)
    reader = prefetched(chunked(source.scans(), source, size=1), depth=2)
    first = next(iter(reader))
    assert first.indices == [0]
    reader.stop(timeout=5.0)
    assert not reader._thread.is_alive()
    assert source.closed and not math.isnan(reader.cpu_seconds)
