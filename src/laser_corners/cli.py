"""The ``laser-corners`` command line (typer + rich).

Heavy modules are imported inside the commands, so ``--help`` stays instant. Known errors
(:class:`~laser_corners.errors.LaserCornersError`, missing files) print one line and exit 2.
"""

from __future__ import annotations

import sys
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

from laser_corners.errors import LaserCornersError

if TYPE_CHECKING:
    from laser_corners.params import DetectorParams

app = typer.Typer(
    name="laser-corners",
    help="Corner-like keypoints in 2D laser scans (Sousa et al., ICARA 2024).",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)


def fail(message: str, code: int = 2) -> typer.Exit:
    """Print ``message`` as one line on stderr and return the exit to raise."""
    typer.echo(f"laser-corners: error: {message}", err=True)
    return typer.Exit(code)


@app.command()
def demo(
    output: Annotated[Path, typer.Option("--output", "-o", help="PNG to write.")] = Path(
        "demo.png"
    ),
    noise: Annotated[float, typer.Option(help="Range noise sigma, metres.")] = 0.005,
) -> None:
    """Simulate a UST-10LX scan of a room, detect corners, compare with the truth, plot."""
    from laser_corners.demo import run_demo

    missed = run_demo(output, noise_sigma=noise)
    if missed:
        raise typer.Exit(1)


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
    from laser_corners.params import DetectorParams

    p = DetectorParams.from_file(params_file) if params_file else DetectorParams()
    if set_:
        p = p.with_overrides(set_)
    typer.echo(p.to_yaml(), nl=False)


@app.command(
    context_settings={"allow_extra_args": True, "ignore_unknown_options": True},
)
def ros1(
    ctx: typer.Context,
    debug: Annotated[bool, typer.Option("--debug", help="Log per-scan latency.")] = False,
    package_path: Annotated[
        bool,
        typer.Option(
            "--package-path", help="Print the folder to add to ROS_PACKAGE_PATH, then exit."
        ),
    ] = False,
) -> None:
    """Run the ROS 1 node: scan -> corners (PoseArray) and corner_markers (MarkerArray).

    Extra arguments go to rospy: remappings (scan:=/base_scan) and private parameters
    (_preset:=paper, _min_points:=6). See docs/ros.md.
    """
    if package_path:
        from laser_corners import ros

        typer.echo(Path(ros.__file__).resolve().parent)
        return
    from laser_corners.ros.ros1_node import main as run_ros1_node

    run_ros1_node(list(ctx.args), debug=debug)


# ------------------------------------------------------------------ recordings (docs/io-and-cli.md)
InputArg = Annotated[
    Path,
    typer.Argument(
        metavar="INPUT",
        help="ROS 1 .bag, ROS 2 bag (directory, .db3, .mcap), CARMEN log (.clf, .gz), .npz, .csv.",
        show_default=False,
    ),
]
TopicOption = Annotated[
    str | None, typer.Option("--topic", "-t", help="LaserScan topic (default: the only one).")
]
PresetOption = Annotated[
    str | None,
    typer.Option(
        "--preset", help="Parameter preset: paper (published values, default), auto (adapted "
        "to the scan's angular resolution) or robust (adapted to the range noise estimated "
        "from the scan)."
    ),
]  # fmt: skip
ParamsOption = Annotated[
    Path | None, typer.Option("--params", help="YAML/TOML parameter file (instead of a preset).")
]
SetOption = Annotated[
    list[str] | None, typer.Option("--set", help="Override a parameter: key=value (repeatable).")
]


@contextmanager
def _known_errors() -> Iterator[None]:
    """Turn known errors into one line on stderr and exit code 2 (also under CliRunner)."""
    try:
        yield
    except LaserCornersError as exc:
        raise fail(str(exc)) from None


def _resolve_params(
    preset: str | None, params_file: Path | None, set_: list[str] | None, scan: object
) -> DetectorParams:
    from laser_corners.errors import InvalidParamsError
    from laser_corners.params import DetectorParams
    from laser_corners.presets import get_preset

    if preset is not None and params_file is not None:
        raise InvalidParamsError("give --preset or --params, not both")
    base = (
        DetectorParams.from_file(params_file)
        if params_file is not None
        else get_preset(preset or "paper", scan)  # type: ignore[arg-type]
    )
    return base.with_overrides(set_) if set_ else base


