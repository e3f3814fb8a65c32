"""Batch detection over many recordings: process pool, Dask LocalCluster or a remote cluster.

``run_batch(inputs, outdir)`` plans one *job* per input (one per LaserScan topic for a bag
with several), runs the jobs in parallel and writes, in ``outdir``:

* ``<name>.parquet`` per job: one row per keypoint, the columns of
  :data:`laser_corners.io.writers.TABLE_COLUMNS` (``map_x, map_y`` too when the recording
  has poses), written by :class:`~laser_corners.io.writers.ParquetKeypointWriter` with the
  resolved parameters and the input path in the schema metadata;
* ``manifest.jsonl``: one JSON record per finished job, appended (and flushed to disk) as
  each job ends: ``input, topic, output, status ("done" or "failed"), scans, keypoints,
  skipped, seconds, read_seconds, detect_seconds, write_seconds, startup_seconds, error,
  worker``;
* ``batch-params.yaml``: the parameter choice every job of the folder used.

Resuming: a job whose input (and topic) has a ``done`` record in the manifest and whose
Parquet file exists is skipped. A job writes ``<name>.parquet.partial`` and renames it to
``<name>.parquet`` only after the writer closed, so a partial file is never taken for a
result; a leftover ``.partial`` is overwritten when its job runs again. A job that fails
(a known error: one line; anything else: the exception's first line, with the traceback in
``errors/<name>.txt``) is recorded as ``failed`` and the other jobs go on; the next run
retries it.

Where the time goes is recorded per job: ``read_seconds`` (the reader: file decoding and
:class:`~laser_corners.LaserScan` construction), ``detect_seconds`` (the numba kernel),
``write_seconds`` (the Parquet writer) and ``startup_seconds`` (loading numba's cached
kernels, once per worker process). See ``docs/batch-and-viewer.md``.
"""

from __future__ import annotations

import hashlib
import json
import logging
import os
import re
import threading
import time
import traceback
from collections.abc import Callable, Iterable, Iterator, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any, Literal

from laser_corners.errors import InputError, LaserCornersError
from laser_corners.params import DetectorParams
from laser_corners.scan import LaserScan

__all__ = [
    "MANIFEST_NAME",
    "PARAMS_NAME",
    "BatchJob",
    "BatchReport",
    "JobResult",
    "Manifest",
    "ParamsChoice",
    "plan_jobs",
    "run_batch",
    "run_job",
]

MANIFEST_NAME = "manifest.jsonl"
"""File name of the manifest in the output folder."""
PARAMS_NAME = "batch-params.yaml"
"""File name of the parameter choice recorded in the output folder."""
PARTIAL_SUFFIX = ".partial"
"""Suffix of an output being written (renamed away on success)."""
CHUNK_SCANS = 256
"""Scans read, detected (:meth:`~laser_corners.CornerDetector.detect_many` with threads) and
written at a time."""
_BAG_KINDS = ("ros1", "ros2", "mcap")
_KERNELS_READY: set[int] = set()  # numba thread counts whose kernels this process has loaded
# numba's fallback threading layer (workqueue) must not be entered by two threads at once;
# Dask workers may run several jobs in threads of one process
_PARALLEL_KERNEL_LOCK = threading.Lock()

Status = Literal["done", "failed"]


