"""Jobs, their results and the manifest that records them (``manifest.jsonl``).

A :class:`BatchJob` is one recording (one LaserScan topic of a bag) -> one Parquet file; a
:class:`JobResult` is one manifest record; :class:`Manifest` is the append-only record of the
output folder (flushed and synced per result, so a killed run loses no finished job).
"""

from __future__ import annotations

import json
import os
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any, Literal

from laser_corners.io.partial import PARTIAL_SUFFIX  # re-exported: batch's temporary names

__all__ = [
    "MANIFEST_NAME",
    "PARAMS_NAME",
    "PARTIAL_SUFFIX",
    "BatchJob",
    "BatchReport",
    "JobResult",
    "Manifest",
    "SkippedInput",
]

MANIFEST_NAME = "manifest.jsonl"
"""File name of the manifest in the output folder."""
PARAMS_NAME = "batch-params.yaml"
"""File name of the parameter choice recorded in the output folder."""

Status = Literal["done", "failed"]


@dataclass(frozen=True)
class SkippedInput:
    """An input that is not a recording (a ``.relations`` file, a README): skipped.

    Attributes
    ----------
    input : str
        The path as given.
    reason : str
        One line saying why.
    """

    input: str
    reason: str


@dataclass(frozen=True)
class BatchJob:
    """One unit of work: a recording (and, for bags, a LaserScan topic) -> one Parquet file.

    Attributes
    ----------
    input : str
        Absolute path of the recording.
    topic : str or None
        The LaserScan topic (bags only; None: the only one).
    output : str
        File name of the result inside the output folder.
    size : int
        Size of the input in bytes (larger jobs are started first).
    odom_topic : str or None
        The odometry of a bag (``nav_msgs/Odometry`` topic or ``"tf"``; None: the only one).
    """

    input: str
    topic: str | None
    output: str
    size: int = 0
    odom_topic: str | None = None

    @property
    def key(self) -> str:
        """Identity of the job in the manifest: the input path, plus ``#topic`` for bags."""
        return self.input + (f"#{self.topic}" if self.topic else "")


@dataclass
class JobResult:
    """What one job did (one manifest record).

    Attributes
    ----------
    input, topic, output : str, str or None, str
        As in :class:`BatchJob`.
    status : {"done", "failed"}
        ``done``: the output is complete; ``failed``: see ``error``.
    scans, keypoints, skipped : int
        Scans processed, keypoints written, bad records the reader skipped.
    seconds : float
        Wall time of the job in its worker.
    read_seconds, detect_seconds, write_seconds : float
        The part of ``seconds`` spent reading scans, detecting keypoints and writing them.
    startup_seconds : float
        The part of ``seconds`` spent loading (or compiling) the numba kernels, once per
        worker process: the first job of each worker pays it.
    reader_seconds : float
        Time the job's reader thread spent reading; it overlaps detection, and
        ``read_seconds`` is only the part it could not hide.
    error : str
        One line saying why the job failed ("" when done).
    worker : str
        Host and process id of the worker that ran the job.
    """

    input: str
    topic: str | None
    output: str
    status: Status
    scans: int = 0
    keypoints: int = 0
    skipped: int = 0
    seconds: float = 0.0
    read_seconds: float = 0.0
    detect_seconds: float = 0.0
    write_seconds: float = 0.0
    startup_seconds: float = 0.0
    reader_seconds: float = 0.0
    error: str = ""
    worker: str = ""

    @property
    def key(self) -> str:
        """Same as :attr:`BatchJob.key`."""
        return self.input + (f"#{self.topic}" if self.topic else "")

    @property
    def scans_per_second(self) -> float:
        """Scans per second of the job, reading and writing included."""
        return self.scans / self.seconds if self.seconds > 0 else 0.0

    def to_record(self) -> dict[str, Any]:
        """The manifest record (JSON-friendly)."""
        record = asdict(self)
        for name in (
            "seconds",
            "read_seconds",
            "detect_seconds",
            "write_seconds",
            "startup_seconds",
            "reader_seconds",
        ):
            record[name] = round(record[name], 4)
        return record

    @classmethod
    def from_record(cls, record: dict[str, Any]) -> JobResult:
        """Inverse of :meth:`to_record` (unknown keys are ignored)."""
        names = cls.__dataclass_fields__.keys()
        return cls(**{k: v for k, v in record.items() if k in names})


