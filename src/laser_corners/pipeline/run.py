"""A whole recording to a keypoint file in one call (what ``laser-corners detect`` runs).

:func:`detect_file` opens the recording (:func:`~laser_corners.pipeline.open_recording`),
opens the writer for ``output`` (CSV, Parquet, or a copy of the input bag with keypoint
topics; the resolved parameters go into its metadata and beside it as
``<output>.params.yaml``) and runs the detect loop. Ctrl-C at any point after the recording
is open ends in a :class:`DetectRun` with ``summary.interrupted`` set and the writer closed:
the output keeps the keypoints of the scans processed, or, when the interruption came while
the output was being created (a bag output copies the input first), it is removed.
"""

from __future__ import annotations

import shutil
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from laser_corners.citation import CITATION
from laser_corners.errors import InputError
from laser_corners.io import KeypointWriter, open_keypoint_writer
from laser_corners.params import DetectorParams
from laser_corners.pipeline.loop import RunSummary, detect_recording
from laser_corners.pipeline.recording import ParamsChoice, Recording, open_recording

__all__ = ["DetectRun", "detect_file"]


@dataclass
class DetectRun:
    """What :func:`detect_file` did.

    Attributes
    ----------
    recording : Recording
        The opened recording (source, parameters, description).
    output : Path or None
        The keypoint file (None: nothing written).
    summary : RunSummary
        Counts, timings, skips, interruption.
    """

    recording: Recording
    output: Path | None
    summary: RunSummary
    removed: bool = False

    @property
    def kept(self) -> str:
        """What the output holds after an interruption, in words ("" without an output)."""
        if self.output is None:
            return ""
        if self.removed:
            return (
                f"{self.output} removed: interrupted while it was being created, before any "
                "keypoint was written"
            )
        if not self.output.exists():
            return f"{self.output} was not created"
        return (
            f"{self.output} keeps what was written: the keypoints of the "
            f"{self.summary.n_scans} scans processed"
        )


def _remove(path: Path) -> None:
    if path.is_dir():
        shutil.rmtree(path, ignore_errors=True)  # a ROS 2 bag output is a folder
    else:
        path.unlink(missing_ok=True)


def _open_writer(
    recording: Recording, out: Path | None, path: str | Path, compression: str | None
) -> KeypointWriter:
    """The keypoint writer of ``out`` (a null writer for None), the parameters recorded in
    its metadata and beside it; Ctrl-C meanwhile closes what was opened and re-raises."""
    params_yaml = recording.params.to_yaml()
    writer = open_keypoint_writer(
        out,
        recording.source,
        with_map=recording.has_poses,
        metadata={
            "laser_corners.params": params_yaml,
            "laser_corners.input": str(path),
            "laser_corners.method": CITATION,
        },
        compression=compression,
    )
    try:
        if out is not None:
            Path(f"{out}.params.yaml").write_text(params_yaml, encoding="utf-8")
    except KeyboardInterrupt:
        writer.close()
        raise
    return writer


def detect_file(
    path: str | Path,
    output: str | Path | None = None,
    *,
    topic: str | None = None,
    params: ParamsChoice | DetectorParams | None = None,
    on_open: Callable[[Recording], None] | None = None,
    progress: Callable[[RunSummary], None] | None = None,
    threads: int = 1,
    compression: str | None = None,
    odom_topic: str | None = None,
) -> DetectRun:
    """Detect keypoints in every scan of ``path`` and write them to ``output``.

    Parameters
    ----------
    path : str or Path
        The recording.
    output : str or Path, optional
        ``.csv``, ``.parquet``, ``.bag`` or ``.mcap`` (see
        :func:`laser_corners.io.open_keypoint_writer`); None: count only.
    topic : str, optional
        LaserScan topic of a bag.
    params : ParamsChoice or DetectorParams, optional
        Parameter choice (default: the ``paper`` preset).
    on_open : callable, optional
        Called with the :class:`Recording` once it is open (before the writer).
    progress : callable, optional
        Progress hook of :func:`~laser_corners.pipeline.detect_recording`.
    threads : int
        numba threads (see :func:`~laser_corners.pipeline.detect_recording`).
    compression : {"lz4", "bz2", "none"}, optional
        Chunk compression of a ``.bag`` output (default
        :data:`~laser_corners.io.bagwriter.BAG_COMPRESSION`).
    odom_topic : str, optional
        Odometry of a bag (map-frame columns): an Odometry topic or ``"tf"``.

    Returns
    -------
    DetectRun

    Raises
    ------
    InputError, InvalidParamsError, OutputError
        The recording cannot be read, the parameters are invalid, the output cannot be written.
        Damage found after scans were written ends in an ``InputError`` that says what the
        output keeps (it is kept, complete up to the damage, under its final name).
    """
    recording = open_recording(path, topic, params, odom_topic=odom_topic)
    if on_open is not None:
        on_open(recording)
    out = Path(output) if output is not None else None
    start = time.perf_counter()
    try:
        writer = _open_writer(recording, out, path, compression)
    except KeyboardInterrupt:  # while the writer was opening (a bag copy takes a while)
        if out is not None:  # an incomplete copy without keypoints: not worth keeping
            _remove(out)
            Path(f"{out}.params.yaml").unlink(missing_ok=True)
        summary = RunSummary(interrupted=True, seconds=time.perf_counter() - start)
        return DetectRun(recording, out, summary, removed=out is not None)
    try:
        summary = detect_recording(recording, writer=writer, progress=progress, threads=threads)
    except InputError as exc:  # damage mid-file: the writer was closed, its output kept
        if out is None:
            raise
        kept = writer.summary()
        raise InputError(
            f"{exc}; {kept.path} is incomplete: it keeps the {kept.n_keypoints} keypoints of "
            f"the {kept.n_scans} scans read before the error"
        ) from None
    return DetectRun(recording, out, summary)