@app.command()
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
    params_file: ParamsOption = None,
    set_: SetOption = None,
    preset: PresetOption = None,
) -> None:
    """Detect keypoints in every scan of a recording; progress bar, then a summary."""
    with _known_errors():
        from rich.console import Console
        from rich.progress import (
            BarColumn,
            MofNCompleteColumn,
            Progress,
            TextColumn,
            TimeElapsedColumn,
        )
        from rich.table import Table

        from laser_corners.detector import CornerDetector
        from laser_corners.errors import InputError
        from laser_corners.io import open_keypoint_writer, open_scans
        from laser_corners.io.run import RunSummary, detect_recording

        source = open_scans(input_path, topic)
        first = source.first_scan()
        if first is None:
            raise InputError(
                f"{input_path}: no readable scan"
                + (f" ({', '.join(source.skip_examples)})" if source.skip_examples else "")
            )
        params = _resolve_params(preset, params_file, set_, first)
        params_yaml = params.to_yaml()
        writer = open_keypoint_writer(
            output, source, with_map=first.pose is not None,
            metadata={"laser_corners.params": params_yaml, "laser_corners.input": str(input_path)},
        )  # fmt: skip
        if output is not None:
            Path(f"{output}.params.yaml").write_text(params_yaml, encoding="utf-8")
        err = Console(stderr=True)
        bar = Progress(
            TextColumn("[bold]{task.description}"), BarColumn(), MofNCompleteColumn(),
            TextColumn("{task.fields[rate]:.0f} scans/s"),
            TextColumn("{task.fields[keypoints]} keypoints"), TimeElapsedColumn(),
            console=err,
        )  # fmt: skip
        with bar:
            task = bar.add_task(input_path.name, total=source.n_scans, rate=0.0, keypoints=0)

            def update(run: RunSummary) -> None:
                bar.update(
                    task, completed=run.n_scans, rate=run.scans_per_second,
                    keypoints=run.n_keypoints,
                )  # fmt: skip

            summary = detect_recording(source, CornerDetector(params), writer, progress=update)
        table = Table(
            title=f"{input_path.name} ({source.kind}"
            + (f" {source.topic}" if source.topic else "")
            + ")",
            show_header=False,
        )
        table.add_row("scans", str(summary.n_scans))
        table.add_row("keypoints", str(summary.n_keypoints))
        table.add_row("keypoints/scan", f"{summary.keypoints_per_scan:.2f}")
        table.add_row("seconds", f"{summary.seconds:.2f} ({summary.scans_per_second:.0f} scans/s)")
        table.add_row("parameters", params_file.name if params_file else (preset or "paper"))
        for reason, count in sorted(summary.skipped.items()):
            table.add_row("skipped", f"{count} {reason}")
        for example in summary.skip_examples:
            table.add_row("", f"first at {example}")
        table.add_row("output", str(output) if output else "(none; use -o FILE)")
        Console().print(table)
        if summary.interrupted:
            kept = f"; {output} keeps what was written" if output else ""
            typer.echo(
                f"interrupted at {summary.position} after {summary.n_scans} scans"
                f" ({summary.n_keypoints} keypoints){kept}",
                err=True,
            )
            raise typer.Exit(130)


