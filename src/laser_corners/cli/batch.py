"""``batch``: many recordings in parallel, resumably (docs/batch-and-viewer.md)."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any

import typer

from laser_corners.cli.app import app, fail
from laser_corners.cli.common import (
    OdomTopicOption,
    new_table,
    quoted,
    stop_progress,
    with_params_choice,
)
from laser_corners.cli.kernels import KernelCommand
from laser_corners.errors import MissingDependencyError

if TYPE_CHECKING:
    from laser_corners.batch import BatchReport
    from laser_corners.pipeline import ParamsChoice

__all__ = ["batch"]


_Inputs = Annotated[
    list[Path],
    typer.Argument(metavar="INPUT", help="Recordings (any kind detect reads).", show_default=False),
]
_Outdir = Annotated[
    Path,
    typer.Option(
        "--output",
        "-o",
        help="Output folder: one Parquet per input, "
        "manifest.jsonl, batch-params.yaml. Running again resumes.",
        show_default=False,
    ),
]
_Workers = Annotated[
    int | None,
    typer.Option("--workers", "-w", min=1, help="Worker processes (default: CPU cores)."),
]
_Scheduler = Annotated[
    str | None,
    typer.Option(
        "--scheduler",
        help="Dask: 'local' (a LocalCluster of --workers "
        "processes) or tcp://host:port (an existing cluster). Default: a local "
        "process pool.",
    ),
]
_Threads = Annotated[
    int | None,
    typer.Option(
        "--threads",
        min=1,
        help="numba threads per worker (default: cores // workers; 1 on a remote cluster).",
    ),
]
_Topic = Annotated[
    str | None,
    typer.Option(
        "--topic",
        "-t",
        help="LaserScan topic of the bags (default: every LaserScan topic, one output each).",
    ),
]


@app.command(cls=KernelCommand)
@with_params_choice
def batch(
    inputs: _Inputs,
    outdir: _Outdir,
    workers: _Workers = None,
    scheduler: _Scheduler = None,
    threads: _Threads = None,
    topic: _Topic = None,
    odom_topic: OdomTopicOption = None,
    *,
    choice: ParamsChoice,
) -> None:
    """Detect keypoints in many recordings in parallel (process pool or Dask), resumably."""
    from rich.console import Console
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn

    from laser_corners.batch import run_batch

    err = Console(stderr=True)
    bar = Progress(
        TextColumn("[bold]batch"),
        BarColumn(),
        MofNCompleteColumn(),
        TextColumn("{task.fields[scans]} scans"),
        console=err,
    )
    task = bar.add_task("jobs", total=None, scans=0)

    def planned(jobs: list[Any], done: list[Any]) -> None:
        if done:
            err.print(f"{len(done)} job(s) already done in {outdir}, skipped")
        bar.update(task, total=len(jobs))
        bar.start()  # only now: errors about the folder come without a bar

    def finished(result: Any) -> None:
        bar.update(task, advance=1, scans=bar.tasks[0].fields["scans"] + result.scans)
        if result.status == "failed":
            err.print(f"[red]failed[/red] {quoted(result.error)}", highlight=False)

    try:
        report = run_batch(
            inputs,
            outdir,
            params=choice,
            topic=topic,
            odom_topic=odom_topic,
            workers=workers,
            scheduler=scheduler,
            threads=threads,
            on_result=finished,
            on_plan=planned,
        )
    except MissingDependencyError as exc:
        raise fail(f"--scheduler: {exc}") from None
    finally:
        stop_progress(bar)
    _present(report, outdir, err)
    if report.interrupted:
        err.print("interrupted; run the same command again to resume")
        raise typer.Exit(130)
    if report.failed:
        raise typer.Exit(1)


def _present(report: BatchReport, outdir: Path, err: Any) -> None:
    from rich.console import Console

    for skipped in report.skipped:
        err.print(
            quoted(f"skipped {skipped.input}: not a recording ({skipped.reason})"),
            highlight=False,
            soft_wrap=True,
        )
    table = new_table(f"batch -> {outdir}", caption="r/d/w: seconds reading/detecting/writing")
    names = [quoted(Path(r.output).stem) for r in report.results]
    widest = max((len(name) for name in names), default=3)
    table.add_column("job", min_width=min(widest, 40), overflow="fold")
    table.add_column("status")
    for column in ("scans", "keypoints", "s", "scans/s", "r/d/w"):
        table.add_column(column, justify="right")
    for name, r in zip(names, report.results, strict=True):
        table.add_row(
            name,
            r.status,
            str(r.scans),
            str(r.keypoints),
            f"{r.seconds:.2f}",
            f"{r.scans_per_second:.0f}",
            f"{r.read_seconds:.2f}/{r.detect_seconds:.2f}/{r.write_seconds:.2f}",
        )
    Console().print(table)
    skipped = f", {len(report.skipped)} input(s) skipped" if report.skipped else ""
    typer.echo(
        f"{len(report.results)} job(s) run ({len(report.failed)} failed), "
        f"{len(report.already_done)} already done{skipped}; {report.n_scans} scans in "
        f"{report.seconds:.2f} s = {report.scans_per_second:.0f} scans/s with "
        f"{report.workers} worker(s); manifest: {outdir / 'manifest.jsonl'}"
    )