# ------------------------------------------------------------------ parameters
@dataclass(frozen=True)
class ParamsChoice:
    """How each job gets its :class:`~laser_corners.DetectorParams` (picklable).

    Parameters
    ----------
    preset : str
        A preset of :data:`laser_corners.presets.PRESETS` (``paper``, ``auto``); presets that
        adapt to the sensor use each recording's first scan. Ignored when ``base`` is given.
    base : DetectorParams, optional
        Fixed parameters (for instance loaded from a file) instead of a preset.
    overrides : tuple of str
        ``key=value`` overrides applied last, as ``--set`` does.

    Examples
    --------
    >>> choice = ParamsChoice(preset="paper", overrides=("min_points=6",))
    >>> choice.resolve(None).min_points
    6
    >>> print(choice.describe(), end="")
    preset: paper
    overrides:
    - min_points=6
    """

    preset: str = "paper"
    base: DetectorParams | None = None
    overrides: tuple[str, ...] = ()

    def resolve(self, scan: LaserScan | None) -> DetectorParams:
        """The parameters for a recording whose first scan is ``scan``."""
        from laser_corners.presets import get_preset

        params = self.base if self.base is not None else get_preset(self.preset, scan)
        return params.with_overrides(list(self.overrides)) if self.overrides else params

    def describe(self) -> str:
        """A YAML document naming the choice (what ``batch-params.yaml`` holds)."""
        import yaml

        data: dict[str, Any] = (
            {"params": yaml.safe_load(self.base.to_yaml())}
            if self.base is not None
            else {"preset": self.preset}
        )
        data["overrides"] = list(self.overrides)
        return yaml.safe_dump(data, sort_keys=False)


# ------------------------------------------------------------------ jobs and results
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
    """

    input: str
    topic: str | None
    output: str
    size: int = 0

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
            "seconds", "read_seconds", "detect_seconds", "write_seconds", "startup_seconds"
        ):  # fmt: skip
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
    """

    outdir: Path
    results: list[JobResult] = field(default_factory=list)
    already_done: list[JobResult] = field(default_factory=list)
    seconds: float = 0.0
    workers: int = 1
    interrupted: bool = False

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


# ------------------------------------------------------------------ manifest
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

    def completed(self, outdir: Path) -> dict[str, JobResult]:
        """Records of jobs that are done and whose output still exists."""
        return {
            key: r
            for key, r in self.load().items()
            if r.status == "done" and (Path(outdir) / r.output).is_file()
        }


# ------------------------------------------------------------------ planning
def _stem(path: Path) -> str:
    name = path.name
    for suffix in (".gz", ".bz2", ".bag", ".mcap", ".db3", ".clf", ".log", ".npz", ".csv",
                   ".carmen", ".txt", ".gfs"):  # fmt: skip
        if name.lower().endswith(suffix) and len(name) > len(suffix):
            name = name[: -len(suffix)]
    return re.sub(r"[^A-Za-z0-9._-]+", "_", name) or "input"


def _topic_part(topic: str) -> str:
    return re.sub(r"[^A-Za-z0-9._-]+", "_", topic.strip("/")) or "topic"


def _short_hash(text: str) -> str:
    return hashlib.sha1(text.encode("utf-8")).hexdigest()[:8]


