"""One job, as a worker runs it: open, detect (the pipeline's loop), write Parquet, rename.

Also the worker processes' initializer: on Linux a worker asks the kernel to kill it when its
parent dies (``prctl(PR_SET_PDEATHSIG, SIGKILL)``), elsewhere a watchdog thread polls the
parent's process id, so a batch killed with SIGKILL leaves no worker running.
"""

from __future__ import annotations

import contextlib
import os
import signal
import sys
import threading
import time
import traceback
from pathlib import Path
from typing import Any

from laser_corners.batch.manifest import PARTIAL_SUFFIX, BatchJob, JobResult
from laser_corners.citation import CITATION
from laser_corners.errors import LaserCornersError, first_line
from laser_corners.io import KeypointWriter
from laser_corners.io.base import PartialOutput
from laser_corners.io.writers import ParquetKeypointWriter
from laser_corners.params import DetectorParams
from laser_corners.pipeline import (
    ParamsChoice,
    Recording,
    detect_recording,
    open_recording,
    set_threads,
    warm_up,
)

__all__ = ["die_with_parent", "failed_result", "run_job", "run_pooled_job", "start_pool_worker"]

_PR_SET_PDEATHSIG = 1


def _watch_parent(parent: int, period: float = 0.5) -> None:
    while os.getppid() == parent:
        time.sleep(period)
    os.kill(os.getpid(), signal.SIGKILL)


_stopping: Any = None  # the pool's "stop" event, in a pool worker (start_pool_worker)


def start_pool_worker(parent: int, stopping: Any = None) -> None:
    """Initializer of a pool worker: it dies with ``parent``, and Ctrl-C reaches it only while
    it runs a job (:func:`run_pooled_job`). An idle worker that took Ctrl-C while reading the
    pool's call queue died holding the queue's lock, and the other workers and the pool's
    shutdown then waited on it for ever (seen once in a full test run). ``stopping`` (a
    multiprocessing event the batch sets on Ctrl-C) stops a job handed out as the Ctrl-C
    came, which the idle worker ignored, before it starts."""
    global _stopping
    die_with_parent(parent)
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    _stopping = stopping


def run_pooled_job(*args: object) -> JobResult:
    """:func:`run_job` in a pool worker, with Ctrl-C stopping it (ignored again after)."""
    signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        if _stopping is not None and _stopping.is_set():
            raise KeyboardInterrupt  # the batch was stopped as this job was handed out
        return run_job(*args)  # type: ignore[arg-type]
    finally:
        signal.signal(signal.SIGINT, signal.SIG_IGN)


def die_with_parent(parent: int | None = None) -> None:
    """Make this process die when its parent process dies (a worker initializer).

    Parameters
    ----------
    parent : int, optional
        The parent's process id (default: the current one). If the parent is already gone,
        the process ends at once.
    """
    parent = os.getppid() if parent is None else parent
    armed = False
    if sys.platform.startswith("linux"):
        try:
            import ctypes

            libc = ctypes.CDLL(None, use_errno=True)
            armed = libc.prctl(_PR_SET_PDEATHSIG, signal.SIGKILL, 0, 0, 0) == 0
        except (OSError, AttributeError):
            armed = False
    if os.getppid() != parent:  # the parent died before the signal was armed
        os.kill(os.getpid(), signal.SIGKILL)
    if not armed:
        threading.Thread(
            target=_watch_parent, args=(parent,), name="laser-corners-parent-watch", daemon=True
        ).start()


def _worker_name() -> str:
    import socket

    return f"{socket.gethostname()}:{os.getpid()}"


def _open_writer(recording: Recording, partial: Path, job: BatchJob) -> KeypointWriter:
    # the Parquet writer by name: the partial file's suffix is not ".parquet"
    return ParquetKeypointWriter(
        partial,
        recording.has_poses,
        metadata={
            "laser_corners.params": recording.params.to_yaml(),
            "laser_corners.method": CITATION,
            "laser_corners.input": job.input,
            "laser_corners.topic": job.topic or "",
        },
    )


