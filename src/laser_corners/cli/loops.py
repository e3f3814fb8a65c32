"""``evaluate loops``: place recognition with FLIRT's protocol (docs/place-recognition.md).

Options -> one library call (:func:`laser_corners.eval.loops.evaluate_loops`) -> a line per
method on the console and ``loops.json``, ``loops.md`` and the plot in ``--output`` (written
after each method, so an interrupted run keeps the methods that finished).
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer
from rich.console import Console

from laser_corners.cli.app import evaluate_app
from laser_corners.cli.common import InputArg, OdomTopicOption, TopicOption, new_folder, quoted
from laser_corners.cli.evaluate import TrajectoryOption, method_list
from laser_corners.cli.kernels import KernelCommand

if TYPE_CHECKING:
    from laser_corners.eval.loops import LoopsResult

__all__ = ["evaluate_loops_command"]


@evaluate_app.command("loops", cls=KernelCommand)
def evaluate_loops_command(
    input_path: InputArg,
    output: Annotated[
        Path, typer.Option("--output", "-o", help="Folder for loops.json, loops.md and the plot.")
    ] = Path("loops"),
    max_scans: Annotated[
        int | None, typer.Option("--max-scans", min=2, help="Use at most this many scans.")
    ] = None,
    methods: Annotated[
        str | None,
        typer.Option(
            "--methods",
            help="Comma-separated: paper, auto, robust, split-and-merge, falko-like (default: "
            "laser_corners.eval.methods.DEFAULT_METHODS).",
        ),
    ] = None,
    min_inliers: Annotated[
        int | None,
        typer.Option("--min-inliers", min=1, help="Detection threshold T (default: the library's)"),
    ] = None,
    window: Annotated[
        float | None,
        typer.Option(
            "--window",
            help="Exclude candidates closer than this in travelled path, metres "
            "(default: LoopsConfig.window_travel).",
        ),
    ] = None,
    topic: TopicOption = None,
    odom_topic: OdomTopicOption = None,
    trajectory: TrajectoryOption = None,
) -> None:
    """Place recognition with FLIRT's protocol on a log with corrected poses.

    Each scan is registered against every scan outside its window with laser_corners.matching
    (scan check on); precision and recall over the inlier threshold, per method, all through
    one descriptor and matcher (docs/place-recognition.md).
    """
    # the library is imported after the options are parsed, so that --help stays instant
    from laser_corners.eval.loops import LoopsConfig, evaluate_loops
    from laser_corners.eval.real import load_scans
    from laser_corners.viz.loops_report import loops_rows, write_loops_report

    console = Console(stderr=True)
    t0 = time.perf_counter()
    given = {
        "min_inliers": min_inliers,
        "max_scans": max_scans,
        "window_travel": window,
        "methods": None if methods is None else method_list(methods),
    }
    config = LoopsConfig(**{k: v for k, v in given.items() if v is not None})
    new_folder(output)
    with _Phases(console) as progress:
        progress(f"reading {input_path.name}", 0, None)
        scans, pose_source = load_scans(input_path, topic, max_scans, trajectory, odom_topic)
        if pose_source.endswith("/tf"):  # a bag's odometry (eval.real.ODOMETRY_POSES)
            progress.warn(
                f"the poses are the bag's raw odometry ({pose_source}), not ground truth: "
                "a correct match counts as wrong where odometry drifted, so precision means "
                "little; give corrected poses with --trajectory"
            )

        def save(partial: LoopsResult) -> None:
            write_loops_report(partial, output)

        result = evaluate_loops(scans, config, input_path.name, progress, on_method=save)
    for row in loops_rows(result):
        p = "n/a" if row["precision"] is None else f"{row['precision']:.3f}"
        console.print(
            f"{row['method']}: precision {p}, recall {row['recall']:.3f} at T="
            f"{row['min_inliers']}, {row['ms_per_pair']:.4f} ms/pair",
            highlight=False,
        )
    typer.echo(f"wrote {output / 'loops.json'} in {time.perf_counter() - t0:.1f} s")


class _Phases:
    """Progress over the evaluation's phases from the start: a rich bar on a terminal, one
    line per phase on stderr otherwise (a bar off a terminal shows nothing until the end)."""

    def __init__(self, console: Console) -> None:
        # rich.progress only when the command runs (not for --help)
        from rich.progress import (
            BarColumn,
            MofNCompleteColumn,
            Progress,
            TextColumn,
            TimeElapsedColumn,
        )

        self.console = console
        columns = (TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn())
        self.bar = Progress(*columns, TimeElapsedColumn(), console=console, transient=True)
        self.task = self.bar.add_task("loops", total=None)
        self.stage = ""

    def __enter__(self) -> _Phases:
        self.bar.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.bar.live.stop()  # not bar.stop(): off a terminal it adds an empty line

    def __call__(self, stage: str, done: int, total: int | None) -> None:
        if stage != self.stage and not self.console.is_terminal:
            self.console.print(f"{quoted(stage)} ...", highlight=False, soft_wrap=True)
        self.stage = stage
        self.bar.update(self.task, description=quoted(stage), completed=done, total=total)

    def warn(self, message: str) -> None:
        """One warning line (above the bar on a terminal)."""
        text = f"[yellow]warning:[/yellow] {quoted(message)}"
        self.console.print(text, highlight=False, soft_wrap=True)