def plan_jobs(
    inputs: Iterable[str | Path],
    topic: str | None = None,
    reserved: dict[str, str] | None = None,
) -> list[BatchJob]:
    """The jobs for ``inputs``: one per recording, one per LaserScan topic of a bag with several.

    Parameters
    ----------
    inputs : iterable of str or Path
        Recordings (any kind :func:`laser_corners.io.open_scans` reads).
    topic : str, optional
        The LaserScan topic to read from every bag (other kinds have no topics). Default:
        every LaserScan topic of each bag, one job each.
    reserved : dict of str to str, optional
        Output names already used in the folder, by job key (from the manifest): a job keeps
        its earlier name; other jobs never take it.

    Returns
    -------
    list of BatchJob
        An input that cannot be opened still gets a job (it fails when run, with the
        reader's one-line error, and the manifest records it).
    """
    from laser_corners.io import detect_kind
    from laser_corners.io.rosbag import BagSource

    reserved = dict(reserved or {})
    wanted: list[tuple[str, str | None, str, int]] = []  # key parts, base name, size
    seen: set[str] = set()
    for item in inputs:
        path = Path(item).expanduser().resolve()
        size = _input_size(path)
        topics: list[str | None] = [None]
        try:
            kind = detect_kind(path)
        except InputError:
            kind = None
        if kind in _BAG_KINDS:
            if topic is not None:
                topics = [topic]
            else:
                try:
                    bag = BagSource(path, kind, None, strict=False)  # type: ignore[arg-type]
                    topics = list(bag.laser_topics) if len(bag.laser_topics) > 1 else [None]
                except InputError:
                    topics = [None]  # the job reports the error
        for one_topic in topics:
            key = str(path) + (f"#{one_topic}" if one_topic else "")
            if key in seen:
                continue
            seen.add(key)
            base = _stem(path) + (f".{_topic_part(one_topic)}" if one_topic else "")
            wanted.append((str(path), one_topic, base, size // len(topics)))
    # names: the earlier name of the job, else the base name unless it clashes (with another
    # input of this run or a name used in the folder before), else base-<hash of the key>
    counts: dict[str, int] = {}
    for _, _, base, _ in wanted:
        counts[base] = counts.get(base, 0) + 1
    taken = {name: key for key, name in reserved.items()}
    jobs = []
    for input_path, one_topic, base, size in wanted:
        key = input_path + (f"#{one_topic}" if one_topic else "")
        name = reserved.get(key)
        if name is None:
            name = f"{base}.parquet"
            if counts[base] > 1 or taken.get(name, key) != key:
                name = f"{base}-{_short_hash(key)}.parquet"
            taken[name] = key
        jobs.append(BatchJob(input_path, one_topic, name, size))
    return jobs


def _input_size(path: Path) -> int:
    try:
        if path.is_dir():
            return sum(p.stat().st_size for p in path.rglob("*") if p.is_file())
        return path.stat().st_size
    except OSError:
        return 0


# ------------------------------------------------------------------ one job (runs in a worker)
def _same_geometry(a: LaserScan, b: LaserScan) -> bool:
    return (a.n_beams, a.angle_min, a.angle_increment, a.range_min, a.range_max) == (
        b.n_beams, b.angle_min, b.angle_increment, b.range_min, b.range_max
    )  # fmt: skip


def _worker_name() -> str:
    import socket

    return f"{socket.gethostname()}:{os.getpid()}"


def _set_threads(threads: int | None) -> int:
    """Limit numba's threads in this process; returns the number in use."""
    import numba

    if threads is not None:
        numba.set_num_threads(max(1, min(int(threads), numba.config.NUMBA_NUM_THREADS)))
    return int(numba.get_num_threads())


def run_job(
    job: BatchJob,
    outdir: str | Path,
    params: ParamsChoice | DetectorParams | None = None,
    threads: int | None = 1,
) -> JobResult:
    """Detect keypoints in every scan of one job's recording and write its Parquet file.

    The output is written to ``<name>.parquet.partial`` and renamed to ``<name>.parquet`` when
    complete. Known errors (:class:`~laser_corners.errors.LaserCornersError`, such as a
    damaged file) and unexpected ones give a ``failed`` result instead of raising; the
    traceback of an unexpected one goes to ``errors/<name>.txt``. Ctrl-C removes the partial
    file and propagates.

    Parameters
    ----------
    job : BatchJob
        The job.
    outdir : str or Path
        Output folder (on a remote cluster: a path the worker can write).
    params : ParamsChoice or DetectorParams, optional
        Parameters (default: the paper's).
    threads : int, optional
        numba threads for this worker process. Scans are read, detected and written in
        chunks of up to :data:`CHUNK_SCANS` scans of one geometry; with 1 thread each scan of a
        chunk goes through :meth:`~laser_corners.CornerDetector.detect`, with more the chunk
        goes through the parallel :meth:`~laser_corners.CornerDetector.detect_many`. None:
        leave numba's setting.

    Returns
    -------
    JobResult
    """
    from laser_corners.detector import CornerDetector
    from laser_corners.io import open_scans
    from laser_corners.io.writers import KeypointWriter, ParquetKeypointWriter

    start = time.perf_counter()
    outdir = Path(outdir)
    final = outdir / job.output
    partial = outdir / (job.output + PARTIAL_SUFFIX)
    result = JobResult(job.input, job.topic, job.output, "failed", worker=_worker_name())
    n_threads = _set_threads(threads)
    writer: KeypointWriter = KeypointWriter()
    source = None
    try:
        partial.unlink(missing_ok=True)  # a leftover of an interrupted run
        source = open_scans(job.input, job.topic)
        scans = iter(source)
        t0 = time.perf_counter()
        first = next(scans, None)
        result.read_seconds += time.perf_counter() - t0
        if first is None:
            detail = f" ({'; '.join(source.skip_examples)})" if source.skip_examples else ""
            raise InputError(f"{job.input}: no readable scan{detail}")
        choice = params if params is not None else DetectorParams()
        resolved = choice if isinstance(choice, DetectorParams) else choice.resolve(first)
        detector = CornerDetector(resolved)
        if n_threads not in _KERNELS_READY:  # load numba's cached kernels, timed apart
            t0 = time.perf_counter()
            detector.detect(first)
            if n_threads > 1:
                with _PARALLEL_KERNEL_LOCK:
                    detector.detect_many([first, first])
            result.startup_seconds = time.perf_counter() - t0
            _KERNELS_READY.add(n_threads)
        with_map = first.pose is not None or getattr(source, "odom_topic", None) is not None
        writer = ParquetKeypointWriter(
            partial, with_map,
            metadata={
                "laser_corners.params": resolved.to_yaml(),
                "laser_corners.input": job.input,
                "laser_corners.topic": job.topic or "",
            },
        )  # fmt: skip
        index = 0
        chunk: list[LaserScan] = [first]
        while chunk:
            t0 = time.perf_counter()
            scan = next(scans, None)
            while scan is not None and len(chunk) < CHUNK_SCANS and _same_geometry(scan, chunk[0]):
                chunk.append(scan)
                scan = next(scans, None)
            t1 = time.perf_counter()
            if n_threads == 1 or len(chunk) == 1:
                found = [detector.detect(one_scan) for one_scan in chunk]
            else:
                with _PARALLEL_KERNEL_LOCK:
                    found = detector.detect_many(chunk)
            t2 = time.perf_counter()
            writer.write_many(index, chunk, found)
            index += len(chunk)
            t3 = time.perf_counter()
            result.read_seconds += t1 - t0
            result.detect_seconds += t2 - t1
            result.write_seconds += t3 - t2
            chunk = [scan] if scan is not None else []
        t0 = time.perf_counter()
        writer.close()
        result.write_seconds += time.perf_counter() - t0
        os.replace(partial, final)
        result.status = "done"
    except KeyboardInterrupt:
        writer.close()
        partial.unlink(missing_ok=True)
        raise
    except LaserCornersError as exc:
        writer.close()
        partial.unlink(missing_ok=True)
        result.error = _first_line(exc)
    except Exception as exc:  # a surprise: keep the traceback next to the results
        writer.close()
        partial.unlink(missing_ok=True)
        result.error = f"{type(exc).__name__}: {_first_line(exc)} (traceback in errors/)"
        errors = outdir / "errors"
        errors.mkdir(exist_ok=True)
        (errors / f"{job.output}.txt").write_text(traceback.format_exc(), encoding="utf-8")
    result.scans = writer.n_scans
    result.keypoints = writer.n_keypoints
    result.skipped = sum(source.skipped.values()) if source is not None else 0
    result.seconds = time.perf_counter() - start
    return result


def _first_line(exc: BaseException) -> str:
    text = str(exc).strip()
    return text.splitlines()[0] if text else type(exc).__name__


def _failed(job: BatchJob, exc: BaseException) -> JobResult:
    """The result of a job whose worker failed before returning one (crash, lost worker)."""
    return JobResult(
        job.input, job.topic, job.output, "failed",
        error=f"worker failed: {type(exc).__name__}: {_first_line(exc)}",
    )  # fmt: skip


# ------------------------------------------------------------------ executors
def _run_here(
    jobs: Sequence[BatchJob], outdir: Path, params: ParamsChoice | DetectorParams, threads: int
) -> Iterator[JobResult]:
    for job in jobs:
        yield run_job(job, outdir, params, threads)


def _run_pool(
    jobs: Sequence[BatchJob],
    outdir: Path,
    params: ParamsChoice | DetectorParams,
    workers: int,
    threads: int,
) -> Iterator[JobResult]:
    """Run the jobs on a pool of ``workers`` spawned processes, at most one job per worker.

    Jobs are handed out only as workers free up, so after Ctrl-C no queued job starts; a
    worker that dies fails its job (and the jobs running beside it) and the pool is renewed.
    """
    import multiprocessing
    from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
    from concurrent.futures.process import BrokenProcessPool

    # spawn: a forked child would inherit the parent's numba (OpenMP) thread pool
    context = multiprocessing.get_context("spawn")
    pool = ProcessPoolExecutor(workers, mp_context=context)
    waiting = list(jobs)
    running: dict[Future[JobResult], BatchJob] = {}
    try:
        while waiting or running:
            while waiting and len(running) < workers:
                job = waiting.pop(0)
                running[pool.submit(run_job, job, outdir, params, threads)] = job
            done, _ = wait(running, return_when=FIRST_COMPLETED)
            broken = False
            for future in done:
                job = running.pop(future)
                try:
                    yield future.result()
                except BrokenProcessPool as exc:
                    broken = True
                    yield _failed(job, exc)
                except Exception as exc:  # an error outside run_job: record, go on
                    yield _failed(job, exc)
            if broken:
                pool.shutdown(wait=True, cancel_futures=True)
                pool = ProcessPoolExecutor(workers, mp_context=context)
    finally:
        pool.shutdown(wait=True, cancel_futures=True)


def _run_dask(
    jobs: Sequence[BatchJob],
    outdir: Path,
    params: ParamsChoice | DetectorParams,
    scheduler: str,
    workers: int,
    threads: int,
    timeout: float,
    started: Callable[[int], None],
) -> Iterator[JobResult]:
    try:
        from dask.distributed import Client, LocalCluster, as_completed
    except ImportError:
        raise InputError("--scheduler needs Dask: pip install 'laser-corners[dask]'") from None

    cluster = None
    if scheduler == "local":
        cluster = LocalCluster(
            n_workers=workers,
            threads_per_worker=1,
            processes=True,
            dashboard_address=None,
            silence_logs=logging.WARNING,
        )
        client = Client(cluster, timeout=timeout)
    else:
        try:
            client = Client(scheduler, timeout=timeout)
        except OSError as exc:
            raise InputError(
                f"cannot reach the Dask scheduler at {scheduler} ({_first_line(exc)})"
            ) from None
    futures: dict[Any, BatchJob] = {}
    try:
        started(len(client.scheduler_info().get("workers", {})) or workers)
        futures = {
            client.submit(
                run_job, job, str(outdir), params, threads,
                key=f"laser-corners-{_short_hash(job.key)}-{time.time_ns()}", pure=False,
            ): job
            for job in jobs
        }  # fmt: skip
        for future in as_completed(futures):
            try:
                yield future.result()
            except Exception as exc:  # KilledWorker, a lost connection: record, go on
                yield _failed(futures[future], exc)
    finally:
        client.cancel(list(futures))  # no-op when all finished; after Ctrl-C: stop the rest
        client.close()
        if cluster is not None:
            cluster.close()


# ------------------------------------------------------------------ the batch
def run_batch(
    inputs: Iterable[str | Path],
    outdir: str | Path,
    *,
    params: ParamsChoice | DetectorParams | None = None,
    topic: str | None = None,
    workers: int | None = None,
    scheduler: str | None = None,
    threads: int | None = None,
    timeout: float = 30.0,
    on_result: Callable[[JobResult], None] | None = None,
    on_plan: Callable[[list[BatchJob], list[JobResult]], None] | None = None,
) -> BatchReport:
    """Detect keypoints in many recordings in parallel, resumably (see the module docstring).

    Parameters
    ----------
    inputs : iterable of str or Path
        Recordings.
    outdir : str or Path
        Output folder (created). Running again on the same folder skips finished jobs.
    params : ParamsChoice or DetectorParams, optional
        Parameters (default: the ``paper`` preset). The folder records the choice and refuses
        another one, so its results always share one choice.
    topic : str, optional
        LaserScan topic of the bags (default: each of their LaserScan topics).
    workers : int, optional
        Worker processes (default: the number of CPU cores). With 1 and no ``scheduler`` the
        jobs run in this process.
    scheduler : str, optional
        None: a local process pool. ``"local"``: a ``dask.distributed.LocalCluster`` of
        ``workers`` processes. ``"tcp://host:port"``: an existing Dask cluster; its workers
        need this package installed and must see the inputs and ``outdir`` at the same paths.
    threads : int, optional
        numba threads per worker (default: cores // workers, at least 1; remote clusters: 1).
    timeout : float
        Seconds to wait for a Dask scheduler to answer.
    on_result : callable, optional
        Called with each :class:`JobResult` as its job ends (after the manifest has it).
    on_plan : callable, optional
        Called once with the jobs to run and the results of the jobs already done.

    Returns
    -------
    BatchReport

    Raises
    ------
    InputError
        ``outdir`` is not a writable folder, holds results of another parameter choice, or
        the Dask scheduler cannot be reached.
    """
    outdir = Path(outdir)
    try:
        outdir.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise InputError(f"{outdir}: cannot create the output folder ({exc.strerror})") from None
    choice = params if params is not None else ParamsChoice()
    described = (
        choice.describe()
        if isinstance(choice, ParamsChoice)
        else ParamsChoice(base=choice).describe()
    )
    params_file = outdir / PARAMS_NAME
    if params_file.exists() and params_file.read_text(encoding="utf-8") != described:
        raise InputError(
            f"{outdir}: holds results made with other parameters (see {params_file}); "
            "use another output folder, or delete this one to start over"
        )
    params_file.write_text(described, encoding="utf-8")

    cores = os.cpu_count() or 1
    n_workers = max(1, int(workers) if workers else cores)
    if threads is None:
        threads = 1 if scheduler not in (None, "local") else max(1, cores // n_workers)
    manifest = Manifest(outdir)
    records = manifest.load()
    jobs = plan_jobs(inputs, topic, reserved={k: r.output for k, r in records.items()})
    completed = manifest.completed(outdir)
    pending = sorted((job for job in jobs if job.key not in completed), key=lambda job: -job.size)
    report = BatchReport(
        outdir, already_done=[completed[j.key] for j in jobs if j.key in completed],
        workers=n_workers,
    )  # fmt: skip
    if on_plan is not None:
        on_plan(pending, report.already_done)

    def started(count: int) -> None:
        report.workers = count

    start = time.perf_counter()
    if not pending:
        executed: Iterator[JobResult] = iter(())
    elif scheduler is not None:
        executed = _run_dask(
            pending, outdir, choice, scheduler, n_workers, threads, timeout, started
        )
    elif n_workers == 1 or len(pending) == 1:
        report.workers = 1
        executed = _run_here(pending, outdir, choice, threads)
    else:
        report.workers = min(n_workers, len(pending))
        executed = _run_pool(pending, outdir, choice, report.workers, threads)
    try:
        for result in executed:
            manifest.append(result)
            report.results.append(result)
            if on_result is not None:
                on_result(result)
    except KeyboardInterrupt:
        report.interrupted = True
    finally:
        close = getattr(executed, "close", None)
        if close is not None:
            close()
        report.seconds = time.perf_counter() - start
    return report