def _abandon(writer: KeypointWriter, output: PartialOutput) -> None:
    """Close the writer of a stopped or failed job and remove its partial output, even when
    closing fails: a writer stopped mid-write (Ctrl-C inside a flush) may raise on close, and
    the partial file must go all the same."""
    try:
        with contextlib.suppress(Exception):  # its file is removed below: nothing is kept
            writer.close()
    finally:  # also on a second Ctrl-C during the close
        output.discard()


def run_job(
    job: BatchJob,
    outdir: str | Path,
    params: ParamsChoice | DetectorParams | None = None,
    threads: int | None = 1,
    prefetch: bool = True,
    publish: bool = True,
) -> JobResult:
    """Detect keypoints in every scan of one job's recording and write its Parquet file.

    The output is written to ``<name>.parquet.partial`` and renamed to ``<name>.parquet`` when
    complete (with ``publish``; the batch's executors leave the rename to
    :meth:`~laser_corners.batch.manifest.Manifest.record`, which records the job with it). Known
    errors (:class:`~laser_corners.errors.LaserCornersError`, such as a damaged file) and
    unexpected ones give a ``failed`` result instead of raising; the traceback of an
    unexpected one goes to ``errors/<name>.txt``. Ctrl-C removes the partial file and
    propagates.

    Parameters
    ----------
    job : BatchJob
        The job.
    outdir : str or Path
        Output folder (on a remote cluster: a path the worker can write).
    params : ParamsChoice or DetectorParams, optional
        Parameters (default: the paper's).
    threads : int, optional
        numba threads for this worker: 1 detects scan by scan, more runs the parallel
        :meth:`~laser_corners.CornerDetector.detect_many` over chunks of one geometry. None:
        leave numba's setting.
    prefetch : bool
        Read in a thread of its own while detecting (see :mod:`laser_corners.pipeline`).
    publish : bool
        Rename the output; with False a ``done`` job leaves it ``<name>.parquet.partial``.

    Returns
    -------
    JobResult
    """
    start = time.perf_counter()
    outdir = Path(outdir)
    partial = outdir / (job.output + PARTIAL_SUFFIX)  # fixed: a re-run replaces a leftover
    output = PartialOutput(outdir / job.output, overwrite=True, create=False, temporary=partial)
    result = JobResult(job.input, job.topic, job.output, "failed", worker=_worker_name())
    n_threads = set_threads(threads)
    writer = KeypointWriter()
    recording: Recording | None = None
    try:
        output.discard()  # a leftover of an interrupted run
        recording = open_recording(job.input, job.topic, params, odom_topic=job.odom_topic)
        result.read_seconds = time.perf_counter() - start
        result.startup_seconds = warm_up(recording.detector, recording.first, n_threads)
        writer = _open_writer(recording, partial, job)
        summary = detect_recording(recording, writer=writer, threads=n_threads, prefetch=prefetch)
        if summary.interrupted:
            raise KeyboardInterrupt
        result.read_seconds += summary.read_seconds
        result.detect_seconds = summary.detect_seconds
        result.write_seconds = summary.write_seconds
        result.reader_seconds = summary.reader_seconds
        if publish:
            output.publish()
        result.status = "done"
    except KeyboardInterrupt:
        _abandon(writer, output)
        raise
    except LaserCornersError as exc:
        _abandon(writer, output)
        result.error = first_line(exc)
    except Exception as exc:  # a surprise: keep the traceback next to the results
        _abandon(writer, output)
        result.error = f"{type(exc).__name__}: {first_line(exc)} (traceback in errors/)"
        errors = outdir / "errors"
        errors.mkdir(exist_ok=True)
        (errors / f"{job.output}.txt").write_text(traceback.format_exc(), encoding="utf-8")
    result.scans = writer.n_scans
    result.keypoints = writer.n_keypoints
    result.skipped = sum(recording.source.skipped.values()) if recording is not None else 0
    result.seconds = time.perf_counter() - start
    return result


def failed_result(job: BatchJob, exc: BaseException) -> JobResult:
    """The result of a job whose worker failed before returning one (crash, lost worker)."""
    return JobResult(
        job.input,
        job.topic,
        job.output,
        "failed",
        error=f"worker failed: {type(exc).__name__}: {first_line(exc)}",
    )
