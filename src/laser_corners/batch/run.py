"""``run_batch``: plan, check the output folder, run the jobs, record each result at once."""

from __future__ import annotations

import json
import os
import time
from collections.abc import Callable, Iterable
from pathlib import Path

from laser_corners.batch.executors import check_scheduler, run_dask, run_here, run_pool
from laser_corners.batch.manifest import (
    PARAMS_NAME,
    PARTIAL_SUFFIX,
    BatchJob,
    BatchReport,
    JobResult,
    Manifest,
)
from laser_corners.batch.plan import check_globs, plan_inputs
from laser_corners.errors import OutputError
from laser_corners.params import DetectorParams
from laser_corners.pipeline import ParamsChoice, as_choice
from laser_corners.pipeline.interrupt import stop_requests

__all__ = ["run_batch"]


def _claim_folder(outdir: Path, choice: ParamsChoice, odom_topic: str | None) -> None:
    """Create ``outdir`` and record the parameter choice (and the odometry, when one is
    named); refuse a folder of another choice."""
    try:
        outdir.mkdir(parents=True, exist_ok=True)
    except FileExistsError:
        raise OutputError(f"{outdir}: a file is in the way of the output folder") from None
    except OSError as exc:
        raise OutputError(f"{outdir}: cannot create the output folder ({exc.strerror})") from None
    described = choice.describe()
    if odom_topic is not None:  # the keypoints' map columns depend on it
        described += f"odom_topic: {json.dumps(odom_topic)}\n"
    params_file = outdir / PARAMS_NAME
    if params_file.exists() and params_file.read_text(encoding="utf-8") != described:
        raise OutputError(
            f"{outdir}: holds results made with other parameters or another --odom-topic "
            f"(see {params_file}); use another output folder, or delete this one to start over"
        )
    try:
        params_file.write_text(described, encoding="utf-8")
    except OSError as exc:
        raise OutputError(f"{params_file}: cannot write ({exc.strerror})") from None