@app.command()
def info(input_path: InputArg, topic: TopicOption = None) -> None:
    """Show what a recording holds: kind, topics, scan geometry, counts, poses."""
    with _known_errors():
        import math

        from rich.console import Console
        from rich.table import Table

        from laser_corners.io import detect_kind, open_scans
        from laser_corners.io.rosbag import BagSource

        kind = detect_kind(input_path)
        if kind in ("ros1", "ros2", "mcap"):
            bag = BagSource(input_path, kind, topic, strict=False)
            sources = [bag] if topic else [
                BagSource(input_path, kind, t) for t in bag.laser_topics
            ]  # fmt: skip
            description = bag.describe()
        else:
            sources = [open_scans(input_path, topic)]
            description = sources[0].describe()
        console = Console()
        head = Table(title=str(input_path), show_header=False)
        head.add_row("kind", kind)
        for key in ("duration_s", "odometry"):
            if key in description:
                head.add_row(key.replace("_s", " (s)"), str(description[key]))
        for word, count in sorted(dict(description.get("records", {})).items()):  # type: ignore[call-overload]
            head.add_row(f"{word} lines", str(count))
        console.print(head)
        if "topics" in description:
            topics = Table("topic", "type", "messages", title="topics")
            for name, entry in dict(description["topics"]).items():  # type: ignore[call-overload]
                topics.add_row(name, entry["type"], str(entry["count"]))
            console.print(topics)
        rows: dict[str, list[str]] = {
            k: []
            for k in (
                "scans", "beams", "resolution (deg)", "field of view (deg)", "range (m)",
                "frame", "first stamp (s)", "sensor pose",
            )
        }  # fmt: skip
        labels = []
        for source in sources:
            scan = source.first_scan()
            labels.append(source.topic or source.kind)
            count = description["scans"] if source.n_scans is None else source.n_scans
            if scan is None:
                values = [str(count)] + ["-"] * (len(rows) - 1)
            else:
                values = [
                    str(count), str(scan.n_beams), f"{scan.resolution_deg:.4g}",
                    f"{math.degrees(abs(scan.angle_increment) * scan.n_beams):.1f}",
                    f"{scan.range_min:g} - {scan.range_max:g}", scan.frame_id or "-",
                    f"{scan.stamp:.6f}" if scan.stamp is not None else "-",
                    "yes" if scan.pose is not None else "no",
                ]  # fmt: skip
            for key, value in zip(rows, values, strict=True):
                rows[key].append(value)
        scans = Table("", *labels, title="scans (geometry of the first scan)")
        for key, values in rows.items():
            scans.add_row(key, *values)
        console.print(scans)
        if len(sources) > 1:
            console.print("several LaserScan topics; pick one for detect/plot with:")
            for source in sources:
                console.print(f"  --topic {source.topic}")


@app.command()
def plot(
    input_path: InputArg,
    scan_index: Annotated[int, typer.Option("--scan", "-n", help="Scan index (0-based).")] = 0,
    output: Annotated[
        Path | None, typer.Option("--output", "-o", help="PNG to write (default INPUT_scanN.png).")
    ] = None,
    topic: TopicOption = None,
    params_file: ParamsOption = None,
    set_: SetOption = None,
    preset: PresetOption = None,
) -> None:
    """Plot one scan: points, per-point candidates and keypoints (sensor frame)."""
    with _known_errors():
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        from laser_corners.detector import CornerDetector
        from laser_corners.io import open_scans
        from laser_corners.viz.plots import plot_scan

        source = open_scans(input_path, topic)
        scan = source.scan_at(scan_index)
        params = _resolve_params(preset, params_file, set_, scan)
        keypoints, candidates = CornerDetector(params).detect(scan, return_candidates=True)
        output = output or Path(f"{input_path.name.split('.')[0]}_scan{scan_index}.png")
        fig, ax = plt.subplots(figsize=(8, 8))
        try:
            plot_scan(ax, scan, keypoints=keypoints, candidates=candidates)
            stamp = f", t = {scan.stamp:.3f} s" if scan.stamp is not None else ""
            ax.set_title(
                f"{input_path.name} scan {scan_index}{stamp}: {len(keypoints)} keypoints "
                f"({params_file.name if params_file else preset or 'paper'})"
            )
            fig.savefig(output, dpi=150, bbox_inches="tight")
        finally:
            plt.close(fig)
        typer.echo(f"wrote {output} ({len(keypoints)} keypoints, {len(candidates)} candidates)")


# ------------------------------------------------------------ evaluate (docs/real-evaluation.md)
evaluate_app = typer.Typer(
    help="Evaluate detectors: on simulated scans (sim) or real recordings with poses (real).",
    no_args_is_help=True,
)
app.add_typer(evaluate_app, name="evaluate")


