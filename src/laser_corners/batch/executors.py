"""Where jobs run: in this process, on a pool of spawned processes, or on a Dask cluster.

Every executor hands each :class:`~laser_corners.batch.manifest.JobResult` to ``deliver`` as
its job ends. Jobs run with ``publish=False``: a finished job's output stays
``NAME.parquet.partial`` until ``deliver`` renames it as it records the job in the manifest
(:meth:`~laser_corners.batch.manifest.Manifest.record`), so a result lost to Ctrl-C (a job
handed to a worker an instant before, a result not yet delivered) leaves no output under its
final name. After Ctrl-C an executor stops starting jobs, waits for the running ones and
delivers every result that came back before re-raising.
"""

from __future__ import annotations

import importlib.util
import logging
import os
import socket
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any
from urllib.parse import urlsplit

from laser_corners.batch.manifest import BatchJob, JobResult
from laser_corners.batch.plan import short_hash
from laser_corners.batch.worker import (
    failed_result,
    run_job,
    run_pooled_job,
    start_pool_worker,
)
from laser_corners.errors import ClusterError, MissingDependencyError, first_line
from laser_corners.params import DetectorParams
from laser_corners.pipeline import ParamsChoice

__all__ = ["check_scheduler", "run_dask", "run_here", "run_pool"]

Deliver = Callable[[JobResult], None]
Choice = ParamsChoice | DetectorParams


def run_here(
    jobs: Sequence[BatchJob],
    outdir: Path,
    params: Choice,
    threads: int,
    deliver: Deliver,
    prefetch: bool = True,
) -> None:
    """Run the jobs one after the other in this process."""
    for job in jobs:
        deliver(run_job(job, outdir, params, threads, prefetch, publish=False))


def _result_of(future: Any, job: BatchJob) -> JobResult | None:
    """The result of a finished future (a failed result for a crashed one), None if cancelled."""
    if future.cancelled():
        return None
    error = future.exception()
    if error is None:
        return future.result()  # type: ignore[no-any-return]
    if isinstance(error, KeyboardInterrupt):  # the job was stopped: nothing to record
        return None
    return failed_result(job, error)


def run_pool(
    jobs: Sequence[BatchJob],
    outdir: Path,
    params: Choice,
    workers: int,
    threads: int,
    deliver: Deliver,
    prefetch: bool = False,
) -> None:
    """Run the jobs on a pool of ``workers`` spawned processes, at most one job per worker.

    Jobs are handed out only as workers free up, so after Ctrl-C no queued job starts; a
    worker that dies fails its job (and the jobs running beside it) and the pool is renewed.
    Workers die with this process and take Ctrl-C only while they run a job
    (:func:`~laser_corners.batch.worker.start_pool_worker`).
    """
    import multiprocessing
    from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
    from concurrent.futures.process import BrokenProcessPool

    # spawn: a forked child would inherit the parent's numba (OpenMP) thread pool
    context = multiprocessing.get_context("spawn")
    stopping = context.Event()  # set on Ctrl-C: a job handed out meanwhile does not start

    def new_pool() -> ProcessPoolExecutor:
        return ProcessPoolExecutor(
            workers,
            mp_context=context,
            initializer=start_pool_worker,
            initargs=(os.getpid(), stopping),
        )

    pool = new_pool()
    waiting = list(jobs)
    running: dict[Future[JobResult], BatchJob] = {}
    try:
        while waiting or running:
            while waiting and len(running) < workers:
                job = waiting.pop(0)
                future = pool.submit(run_pooled_job, job, outdir, params, threads, prefetch, False)
                running[future] = job
            done, _ = wait(running, return_when=FIRST_COMPLETED)
            broken = False
            for future in done:
                job = running.pop(future)
                broken = broken or isinstance(future.exception(), BrokenProcessPool)
                result = _result_of(future, job)
                if result is not None:
                    deliver(result)
            if broken:
                pool.shutdown(wait=True, cancel_futures=True)
                pool = new_pool()
    except BaseException:
        stopping.set()
        pool.shutdown(wait=True, cancel_futures=True)  # the running jobs end (or stop)
        for future, job in running.items():
            result = _result_of(future, job)
            if result is not None and result.status == "done":
                deliver(result)
        raise
    finally:
        pool.shutdown(wait=True, cancel_futures=True)