def run_batch(
    inputs: Iterable[str | Path],
    outdir: str | Path,
    *,
    params: ParamsChoice | DetectorParams | None = None,
    topic: str | None = None,
    odom_topic: str | None = None,
    workers: int | None = None,
    scheduler: str | None = None,
    threads: int | None = None,
    timeout: float = 30.0,
    prefetch: bool | None = None,
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
        another one, so its results always share one choice (and one ``odom_topic``).
    topic : str, optional
        LaserScan topic of the bags (default: each of their LaserScan topics).
    odom_topic : str, optional
        Odometry of the bags: a ``nav_msgs/Odometry`` topic or ``"tf"`` (default: each bag's
        only one; a bag with several fails with one line naming them).
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
    prefetch : bool, optional
        Read each recording in a thread of its own while detecting (see
        :mod:`laser_corners.pipeline`). Default: only when a core is left for it (local
        workers x threads < cores); it costs a little CPU for the hand-over.
    on_result : callable, optional
        Called with each :class:`JobResult` as its job ends (after the manifest has it).
    on_plan : callable, optional
        Called once with the jobs to run and the results of the jobs already done.

    Returns
    -------
    BatchReport
        Inputs that are not recordings are listed in ``skipped``, not run.

    Raises
    ------
    OutputError
        ``outdir`` is not a writable folder, or holds results of another parameter choice.
    MissingDependencyError
        A Dask ``scheduler`` is asked for and Dask is not installed.
    InputError
        An input is a glob pattern that matches no file (checked before anything is written).
    ClusterError
        The Dask scheduler cannot be reached (checked before anything is written).
    """
    outdir, inputs = Path(outdir), list(inputs)
    choice = as_choice(params)
    check_globs(inputs)  # the inputs and the scheduler first: nothing is written before
    check_scheduler(scheduler, timeout)
    _claim_folder(outdir, choice, odom_topic)
    n_workers, threads, prefetch = _resources(workers, scheduler, threads, prefetch)
    manifest = Manifest(outdir)
    pending, report = _plan(manifest, outdir, inputs, (topic, odom_topic), n_workers)
    if on_plan is not None:
        on_plan(pending, report.already_done)
    deliver = _recorder(manifest, report, on_result)
    _run_jobs(pending, outdir, choice, (scheduler, threads, timeout, prefetch), report, deliver)
    return report


def _recorder(
    manifest: Manifest, report: BatchReport, on_result: Callable[[JobResult], None] | None
) -> Callable[[JobResult], None]:
    """What happens to each result as its job ends: manifest, report, then ``on_result``."""

    def deliver(result: JobResult) -> None:
        with stop_requests() as stop:  # Ctrl-C waits until the record and the rename are done
            manifest.record(result)  # flushed and synced: a killed run keeps the record
            report.results.append(result)
        if on_result is not None:
            on_result(result)
        if stop.is_set():
            raise KeyboardInterrupt

    return deliver


def _run_jobs(
    pending: list[BatchJob],
    outdir: Path,
    choice: ParamsChoice,
    how: tuple[str | None, int, float, bool],
    report: BatchReport,
    deliver: Callable[[JobResult], None],
) -> None:
    """Run the jobs (``how``: scheduler, threads, timeout, prefetch), timed in
    ``report.seconds``; an interrupt ends the run with what is done (``report.interrupted``)."""
    start = time.perf_counter()
    try:
        _dispatch(pending, outdir, choice, *how, report, deliver)
    except KeyboardInterrupt:
        report.interrupted = True
        for job in pending:  # finished but not recorded: not a result (a re-run makes it)
            (outdir / (job.output + PARTIAL_SUFFIX)).unlink(missing_ok=True)
    finally:
        report.seconds = time.perf_counter() - start


def _resources(
    workers: int | None, scheduler: str | None, threads: int | None, prefetch: bool | None
) -> tuple[int, int, bool]:
    """Workers, numba threads per worker and prefetching, defaults filled in from the cores."""
    cores = os.cpu_count() or 1
    n_workers = max(1, int(workers) if workers else cores)
    if threads is None:
        threads = 1 if scheduler not in (None, "local") else max(1, cores // n_workers)
    if prefetch is None:
        prefetch = scheduler in (None, "local") and n_workers * threads < cores
    return n_workers, threads, prefetch


def _plan(
    manifest: Manifest,
    outdir: Path,
    inputs: list[str | Path],
    topics: tuple[str | None, str | None],
    n_workers: int,
) -> tuple[list[BatchJob], BatchReport]:
    """The jobs still to run (largest first) and a report holding those already done;
    ``topics``: the LaserScan and the odometry topic."""
    records = manifest.load()
    reserved = {k: r.output for k, r in records.items()}
    jobs, skipped = plan_inputs(inputs, topics[0], reserved, odom_topic=topics[1])
    completed = manifest.completed(outdir)
    pending = sorted((job for job in jobs if job.key not in completed), key=lambda job: -job.size)
    report = BatchReport(
        outdir,
        already_done=[completed[j.key] for j in jobs if j.key in completed],
        workers=n_workers,
        skipped=skipped,
    )
    return pending, report


def _dispatch(
    pending: list[BatchJob],
    outdir: Path,
    choice: ParamsChoice,
    scheduler: str | None,
    threads: int,
    timeout: float,
    prefetch: bool,
    report: BatchReport,
    deliver: Callable[[JobResult], None],
) -> None:
    """Run the pending jobs on a Dask cluster, in a process pool or here; ``report.workers``
    says how many workers ran them."""
    if not pending:
        return

    def started(count: int) -> None:
        report.workers = count

    n_workers = report.workers
    if scheduler is not None:
        args = (n_workers, threads, timeout, started, deliver, prefetch)
        run_dask(pending, outdir, choice, scheduler, *args)
    elif n_workers == 1 or len(pending) == 1:
        report.workers = 1
        run_here(pending, outdir, choice, threads, deliver, prefetch)
    else:
        report.workers = min(n_workers, len(pending))
        run_pool(pending, outdir, choice, report.workers, threads, deliver, prefetch)