@dataclass
class BatchReport:
    """What :func:`run_batch` did.

    Attributes
    ----------
    outdir : Path
        The output folder.
    results : list of JobResult
        The jobs run now, in the order they finished.
    already_done : list of JobResult
        The jobs skipped because the manifest records them as done.
    seconds : float
        Wall time of running the jobs (planning and start-up of workers included).
    workers : int
        Workers used (Dask: the cluster's workers when the run started).
    interrupted : bool
        Stopped by Ctrl-C; the manifest holds every job that finished before.
    skipped : list of SkippedInput
        Inputs that are not recordings (skipped, not failed).
    """

    outdir: Path
    results: list[JobResult] = field(default_factory=list)
    already_done: list[JobResult] = field(default_factory=list)
    seconds: float = 0.0
    workers: int = 1
    interrupted: bool = False
    skipped: list[SkippedInput] = field(default_factory=list)

    @property
    def failed(self) -> list[JobResult]:
        """The jobs of this run that failed."""
        return [r for r in self.results if r.status == "failed"]

    @property
    def n_scans(self) -> int:
        """Scans processed by the jobs of this run."""
        return sum(r.scans for r in self.results)

    @property
    def scans_per_second(self) -> float:
        """Scans of this run per second of wall time."""
        return self.n_scans / self.seconds if self.seconds > 0 else 0.0


class Manifest:
    """The append-only record of finished jobs (``manifest.jsonl``) of an output folder.

    Each line is one :meth:`JobResult.to_record`; for a job listed several times (failed
    first, done later) the last line wins. A torn last line (the process was killed while
    writing it) is ignored.
    """

    def __init__(self, outdir: Path) -> None:
        self.path = Path(outdir) / MANIFEST_NAME

    def load(self) -> dict[str, JobResult]:
        """The latest record of every job key."""
        records: dict[str, JobResult] = {}
        if not self.path.exists():
            return records
        with self.path.open(encoding="utf-8") as handle:
            for line in handle:
                try:
                    result = JobResult.from_record(json.loads(line))
                except (json.JSONDecodeError, TypeError):
                    continue  # torn or foreign line
                records[result.key] = result
        return records

    def append(self, result: JobResult) -> None:
        """Append one record and push it to disk (after a torn last line, on a new line)."""
        torn = False
        if self.path.exists() and self.path.stat().st_size > 0:
            with self.path.open("rb") as handle:
                handle.seek(-1, os.SEEK_END)
                torn = handle.read(1) != b"\n"
        with self.path.open("a", encoding="utf-8") as handle:
            handle.write(("\n" if torn else "") + json.dumps(result.to_record()) + "\n")
            handle.flush()
            os.fsync(handle.fileno())

    def record(self, result: JobResult) -> None:
        """Give a done job's output its final name, then append ``result``.

        Workers leave a finished job's output as ``NAME.parquet.partial``
        (:func:`~laser_corners.batch.worker.run_job` with ``publish=False``); the batch renames
        it here, as it records the job (with Ctrl-C held off between the two), so an output
        under its final name always has its record, and a record of a done job its output (a
        ``kill -9`` between the two leaves a complete output without a record: the job runs
        again). An output that cannot be renamed makes the job ``failed``, with that reason.
        """
        if result.status == "done":
            folder = self.path.parent
            partial = folder / (result.output + PARTIAL_SUFFIX)
            try:
                if partial.exists():
                    os.replace(partial, folder / result.output)
            except OSError as exc:
                result.status = "failed"
                result.error = (
                    f"{folder / result.output}: cannot give the output its name "
                    f"({exc.strerror}); it is kept as {partial}"
                )
        self.append(result)

    def completed(self, outdir: Path) -> dict[str, JobResult]:
        """Records of jobs that are done and whose output still exists."""
        return {
            key: r
            for key, r in self.load().items()
            if r.status == "done" and (Path(outdir) / r.output).is_file()
        }