@evaluate_app.command("real")
def evaluate_real_command(
    input_path: InputArg,
    output: Annotated[
        Path, typer.Option("--output", "-o", help="Folder for the figures, arrays and report.md.")
    ] = Path("report"),
    topic: TopicOption = None,
    preset: PresetOption = None,
    params_file: ParamsOption = None,
    set_: SetOption = None,
    trajectory: Annotated[
        Path | None,
        typer.Option(
            "--trajectory",
            help="TUM trajectory (t x y z qx qy qz qw) giving the "
            "sensor poses, instead of the recording's.",
        ),
    ] = None,
    relations: Annotated[
        Path | None,
        typer.Option(
            "--relations",
            help="Ground-truth relative poses (t1 t2 x y z roll pitch "
            "yaw) for repeatability. Default: <name>.relations beside a <name>.bag, "
            "else pairs from the poses.",
        ),
    ] = None,
    relations_mount: Annotated[
        str,
        typer.Option(
            "--relations-mount", help="Sensor pose x,y,theta in the robot frame of the relations."
        ),
    ] = "0,0,0",
    max_scans: Annotated[
        int | None, typer.Option("--max-scans", min=1, help="Read at most this many scans.")
    ] = None,
    max_pairs: Annotated[
        int, typer.Option("--max-pairs", min=1, help="At most this many repeatability pairs.")
    ] = 1000,
    max_range: Annotated[
        float | None,
        typer.Option(
            "--max-range",
            help="Only count cells/keypoints this close to the sensor "
            "as in view, metres (default: the sensor's range).",
        ),
    ] = None,
    resolution: Annotated[
        float, typer.Option("--resolution", help="Observability cell size, metres.")
    ] = 0.03,
    association_radius: Annotated[
        float, typer.Option("--association-radius", help="Keypoint-feature radius, metres.")
    ] = 0.06,
    min_ratio: Annotated[
        float, typer.Option("--min-ratio", help="Lowest N8 observability of a persistent feature.")
    ] = 0.25,
    min_views: Annotated[
        int, typer.Option("--min-views", help="Fewest scans that saw a persistent feature's cell.")
    ] = 20,
    occlusion: Annotated[
        bool, typer.Option("--occlusion/--no-occlusion", help="Ray-cast against each scan.")
    ] = True,
    methods: Annotated[
        str,
        typer.Option(
            "--methods", help="Repeatability rows, comma-separated: preset names, baseline, falko."
        ),
    ] = "paper,auto,baseline,falko",
) -> None:
    """Paper section IV on a recording with poses (maps, features, association, repeatability).

    Writes the observability maps, persistent features, association matrix and histogram,
    the repeatability table and report.md into --output (docs/real-evaluation.md).
    """
    import time

    from rich.console import Console
    from rich.table import Table

    from laser_corners.errors import InvalidParamsError
    from laser_corners.eval.poses import read_relations
    from laser_corners.eval.real import (
        RealEvalConfig,
        default_relations,
        evaluate_real,
        load_scans,
    )
    from laser_corners.eval.report import repeatability_rows, write_real_report

    console = Console(stderr=True)
    with _known_errors():
        try:
            mount = tuple(float(v) for v in relations_mount.split(","))
        except ValueError:
            mount = ()
        if len(mount) != 3:
            raise InvalidParamsError(f"--relations-mount needs x,y,theta, got {relations_mount!r}")
        t0 = time.perf_counter()
        scans, pose_source = load_scans(input_path, topic, max_scans, trajectory)
        params = _resolve_params(preset, params_file, set_, scans[0])
        relations_path = relations if relations is not None else default_relations(input_path)
        config = RealEvalConfig(
            preset=preset or "paper",
            resolution=resolution,
            association_radius=association_radius,
            min_ratio=min_ratio,
            min_views=min_views,
            occlusion=occlusion,
            max_range=max_range,
            max_scans=max_scans,
            max_pairs=max_pairs,
            relations_mount=mount,  # type: ignore[arg-type]
            methods=tuple(m.strip() for m in methods.split(",") if m.strip()),
        )
        custom = params_file is not None or bool(set_)
        result = evaluate_real(
            scans, config,
            relations=read_relations(relations_path) if relations_path is not None else None,
            params=params if custom else None,
            source=input_path.name, pose_source=pose_source,
            progress=lambda message: console.print(message, highlight=False),
        )  # fmt: skip
        paths = write_real_report(result, output)
    counts = result.persistence_counts()
    a = result.association
    console.print(
        f"{len(result.features)} persistent features (N8 >= 50 %: {counts[0.5]}, >= 75 %: "
        f"{counts[0.75]}, 100 %: {counts[1.0]}); association: max std "
        f"{a.max_std * 1000:.1f} mm, {100 * a.share_std_within:.1f} % of {a.n_pairs_with_std} "
        f"pairs <= {a.threshold * 1000:g} mm, {a.n_pairs_never_together} pairs never together",
        highlight=False,
    )
    table = Table(title=f"repeatability, {result.n_pairs} pairs ({result.pairs_source})")
    table.add_column("method")
    table.add_column("kp/scan", justify="right")
    table.add_column("visible", justify="right")
    for r in config.radii:
        table.add_column(f"r={r:g} m", justify="right")
    for row in repeatability_rows(result):
        values = [row[f"repeatability_r{r:g}"] for r in config.radii]
        table.add_row(row["method"], f"{row['keypoints_per_scan']:.2f}", str(row["visible"]),
                      *("n/a" if v is None else f"{100 * v:.1f} %" for v in values))  # fmt: skip
    console.print(table)
    typer.echo(f"wrote {len(paths)} files to {output} ({paths['report.md']}) in "
               f"{time.perf_counter() - t0:.1f} s")  # fmt: skip


