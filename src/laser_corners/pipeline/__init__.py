"""The pipeline layer: open a recording, resolve its parameters, run THE detect loop.

Between the core (detector, parameters, presets) and the front ends (CLI, batch, viewer,
evaluation): a command parses its options, makes one call here and presents the result.

* :func:`open_recording` opens any recording :func:`laser_corners.io.open_scans` reads, reads
  its first scan and resolves a :class:`ParamsChoice` (preset or parameter file, plus
  overrides) against it: a :class:`Recording`.
* :func:`detect_recording` is the detect loop (chunks, numba threads, a reader thread, timings
  per phase, progress, Ctrl-C): a :class:`RunSummary`.

Examples
--------
>>> from laser_corners.pipeline import ParamsChoice, detect_recording, open_recording
>>> recording = open_recording("fr079.bag", params=ParamsChoice("auto"))  # doctest: +SKIP
>>> summary = detect_recording(recording)  # doctest: +SKIP
"""

from laser_corners.pipeline.loop import (
    CHUNK_SCANS,
    RunSummary,
    detect_recording,
    set_threads,
    warm_up,
)
from laser_corners.pipeline.prefetch import Chunk, chunked, prefetched, same_geometry
from laser_corners.pipeline.recording import (
    ParamsChoice,
    Recording,
    as_choice,
    laser_topic_sources,
    laser_topics,
    no_scan_error,
    open_recording,
    scan_at,
)
from laser_corners.pipeline.run import DetectRun, detect_file

__all__ = [
    "CHUNK_SCANS",
    "Chunk",
    "DetectRun",
    "ParamsChoice",
    "Recording",
    "RunSummary",
    "as_choice",
    "chunked",
    "detect_file",
    "detect_recording",
    "laser_topic_sources",
    "laser_topics",
    "no_scan_error",
    "open_recording",
    "prefetched",
    "same_geometry",
    "scan_at",
    "set_threads",
    "warm_up",
]
