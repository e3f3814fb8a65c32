"""Issue 13 on ``batch``: inputs that are not recordings, workers that outlive a killed batch,
finished outputs missing from the manifest after Ctrl-C."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from conftest import default_sigint
from laser_corners.batch import MANIFEST_NAME, BatchJob, Manifest, run_batch, run_job, worker
from laser_corners.cli import app
from laser_corners.io import KeypointWriter

CLI = [str(Path(sys.executable).with_name("laser-corners"))]


def _room_log(path: Path, n: int) -> Path:
    """A CARMEN log of ``n`` noisy 181-beam scans of a rectangular room (written here)."""
    rng = np.random.default_rng(len(path.name) + n)
    angles = np.linspace(-np.pi / 2, np.pi / 2, 181)
    base = np.minimum(
        3.0 / np.maximum(np.abs(np.cos(angles)), 1e-9),
        2.0 / np.maximum(np.abs(np.sin(angles)), 1e-9),
    )
    with path.open("w") as handle:
        for i in range(n):
            ranges = base + rng.normal(0.0, 0.005, base.size)
            body = " ".join(f"{r:.3f}" for r in ranges)
            handle.write(f"FLASER 181 {body} 0 0 0 0 0 0 {i * 0.1:.3f} host {i * 0.1:.3f}\n")
    return path


def _children(pid: int) -> list[int]:
    """Process ids whose parent is ``pid`` (Linux /proc)."""
    found = []
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                stat = (entry / "stat").read_text()
            except OSError:
                continue
            fields = stat[stat.rindex(")") + 2 :].split()
            if int(fields[1]) == pid and fields[0] != "Z":
                found.append(int(entry.name))
    return found


def _alive(pid: int) -> bool:
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return False
    return stat[stat.rindex(")") + 2] != "Z"


# ------------------------------------------------------------------ (3) not recordings
def test_glob_with_files_that_are_not_recordings(tmp_path: Path) -> None:
    data = tmp_path / "data"
    data.mkdir()
    _room_log(data / "room.clf", 20)
    (data / "room.relations").write_text("1.0 2.0 0.1 0 0 0 0 0.02\n")
    (data / "README.md").write_text("# the data\n")
    inputs = sorted(str(p) for p in data.iterdir())  # what the shell's data/* gives
    result = CliRunner().invoke(app, ["batch", *inputs, "-o", str(tmp_path / "out"), "-w", "1"])
    assert result.exit_code == 0, result.output
    skipped = [line for line in result.stderr.splitlines() if line.startswith("skipped ")]
    assert len(skipped) == 2, result.stderr
    assert any("room.relations: not a recording" in line for line in skipped)
    assert any("README.md: not a recording" in line for line in skipped)
    assert "1 job(s) run (0 failed)" in result.stdout and "2 input(s) skipped" in result.stdout
    records = Manifest(tmp_path / "out").load()
    assert [Path(k).name for k in records] == ["room.clf"]
    assert records[str((data / "room.clf").resolve())].status == "done"


def test_missing_inputs_still_fail(tmp_path: Path) -> None:
    log = _room_log(tmp_path / "room.clf", 5)
    report = run_batch([log, tmp_path / "gone.clf"], tmp_path / "out", workers=1)
    assert [r.status for r in sorted(report.results, key=lambda r: r.input)] == ["failed", "done"]
    assert report.skipped == []


# ------------------------------------------------------------------ (4) kill and Ctrl-C
@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")
def test_killed_batch_leaves_no_worker_running(tmp_path: Path) -> None:
    logs = [_room_log(tmp_path / f"log{i}.clf", 4000) for i in range(4)]
    command = [*CLI, "batch", *map(str, logs), "-o", str(tmp_path / "out"), "-w", "2"]
    process = subprocess.Popen(
        command, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True
    )
    workers: list[int] = []
    try:
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline and process.poll() is None:
            workers = [
                p
                for p in _children(process.pid)
                if b"spawn_main" in Path(f"/proc/{p}/cmdline").read_bytes()
            ]
            if len(workers) >= 2:
                break
            time.sleep(0.05)
        assert len(workers) >= 2 and process.poll() is None, "no workers seen"
        time.sleep(0.5)
        os.kill(process.pid, signal.SIGKILL)  # the batch only, not its process group
        process.wait(timeout=30)
        deadline = time.monotonic() + 20
        while time.monotonic() < deadline and any(map(_alive, workers)):
            time.sleep(0.1)
        assert not [p for p in workers if _alive(p)], "workers outlived the killed batch"
    finally:
        try:
            os.killpg(process.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass


def test_ctrl_c_keeps_every_finished_output_in_the_manifest(tmp_path: Path) -> None:
    logs = [_room_log(tmp_path / f"log{i}.clf", 300 + 400 * i) for i in range(5)]
    outdir = tmp_path / "out"
    command = [*CLI, "batch", *map(str, logs), "-o", str(outdir), "-w", "2"]
    process = subprocess.Popen(
        command,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        start_new_session=True,
        preexec_fn=default_sigint,
    )
    manifest = outdir / MANIFEST_NAME
    try:
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline and process.poll() is None:
            if manifest.exists() and manifest.read_text(encoding="utf-8").count("\n") >= 1:
                break
            time.sleep(0.02)
    finally:
        if process.poll() is None:
            os.killpg(process.pid, signal.SIGINT)  # Ctrl-C reaches the batch and its workers
        try:
            process.wait(timeout=120)
        except subprocess.TimeoutExpired:  # a hang fails the test, and leaves no process
            os.killpg(process.pid, signal.SIGKILL)
            process.wait()
            raise
    assert process.returncode in (0, 130)
    records = [json.loads(line) for line in manifest.read_text(encoding="utf-8").splitlines()]
    recorded = {r["output"] for r in records if r["status"] == "done"}
    finished = {p.name for p in outdir.glob("*.parquet")}
    assert finished and finished <= recorded  # no finished output missing from the manifest
    assert list(outdir.glob("*.partial")) == []


@pytest.mark.parametrize("stop", [KeyboardInterrupt, RuntimeError], ids=["ctrl-c", "error"])
def test_stopped_job_removes_its_partial_even_when_the_writer_fails_to_close(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, stop: type[BaseException]
) -> None:
    """A writer stopped mid-write may raise on close; the partial output must go anyway
    (issue 21: a Ctrl-C'd process-pool batch sometimes left ``*.partial``)."""

    class Stuck(KeypointWriter):
        def close(self) -> None:
            raise OSError("close of a writer stopped mid-write")

    def opened(recording: object, partial: Path, job: object) -> KeypointWriter:
        partial.write_bytes(b"PAR1 half a file")  # what the writer had written so far
        return Stuck()

    def detect(*args: object, **kwargs: object) -> None:
        raise stop("stopped")

    monkeypatch.setattr(worker, "_open_writer", opened)
    monkeypatch.setattr(worker, "detect_recording", detect)
    job = BatchJob(str(_room_log(tmp_path / "room.log", 3)), None, "room.parquet")
    out = tmp_path / "out"
    out.mkdir()
    if stop is KeyboardInterrupt:
        with pytest.raises(KeyboardInterrupt):
            run_job(job, out, threads=1)
    else:
        assert run_job(job, out, threads=1).status == "failed"
    assert sorted(p.name for p in out.iterdir() if p.name != "errors") == []


# ------------------------------------------- an output is named only once it is recorded
@pytest.mark.parametrize("where", ["here", "pool"])
def test_an_output_keeps_its_temporary_name_until_the_batch_records_it(
    tmp_path: Path, where: str
) -> None:
    """CI at f3790ad: a pool worker finished and renamed a job that Ctrl-C had kept from the
    manifest (handed out an instant before the parent was stopped), so a finished output
    had no record. Now only the batch renames, after recording: a result that never reaches
    ``deliver`` leaves no output under its final name."""
    from laser_corners.batch.executors import run_here, run_pool
    from laser_corners.pipeline import ParamsChoice

    logs = [_room_log(tmp_path / f"log{i}.clf", 30) for i in range(2)]
    jobs = [BatchJob(str(log), None, f"{log.stem}.parquet") for log in logs]
    out = tmp_path / "out"
    out.mkdir()
    came_back = []

    def stopped_before_recording(result: object) -> None:
        came_back.append(result)
        raise KeyboardInterrupt  # Ctrl-C as the first result comes back

    with pytest.raises(KeyboardInterrupt):
        if where == "here":
            run_here(jobs, out, ParamsChoice(), 1, stopped_before_recording)
        else:
            run_pool(jobs, out, ParamsChoice(), 2, 1, stopped_before_recording)
    assert came_back and came_back[0].status == "done"
    assert not list(out.glob("*.parquet"))  # finished, not recorded: not under its name


def test_ctrl_c_while_a_job_is_recorded_keeps_the_record_and_the_output_together(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Ctrl-C arriving while the manifest takes a record waits for the rename, then stops."""
    logs = [_room_log(tmp_path / f"log{i}.clf", 30 + i) for i in range(2)]
    append = Manifest.append

    def append_then_ctrl_c(self: Manifest, result: object) -> None:
        append(self, result)
        os.kill(os.getpid(), signal.SIGINT)

    monkeypatch.setattr(Manifest, "append", append_then_ctrl_c)
    out = tmp_path / "out"
    # Python's own handler, as in a terminal (a background job inherits SIGINT ignored)
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        report = run_batch(logs, out, workers=1, threads=1)
    finally:
        signal.signal(signal.SIGINT, previous)
    assert report.interrupted and len(report.results) == 1
    records = Manifest(out).load()
    assert [r.output for r in records.values()] == [report.results[0].output]
    assert sorted(p.name for p in out.glob("*.parquet")) == [report.results[0].output]
    assert not list(out.glob("*.partial"))