@evaluate_app.command("loops")
def evaluate_loops_command(
    input_path: InputArg,
    output: Annotated[
        Path, typer.Option("--output", "-o", help="Folder for loops.json, loops.md and the plot.")
    ] = Path("loops"),
    max_scans: Annotated[
        int | None, typer.Option("--max-scans", min=2, help="Use at most this many scans.")
    ] = None,
    methods: Annotated[
        str,
        typer.Option(
            "--methods", help="Comma-separated: paper, auto, robust, split-and-merge, falko-like."
        ),
    ] = "paper,auto,split-and-merge,falko-like",
    min_inliers: Annotated[
        int, typer.Option("--min-inliers", min=2, help="Default detection threshold T.")
    ] = 6,
    window: Annotated[
        float,
        typer.Option(
            "--window", help="Exclude candidates closer than this in travelled path, metres."
        ),
    ] = 5.0,
    matcher: Annotated[
        str,
        typer.Option(
            "--matcher",
            help="Pair scorer: local (eval.loop_match) or matching (laser_corners.matching).",
        ),
    ] = "local",
) -> None:
    """Place recognition with FLIRT's protocol on a log with corrected poses.

    Each scan is registered against every scan outside its window; precision and recall over
    the inlier threshold, per method, all through one descriptor and matcher
    (docs/place-recognition.md).
    """
    import time

    from rich.console import Console
    from rich.progress import Progress

    from laser_corners.eval.loops import LoopsConfig, LoopsResult, evaluate_loops
    from laser_corners.eval.loops_report import check_output_dir, loops_rows, write_loops_report
    from laser_corners.eval.real import load_scans

    console = Console(stderr=True)
    t0 = time.perf_counter()
    with _known_errors():
        names = tuple(m.strip() for m in methods.split(",") if m.strip())
        config = LoopsConfig(methods=names, min_inliers=min_inliers, window_travel=window,
                             max_scans=max_scans, matcher=matcher)  # fmt: skip
        check_output_dir(output)
        scans, _ = load_scans(input_path, None, max_scans)
        with Progress(console=console, transient=True) as bar:
            task = bar.add_task("loops", total=1)

            def progress(stage: str, done: int, total: int) -> None:
                bar.update(task, description=stage, completed=done, total=total)

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


