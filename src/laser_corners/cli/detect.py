"""Commands on one recording: ``detect``, ``info``, ``plot``, ``params`` (docs/io-and-cli.md)."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any

import typer

from laser_corners.cli.app import app
from laser_corners.cli.common import (
    InputArg,
    OdomTopicOption,
    TopicOption,
    image_file,
    new_table,
    params_choice,
    quoted,
    stop_progress,
    with_params_choice,
    writable_file,
)
from laser_corners.cli.kernels import KernelCommand

if TYPE_CHECKING:
    from laser_corners.pipeline import DetectRun, ParamsChoice

__all__ = ["detect", "info", "params", "plot"]


@app.command()
def params(
    params_file: Annotated[
        Path | None, typer.Option("--params", help="YAML/TOML file to load first.")
    ] = None,
    set_: Annotated[
        list[str] | None, typer.Option("--set", help="Override a field: key=value.")
    ] = None,
) -> None:
    """Print detector parameters as YAML (the paper's defaults unless overridden)."""
    choice = params_choice(None, params_file, set_)
    typer.echo(choice.resolve(None).to_yaml(), nl=False)


def _progress_bar() -> Any:
    from rich.console import Console
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

    return Progress(
        TextColumn("[bold]{task.description}"),
        BarColumn(),
        MofNCompleteColumn(),
        TextColumn("{task.fields[rate]:.0f} scans/s"),
        TextColumn("{task.fields[keypoints]} keypoints"),
        TimeElapsedColumn(),
        console=Console(stderr=True),
    )


def _summary_table(run: DetectRun) -> Any:
    summary, recording = run.summary, run.recording
    table = new_table(recording.description, "", "", show_header=False)
    expected = recording.source.n_scans  # from the bag's index; None: unknown
    read_all = expected is None or summary.interrupted or summary.n_scans == expected
    table.add_row("scans", str(summary.n_scans) if read_all else f"{summary.n_scans} of {expected}")
    table.add_row("keypoints", str(summary.n_keypoints))
    table.add_row("keypoints/scan", f"{summary.keypoints_per_scan:.2f}")
    table.add_row("seconds", f"{summary.seconds:.2f} ({summary.scans_per_second:.0f} scans/s)")
    table.add_row("parameters", recording.preset)
    for reason, count in sorted(summary.skipped.items()):
        table.add_row("skipped", quoted(f"{count} {reason}"))
    for example in summary.skip_examples:
        table.add_row("", quoted(f"first at {example}"))
    table.add_row("output", quoted(run.output) if run.output else "(none; use -o FILE)")
    return table


@app.command(cls=KernelCommand)
@with_params_choice
def detect(
    input_path: InputArg,
    output: Annotated[
        Path | None,
        typer.Option(
            "--output",
            "-o",
            help="Keypoints file: .csv, .parquet, or a copy of the input bag with keypoint "
            "topics (.bag for ROS 1, .mcap for ROS 2). Default: summary only.",
        ),
    ] = None,
    topic: TopicOption = None,
    odom_topic: OdomTopicOption = None,
    compression: Annotated[
        str | None,
        typer.Option(
            "--compression",
            help="Chunk compression of a .bag output: lz4 (default), bz2 or none, as rosbag "
            "record offers.",
        ),
    ] = None,
    *,
    choice: ParamsChoice,
) -> None:
    """Detect keypoints in every scan of a recording; progress bar, then a summary."""
    from rich.console import Console

    from laser_corners.pipeline import detect_file

    if output is not None:
        writable_file(output)
    bar = _progress_bar()
    task = bar.add_task(input_path.name, total=None, rate=0.0, keypoints=0)

    def opened(recording: Any) -> None:
        bar.update(task, total=recording.source.n_scans)
        bar.start()

    def update(run: Any) -> None:
        bar.update(
            task, completed=run.n_scans, rate=run.scans_per_second, keypoints=run.n_keypoints
        )

    try:
        result = detect_file(
            input_path,
            output,
            topic=topic,
            params=choice,
            on_open=opened,
            progress=update,
            compression=compression,
            odom_topic=odom_topic,
        )
    finally:
        stop_progress(bar)
    Console().print(_summary_table(result))
    summary = result.summary
    if summary.interrupted:
        kept = f"; {result.kept}" if result.output else ""
        typer.echo(
            f"interrupted at {summary.position} after {summary.n_scans} scans"
            f" ({summary.n_keypoints} keypoints){kept}",
            err=True,
        )
        raise typer.Exit(130)


@app.command()
def info(input_path: InputArg, topic: TopicOption = None) -> None:
    """Show what a recording holds: kind, topics, scan geometry, counts, poses."""
    from rich.console import Console

    from laser_corners.pipeline import laser_topic_sources

    sources = laser_topic_sources(input_path, topic)
    description = sources[0].describe()
    console = Console()
    console.print(_head_table(input_path, description))
    if "topics" in description:
        topics = new_table("topics", "topic", "type", "messages")
        for name, entry in dict(description["topics"]).items():  # type: ignore[call-overload]
            topics.add_row(quoted(name), quoted(entry["type"]), str(entry["count"]))
        console.print(topics)
    console.print(_scans_table(sources, description))
    if len(sources) > 1:
        console.print("several LaserScan topics; pick one for detect/plot with:")
        for source in sources:
            console.print(f"  --topic {quoted(source.topic)}", highlight=False)
    odometry = list(getattr(sources[0], "odom_topics", []))
    if len(odometry) > 1:  # a listing reads none of them: say how to choose
        console.print("several Odometry topics; pick the scan poses' odometry with:")
        for name in odometry:
            console.print(f"  --odom-topic {quoted(name)}", highlight=False)


def _head_table(input_path: Path, description: dict[str, Any]) -> Any:
    head = new_table(str(input_path), "", "", show_header=False)
    head.add_row("kind", str(description["kind"]))
    for key in ("duration_s", "odometry"):
        if key in description:
            head.add_row(key.replace("_s", " (s)"), quoted(description[key]))
    for word, count in sorted(dict(description.get("records", {})).items()):
        head.add_row(quoted(f"{word} lines"), str(count))
    return head


def _scans_table(sources: list[Any], description: dict[str, Any]) -> Any:
    import math

    keys = (
        "scans",
        "beams",
        "resolution (deg)",
        "field of view (deg)",
        "range (m)",
        "frame",
        "first stamp (s)",
        "sensor pose",
    )
    rows: dict[str, list[str]] = {k: [] for k in keys}
    labels = []
    for source in sources:
        scan = source.first_scan()
        labels.append(quoted(source.topic or source.kind))
        count = description["scans"] if source.n_scans is None else source.n_scans
        if scan is None:
            values = [str(count)] + ["-"] * (len(rows) - 1)
        else:
            values = [
                str(count),
                str(scan.n_beams),
                f"{scan.resolution_deg:.4g}",
                f"{math.degrees(abs(scan.angle_increment) * scan.n_beams):.1f}",
                f"{scan.range_min:g} - {scan.range_max:g}",
                quoted(scan.frame_id or "-"),
                f"{scan.stamp:.6f}" if scan.stamp is not None else "-",
                "yes" if scan.pose is not None else "no",
            ]
        for key, value in zip(rows, values, strict=True):
            rows[key].append(value)
    table = new_table("scans (geometry of the first scan)", "", *labels)
    stamp_width = max(map(len, rows["first stamp (s)"]))
    for column in table.columns[1:]:  # a stamp is never folded over two lines
        column.min_width = stamp_width
    for key, values in rows.items():
        table.add_row(key, *values)
    return table


@app.command(cls=KernelCommand)
@with_params_choice
def plot(
    input_path: InputArg,
    scan_index: Annotated[int, typer.Option("--scan", "-n", help="Scan index (0-based).")] = 0,
    output: Annotated[
        Path | None, typer.Option("--output", "-o", help="PNG to write (default INPUT_scanN.png).")
    ] = None,
    topic: TopicOption = None,
    odom_topic: OdomTopicOption = None,
    *,
    choice: ParamsChoice,
) -> None:
    """Plot one scan: points, per-point candidates and keypoints (sensor frame)."""
    default = Path(f"{input_path.name.split('.')[0]}_scan{scan_index}.png")
    output, kind = image_file(output or default)
    topics = (topic, odom_topic)
    n_keypoints, n_candidates = _plot_scan(input_path, scan_index, (output, kind), topics, choice)
    typer.echo(f"wrote {output} ({n_keypoints} keypoints, {n_candidates} candidates)")


def _plot_scan(
    input_path: Path,
    index: int,
    output: tuple[Path, str],
    topics: tuple[str | None, str | None],
    choice: Any,
) -> tuple[int, int]:
    """Plot scan ``index`` with its candidates and keypoints into ``output`` (a path and an
    image format); the counts. ``topics``: the LaserScan topic and the odometry."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from laser_corners.pipeline import open_recording, scan_at
    from laser_corners.viz.plots import plot_scan

    with open_recording(input_path, topics[0], choice, odom_topic=topics[1]) as recording:
        scan = recording.first if index == 0 else scan_at(recording.source, index)
        keypoints, candidates = recording.detector.detect(scan, return_candidates=True)
    fig, ax = plt.subplots(figsize=(8, 8))
    try:
        plot_scan(ax, scan, keypoints=keypoints, candidates=candidates)
        stamp = f", t = {scan.stamp:.3f} s" if scan.stamp is not None else ""
        ax.set_title(
            f"{input_path.name} scan {index}{stamp}: {len(keypoints)} keypoints "
            f"({recording.preset})"
        )
        fig.savefig(output[0], format=output[1], dpi=150, bbox_inches="tight")
    finally:
        plt.close(fig)
    return len(keypoints), len(candidates)
