"""A batch run (:mod:`laser_corners.batch.run`): a real Dask LocalCluster (2 workers) with damaged
inputs and a resumed run, an unreachable scheduler, a killed run that resumes, and the CLI
(process pool). Planning, the manifest and one job: test_plan, test_manifest, test_worker."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any

import pyarrow.parquet as pq
import pytest
from typer.testing import CliRunner

from conftest import default_sigint, real_file
from laser_corners.batch import (
    MANIFEST_NAME,
    BatchReport,
    JobResult,
    Manifest,
    run_batch,
)
from laser_corners.cli import app
from laser_corners.errors import ClusterError
from laser_corners.io import open_scans

CLUSTER_TIMEOUT_S = 120  # a batch on the cluster that takes longer fails the test, not hangs


def _on_cluster(*args: Any, **kwargs: Any) -> BatchReport:
    """run_batch, bounded: the test fails after CLUSTER_TIMEOUT_S instead of waiting forever."""
    runner = ThreadPoolExecutor(1)
    try:
        return runner.submit(run_batch, *args, **kwargs).result(timeout=CLUSTER_TIMEOUT_S)
    finally:
        runner.shutdown(wait=False)  # on a timeout, do not wait for the stuck run


def _truncated_copy(source: Path, target: Path, keep: int) -> Path:
    target.write_bytes(source.read_bytes()[:keep])
    return target


def _byte_flipped_copy(source: Path, target: Path, start: int, length: int) -> Path:
    data = bytearray(source.read_bytes())
    for i in range(start, start + length):
        data[i] ^= 0xFF
    target.write_bytes(bytes(data))
    return target


def _latest(outdir: Path) -> dict[str, JobResult]:
    return Manifest(outdir).load()


@pytest.fixture(scope="module")
def cluster():
    """A real dask.distributed LocalCluster of 2 worker processes, closed at teardown."""
    distributed = pytest.importorskip("dask.distributed")
    local = distributed.LocalCluster(
        n_workers=2,
        threads_per_worker=1,
        processes=True,
        memory_limit="1GiB",
        dashboard_address=None,
    )
    try:
        yield local
    finally:
        local.close(timeout=30)


# ------------------------------------------------------------------ planning


# ------------------------------------------------------------------ one job


# ------------------------------------------------------------------ Dask LocalCluster
def test_dask_cluster_batch_with_damaged_inputs_resumes(tmp_path: Path, cluster) -> None:
    fr079_log = real_file("fr079-corrected.clf.gz")
    intel_log = real_file("intel-corrected.clf.gz")
    aces = real_file("aces.bag")
    truncated = _truncated_copy(aces, tmp_path / "truncated.bag", keep=700_000)
    flipped = _byte_flipped_copy(intel_log, tmp_path / "flipped.clf.gz", 200_000, 400)
    outdir = tmp_path / "out"
    outdir.mkdir()
    inputs = [fr079_log, intel_log, aces, truncated, flipped]

    # the state a killed run leaves: one job done and in the manifest, one partial output
    first = run_batch([fr079_log], outdir, workers=1)
    assert [r.status for r in first.results] == ["done"]
    done_mtime = (outdir / "fr079-corrected.parquet").stat().st_mtime_ns
    leftover = outdir / "intel-corrected.parquet.partial"
    leftover.write_bytes(b"PAR1 half a file")

    report = _on_cluster(inputs, outdir, scheduler=cluster.scheduler_address, workers=2, timeout=30)
    assert [r.output for r in report.already_done] == ["fr079-corrected.parquet"]
    assert (outdir / "fr079-corrected.parquet").stat().st_mtime_ns == done_mtime
    by_input = {Path(r.input).name: r for r in report.results}
    assert set(by_input) == {
        "intel-corrected.clf.gz",
        "aces.bag",
        "truncated.bag",
        "flipped.clf.gz",
    }
    assert report.workers == 2
    assert len({r.worker for r in report.results}) == 2  # both worker processes got jobs

    for name in ("intel-corrected.clf.gz", "aces.bag"):
        result = by_input[name]
        assert result.status == "done", result.error
        table = pq.read_table(outdir / result.output)
        assert table.num_rows == result.keypoints > 0
        assert result.scans == sum(1 for _ in open_scans(result.input))
    assert not leftover.exists()

    truncated_result = by_input["truncated.bag"]
    assert truncated_result.status == "failed"
    assert "truncated.bag" in truncated_result.error and "\n" not in truncated_result.error
    flipped_result = by_input["flipped.clf.gz"]
    assert flipped_result.status == "failed"
    assert "gzip" in flipped_result.error and "\n" not in flipped_result.error
    # the damaged log failed in the middle: its partial output is gone, no result file
    assert not (outdir / flipped_result.output).exists()
    assert sorted(p.name for p in outdir.glob("*.partial")) == []

    latest = _latest(outdir)
    assert {Path(k).name: r.status for k, r in latest.items()} == {
        "fr079-corrected.clf.gz": "done",
        "intel-corrected.clf.gz": "done",
        "aces.bag": "done",
        "truncated.bag": "failed",
        "flipped.clf.gz": "failed",
    }

    # running again retries only the failed jobs
    again = _on_cluster(inputs, outdir, scheduler=cluster.scheduler_address, timeout=30)
    assert sorted(Path(r.input).name for r in again.results) == ["flipped.clf.gz", "truncated.bag"]
    assert len(again.already_done) == 3


def test_unreachable_scheduler_is_a_known_error(tmp_path: Path) -> None:
    log = real_file("fr079-corrected.clf.gz")
    with pytest.raises(
        ClusterError, match=r"cannot reach the Dask scheduler at tcp://127\.0\.0\.1:9"
    ):
        run_batch([log], tmp_path / "out", scheduler="tcp://127.0.0.1:9", timeout=2)
    # nothing ran, nothing was recorded as done
    assert Manifest(tmp_path / "out").load() == {}


# ------------------------------------------------------------------ a run killed for real
@pytest.mark.parametrize(
    ("stop", "workers", "exit_code"),
    [(signal.SIGKILL, "1", -signal.SIGKILL), (signal.SIGINT, "2", 130)],
    ids=["kill-9-in-process", "ctrl-c-process-pool"],
)
def test_stopped_run_resumes_without_redoing_or_trusting_partials(
    tmp_path: Path, stop: signal.Signals, workers: str, exit_code: int
) -> None:
    aces = real_file("aces.bag")  # the largest input: the first job
    intel = real_file("intel-corrected.clf.gz")
    log = real_file("fr079-corrected.clf.gz")
    outdir = tmp_path / "out"
    command = [
        str(Path(sys.executable).parent / "laser-corners"),
        "batch",
        str(intel),
        str(aces),
        str(log),
        "-o",
        str(outdir),
        "-w",
        workers,
    ]
    process = subprocess.Popen(
        command,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        start_new_session=True,
        preexec_fn=default_sigint,
    )
    manifest = outdir / MANIFEST_NAME
    deadline = time.monotonic() + 120
    try:
        while time.monotonic() < deadline and process.poll() is None:
            if manifest.exists() and manifest.read_text(encoding="utf-8").count("\n") >= 1:
                break
            time.sleep(0.02)
    finally:
        if process.poll() is None:
            os.killpg(process.pid, stop)
        process.wait(timeout=60)
    assert process.returncode == exit_code  # stopped, not finished
    if stop == signal.SIGINT:  # Ctrl-C: the jobs in progress removed their partial outputs
        assert list(outdir.glob("*.partial")) == []
    records = [json.loads(line) for line in manifest.read_text(encoding="utf-8").splitlines()]
    assert records and records[0]["status"] == "done"
    assert len(records) < 3
    finished_first = {r["output"] for r in records}
    first_mtimes = {name: (outdir / name).stat().st_mtime_ns for name in finished_first}

    report = run_batch([aces, intel, log], outdir, workers=1)
    assert {r.output for r in report.already_done} == finished_first
    assert all(r.status == "done" for r in report.results)
    assert {r.output for r in report.results}.isdisjoint(finished_first)
    for name, mtime in first_mtimes.items():
        assert (outdir / name).stat().st_mtime_ns == mtime
    assert list(outdir.glob("*.partial")) == []
    latest = _latest(outdir)
    assert len(latest) == 3 and all(r.status == "done" for r in latest.values())
    for record in latest.values():
        assert pq.read_metadata(outdir / record.output).num_rows == record.keypoints


# ------------------------------------------------------------------ CLI, process pool
def test_cli_batch_process_pool_and_parameter_guard(tmp_path: Path) -> None:
    fr079_log = real_file("fr079-corrected.clf.gz")
    intel_log = real_file("intel-corrected.clf.gz")
    missing = tmp_path / "missing.bag"
    outdir = tmp_path / "out"
    runner = CliRunner()
    result = runner.invoke(
        app, ["batch", str(fr079_log), str(intel_log), str(missing), "-o", str(outdir), "-w", "2"]
    )
    assert result.exit_code == 1, result.output  # one input failed, the others are done
    assert "3 job(s) run (1 failed)" in result.output
    latest = _latest(outdir)
    assert latest[str(missing)].status == "failed"
    assert "no such file" in latest[str(missing)].error
    assert {Path(r.input).name for r in latest.values() if r.status == "done"} == {
        fr079_log.name,
        intel_log.name,
    }
    assert "preset: paper" in (outdir / "batch-params.yaml").read_text(encoding="utf-8")

    other = runner.invoke(
        app, ["batch", str(fr079_log), "-o", str(outdir), "--set", "min_points=6"]
    )
    assert other.exit_code == 2
    assert "other parameters" in other.output and len(other.output.strip().splitlines()) == 1

    bad = runner.invoke(app, ["batch", str(fr079_log), "-o", str(outdir), "--set", "nope=1"])
    assert bad.exit_code == 2 and "unknown parameter 'nope'" in bad.output