# ------------------------------------------------------ batch and view (docs/batch-and-viewer.md)
@app.command()
def batch(
    inputs: Annotated[
        list[Path],
        typer.Argument(
            metavar="INPUT", help="Recordings (any kind detect reads).", show_default=False
        ),
    ],
    outdir: Annotated[
        Path,
        typer.Option(
            "--output",
            "-o",
            help="Output folder: one Parquet per input, "
            "manifest.jsonl, batch-params.yaml. Running again resumes.",
            show_default=False,
        ),
    ],
    workers: Annotated[
        int | None,
        typer.Option("--workers", "-w", min=1, help="Worker processes (default: CPU cores)."),
    ] = None,
    scheduler: Annotated[
        str | None,
        typer.Option(
            "--scheduler",
            help="Dask: 'local' (a LocalCluster of --workers "
            "processes) or tcp://host:port (an existing cluster). Default: a local "
            "process pool.",
        ),
    ] = None,
    threads: Annotated[
        int | None,
        typer.Option(
            "--threads",
            min=1,
            help="numba threads per worker (default: cores // workers; 1 on a remote cluster).",
        ),
    ] = None,
    topic: Annotated[
        str | None,
        typer.Option(
            "--topic",
            "-t",
            help="LaserScan topic of the bags (default: every LaserScan topic, one output each).",
        ),
    ] = None,
    params_file: ParamsOption = None,
    set_: SetOption = None,
    preset: PresetOption = None,
) -> None:
    """Detect keypoints in many recordings in parallel (process pool or Dask), resumably."""
    with _known_errors():
        from rich.console import Console
        from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn
        from rich.table import Table

        from laser_corners.batch import BatchJob, JobResult, ParamsChoice, run_batch
        from laser_corners.errors import InvalidParamsError
        from laser_corners.params import DetectorParams
        from laser_corners.presets import PRESETS, get_preset

        if preset is not None and params_file is not None:
            raise InvalidParamsError("give --preset or --params, not both")
        if preset is not None and preset not in PRESETS:
            get_preset(preset)  # raises the error listing the presets
        if set_:
            DetectorParams().with_overrides(set_)  # unknown keys fail now, not in every job
        choice = ParamsChoice(
            preset=preset or "paper",
            base=DetectorParams.from_file(params_file) if params_file is not None else None,
            overrides=tuple(set_ or ()),
        )
        err = Console(stderr=True)
        bar = Progress(
            TextColumn("[bold]batch"), BarColumn(), MofNCompleteColumn(),
            TextColumn("{task.fields[scans]} scans"), console=err,
        )  # fmt: skip
        task = bar.add_task("jobs", total=None, scans=0)

        def planned(jobs: list[BatchJob], done: list[JobResult]) -> None:
            if done:
                err.print(f"{len(done)} job(s) already done in {outdir}, skipped")
            bar.update(task, total=len(jobs))
            bar.start()  # only now: errors about the folder come without a bar

        def finished(result: JobResult) -> None:
            bar.update(task, advance=1, scans=bar.tasks[0].fields["scans"] + result.scans)
            if result.status == "failed":
                err.print(f"[red]failed[/red] {result.error}", highlight=False)

        try:
            report = run_batch(
                inputs, outdir, params=choice, topic=topic, workers=workers,
                scheduler=scheduler, threads=threads, on_result=finished, on_plan=planned,
            )  # fmt: skip
        finally:
            bar.stop()
        table = Table(
            title=f"batch -> {outdir}", caption="r/d/w: seconds reading/detecting/writing"
        )
        for column in ("job", "status", "scans", "keypoints", "s", "scans/s", "r/d/w"):
            table.add_column(column, justify="left" if column in ("job", "status") else "right")
        for r in report.results:
            table.add_row(
                Path(r.output).stem, r.status, str(r.scans), str(r.keypoints),
                f"{r.seconds:.2f}", f"{r.scans_per_second:.0f}",
                f"{r.read_seconds:.2f}/{r.detect_seconds:.2f}/{r.write_seconds:.2f}",
            )  # fmt: skip
        Console().print(table)
        typer.echo(
            f"{len(report.results)} job(s) run ({len(report.failed)} failed), "
            f"{len(report.already_done)} already done; {report.n_scans} scans in "
            f"{report.seconds:.2f} s = {report.scans_per_second:.0f} scans/s with "
            f"{report.workers} worker(s); manifest: {outdir / 'manifest.jsonl'}"
        )
        if report.interrupted:
            err.print("interrupted; run the same command again to resume")
            raise typer.Exit(130)
        if report.failed:
            raise typer.Exit(1)