def check_scheduler(scheduler: str | None, timeout: float) -> None:
    """Check that a Dask scheduler address (``tcp://host:port``) answers, before any output.

    ``None`` (a local process pool) needs no check, ``"local"`` only Dask.

    Raises
    ------
    MissingDependencyError
        Dask is not installed.
    ClusterError
        The address is not of the form ``tcp://host:port``, or nothing accepts a connection
        there within ``timeout`` seconds.
    """
    if scheduler is None:
        return
    if importlib.util.find_spec("distributed") is None:
        raise MissingDependencyError("Dask is needed: pip install 'laser-corners[dask]'")
    if scheduler == "local":
        return
    try:
        parts = urlsplit(scheduler if "://" in scheduler else f"tcp://{scheduler}")
        host, port = parts.hostname, parts.port
    except ValueError:
        host, port = None, None
    if not host or port is None:
        raise ClusterError(f"{scheduler}: not a Dask scheduler address (tcp://host:port)")
    try:
        socket.create_connection((host, port), timeout=min(timeout, 10.0)).close()
    except OSError as exc:
        reason = exc.strerror or first_line(exc)
        raise ClusterError(f"cannot reach the Dask scheduler at {scheduler} ({reason})") from None


def _client(scheduler: str, workers: int, timeout: float) -> tuple[Any, Any]:
    """A Dask client (and the LocalCluster it owns, or None)."""
    try:
        from dask.distributed import Client, LocalCluster
    except ImportError:
        raise MissingDependencyError("Dask is needed: pip install 'laser-corners[dask]'") from None
    if scheduler == "local":
        cluster = LocalCluster(
            n_workers=workers,
            threads_per_worker=1,
            processes=True,
            dashboard_address=None,
            silence_logs=logging.WARNING,
        )
        return Client(cluster, timeout=timeout), cluster
    try:
        return Client(scheduler, timeout=timeout), None
    except OSError as exc:
        raise ClusterError(
            f"cannot reach the Dask scheduler at {scheduler} ({first_line(exc)})"
        ) from None


def run_dask(
    jobs: Sequence[BatchJob],
    outdir: Path,
    params: Choice,
    scheduler: str,
    workers: int,
    threads: int,
    timeout: float,
    started: Callable[[int], None],
    deliver: Deliver,
    prefetch: bool = False,
) -> None:
    """Run the jobs on a Dask cluster: ``"local"`` (a LocalCluster) or ``tcp://host:port``.

    Raises
    ------
    MissingDependencyError
        Dask is not installed.
    ClusterError
        The scheduler cannot be reached.
    """
    from dask.distributed import as_completed

    client, cluster = _client(scheduler, workers, timeout)
    futures: dict[Any, BatchJob] = {}
    delivered: set[Any] = set()
    try:
        started(len(client.scheduler_info().get("workers", {})) or workers)
        futures = {
            client.submit(
                run_job,
                job,
                str(outdir),
                params,
                threads,
                prefetch,
                False,  # publish: the batch renames the output once it has recorded it
                key=f"laser-corners-{short_hash(job.key)}-{time.time_ns()}",
                pure=False,
            ): job
            for job in jobs
        }
        for future in as_completed(futures):
            delivered.add(future)
            try:
                deliver(future.result())
            except Exception as exc:  # KilledWorker, a lost connection: record, go on
                deliver(failed_result(futures[future], exc))
    except BaseException:
        for future in futures:  # results that came back but were not handed on yet
            if future not in delivered and future.status == "finished":
                deliver(future.result())
        raise
    finally:
        client.cancel(list(futures))  # no-op when all finished; after Ctrl-C: stop the rest
        client.close()
        if cluster is not None:
            cluster.close()