@app.command()
def view(
    input_path: InputArg,
    save: Annotated[
        Path | None,
        typer.Option(
            "--save", help="Write a rerun .rrd file instead of opening a viewer (works headless)."
        ),
    ] = None,
    connect: Annotated[
        str | None,
        typer.Option(
            "--connect",
            help="Send to a running rerun viewer at this gRPC address "
            "(rerun+http://127.0.0.1:9876/proxy).",
        ),
    ] = None,
    every: Annotated[int, typer.Option("--every", min=1, help="Log every N-th scan.")] = 1,
    max_scans: Annotated[
        int | None, typer.Option("--max-scans", min=1, help="Stop after this many scans.")
    ] = None,
    topic: TopicOption = None,
    params_file: ParamsOption = None,
    set_: SetOption = None,
    preset: PresetOption = None,
) -> None:
    """Stream scans and keypoints (and map-frame keypoints when poses exist) to rerun."""
    with _known_errors():
        from laser_corners.detector import CornerDetector
        from laser_corners.errors import InputError
        from laser_corners.io import open_scans
        from laser_corners.viz.viewer import open_recording_stream, stream_scans

        source = open_scans(input_path, topic)
        first = source.first_scan()
        if first is None:
            raise InputError(f"{input_path}: no readable scan")
        detector = CornerDetector(_resolve_params(preset, params_file, set_, first))
        recording = open_recording_stream(input_path.name, save=save, connect=connect)
        try:
            summary = stream_scans(source, detector, recording, every=every, max_scans=max_scans)
        finally:
            recording.disconnect()
        where = f"wrote {save}" if save is not None else "sent to the viewer"
        typer.echo(
            f"{where}: {summary.n_scans} scans, {summary.n_keypoints} keypoints"
            f" ({summary.n_with_pose} scans with a pose)"
        )


# ------------------------------------------------- simulator (docs/simulation-and-accuracy.md)
@app.command()
def simulate(
    output: Annotated[
        Path, typer.Option("--output", "-o", help="Folder for scans.npz, truth.npz, scans.bag.")
    ] = Path("sim"),
    world: Annotated[
        str, typer.Option(help="World kind: room, l_room, corridor or random.")
    ] = "random",
    sensor: Annotated[
        str, typer.Option(help="Sensor: ust-10lx, sick-1deg, sick-0.5deg, hokuyo-0.352deg.")
    ] = "ust-10lx",
    noise: Annotated[
        float | None,
        typer.Option(help="Range noise sigma, metres (default: the sensor's spec)."),
    ] = None,
    scans: Annotated[int, typer.Option(min=1, help="Number of scans.")] = 200,
    speed: Annotated[float, typer.Option(help="Robot speed, m/s.")] = 0.5,
    seed: Annotated[int, typer.Option(help="Random seed (world, trajectory, noise).")] = 0,
    bag: Annotated[bool, typer.Option("--bag/--no-bag", help="Also write a ROS 1 bag.")] = True,
) -> None:
    """Simulate a drive through a random world: scans, ground-truth corners, a ROS bag."""
    import numpy as np

    from laser_corners.sim import get_sensor, random_world, trajectory
    from laser_corners.sim.export import simulate_sequence, write_sequence

    with _known_errors():
        profile = get_sensor(sensor)
        rng = np.random.default_rng(seed)
        the_world = random_world(rng, None if world == "random" else world)
        poses = trajectory(the_world, scans, rng, rate_hz=profile.rate_hz, speed=speed)
        sigma = profile.range_noise_sigma if noise is None else noise
        sequence = simulate_sequence(the_world, profile, poses, sigma, rng)
        paths = write_sequence(sequence, output, bag=bag)
    typer.echo(
        f"{the_world.name}: {len(the_world.corners)} corners, {scans} scans of {profile.name} "
        f"(noise sigma {sigma} m), {int(sequence.visible.sum())} visible corner sightings"
    )
    for path in paths.values():
        typer.echo(f"wrote {path}")


@evaluate_app.command("sim")
def evaluate_sim_command(
    output: Annotated[
        Path, typer.Option("--output", "-o", help="Folder for accuracy.csv/.md/.png.")
    ] = Path("eval-sim"),
    worlds: Annotated[int, typer.Option(min=1, help="Random worlds.")] = 200,
    poses: Annotated[int, typer.Option(min=1, help="Random poses per world.")] = 10,
    noise: Annotated[
        str, typer.Option(help="Comma-separated range noise sigmas, metres.")
    ] = "0,0.005,0.01,0.02,0.03",
    methods: Annotated[
        str, typer.Option(help="Comma-separated presets, and 'baseline' (split-and-merge).")
    ] = "paper,robust,baseline",
    sensor: Annotated[str, typer.Option(help="Sensor profile (see `simulate`).")] = "ust-10lx",
    match_radius: Annotated[float, typer.Option(help="Match distance, metres.")] = 0.1,
    seed: Annotated[int, typer.Option(help="Random seed.")] = 0,
) -> None:
    """Recall, false keypoints and localisation error against simulated ground truth."""
    import time

    import yaml
    from rich.console import Console
    from rich.table import Table

    from laser_corners.errors import InvalidParamsError
    from laser_corners.eval.accuracy import default_methods, make_cases, run_sweep, write_report
    from laser_corners.sim import get_sensor

    console = Console(width=max(Console().width, 120))
    with _known_errors():
        try:
            sigmas = [float(v) for v in noise.split(",") if v.strip()]
        except ValueError:
            raise InvalidParamsError(f"--noise: not a list of numbers: {noise!r}") from None
        profile = get_sensor(sensor)
        factories = default_methods([m.strip() for m in methods.split(",") if m.strip()])
        t0 = time.perf_counter()
        cases = make_cases(worlds, poses, profile, seed=seed)
        stats, used = run_sweep(cases, factories, sigmas, profile, seed=seed,
                                match_radius=match_radius, progress=console.print)  # fmt: skip
        paths = write_report(stats, output)
    table = Table(title=f"{profile.name}: {len(cases)} poses in {worlds} random worlds")
    for name in ("sigma m", "method", "recall", "false kp", "false/scan", "median mm",
                 "p95 mm", "kp/corner", "ms/scan"):  # fmt: skip
        table.add_column(name, justify="left" if name == "method" else "right")
    for s in stats:
        r = s.row()
        table.add_row(
            f"{r['sigma_m']:g}", r["method"], f"{r['recall']:.3f}",
            f"{100 * r['false_rate']:.1f} %", f"{r['false_per_scan']:.2f}",
            f"{r['median_error_mm']:.1f}", f"{r['p95_error_mm']:.1f}",
            f"{r['keypoints_per_corner']:.3f}", f"{r['ms_per_scan']:.2f}",
        )  # fmt: skip
    console.print(table)
    config = {
        "sensor": sensor, "worlds": worlds, "poses_per_world": poses, "noise_sigmas": sigmas,
        "match_radius": match_radius, "seed": seed,
        "params": {
            name: {f"{sigma:g}": _params_record(det) for sigma, det in per_sigma.items()}
            for name, per_sigma in used.items()
        },
    }  # fmt: skip
    (output / "config.yaml").write_text(yaml.safe_dump(config, sort_keys=False))
    for path in [*paths.values(), output / "config.yaml"]:
        typer.echo(f"wrote {path}")
    typer.echo(f"{time.perf_counter() - t0:.1f} s")


def _params_record(detector: object) -> dict[str, object]:
    from dataclasses import asdict, is_dataclass

    params = getattr(detector, "params", None)
    if hasattr(params, "model_dump"):
        data = params.model_dump()  # type: ignore[union-attr]
        data["scales"] = [float(v) for v in data["scales"]]
        return data
    return asdict(params) if is_dataclass(params) else {}  # type: ignore[arg-type]


def main() -> None:
    """Entry point: run the app, turning known errors into one line and exit code 2."""
    try:
        app(standalone_mode=True)
    except LaserCornersError as exc:
        typer.echo(f"laser-corners: error: {exc}", err=True)
        sys.exit(2)
