"""``slam`` (a map and a trajectory from a recording) and ``evaluate slam`` (the relation metric).

See docs/slam.md. ``slam`` parses its options, makes one call (``slam.run_slam``), measures
the relation metric when asked, and writes the output folder
(:func:`~laser_corners.viz.slam_report.write_slam_outputs`, the folder written whole).

The output is checked before any mapping: a folder name, no overlap with the input, a folder
that can be written and replaced, a grid size that can fit. Ctrl-C or SIGTERM stops the run,
and an error while mapping ends it: what was mapped so far is written (``summary.json``:
``"partial": true`` and why) and the command exits with 130, 143 or 1.
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any

import typer

from laser_corners.cli.app import app, evaluate_app, fail
from laser_corners.cli.common import (
    InputArg,
    MountOption,
    OdomTopicOption,
    RecordingProgress,
    TopicOption,
    check_number,
    new_folder,
    parse_pose,
    refuse_overlap,
    stop_exit_code,
)
from laser_corners.cli.kernels import SlamKernelCommand

if TYPE_CHECKING:
    from laser_corners.slam import SlamOptions, SlamResult

__all__ = ["evaluate_slam_command", "relations_table", "slam_command", "slam_options"]

_Relations = Annotated[
    Path | None,
    typer.Option(
        "--relations",
        help="Ground-truth relative poses (t1 t2 x y z roll pitch yaw per line, the Freiburg "
        "benchmark's .relations): report the relation metric of the trajectory and of odometry.",
    ),
]
_Set = Annotated[
    list[str] | None, typer.Option("--set", help="Override a SLAM option: key=value (repeatable).")
]
_Config = Annotated[
    Path | None, typer.Option("--config", help="YAML file of SLAM options (before --set).")
]
_StopScan = Annotated[
    int | None,
    typer.Option("--stop-scan", min=1, help="Stop before this scan index (map the first N scans)."),
]
_StartScan = Annotated[int, typer.Option("--start-scan", min=0, help="Start at this scan index.")]
_PriorMap = Annotated[
    Path | None,
    typer.Option(
        "--map",
        "--prior-map",
        help="Grow this map folder (written by `laser-corners slam -o`; never modified): "
        "start in it, keep its keyframes, add this run's; -o gets the one grown map.",
    ),
]
_Pose = Annotated[
    str | None,
    typer.Option(
        "--initial-pose",
        help="With --map: the base pose x,y,θ (m, m, rad) of the first scan in the map "
        "(default: found by a global search of the map).",
    ),
]
_Resolution = Annotated[
    float, typer.Option("--resolution", help="Occupancy grid cell size, metres (map.pgm).")
]


def slam_options(
    config: Path | None, overrides: list[str] | None, mount: str | None = None
) -> SlamOptions:
    """``SlamOptions`` from a YAML/TOML file (or the defaults), then ``key=value`` overrides,
    then ``--mount`` (as ``localise``'s).

    Raises
    ------
    InvalidParamsError
        An unknown key or a bad value (named); a file that cannot be read or parsed.
    """
    from laser_corners.slam import SlamOptions

    options = SlamOptions() if config is None else SlamOptions.from_file(config)
    options = options.with_overrides(overrides) if overrides else options
    if mount is not None:
        options = options.with_overrides({"mount": parse_pose(mount, "--mount")})
    return options


def _run(
    input_path: Path,
    options: SlamOptions,
    topics: tuple[str | None, str | None],
    span: tuple[int, int | None],
    grow: dict[str, Any],
) -> tuple[SlamResult, float]:
    """``run_slam`` under a progress bar showing the real-time factor; the result, wall s.

    ``topics``: the LaserScan topic and the odometry (``--topic``, ``--odom-topic``);
    ``span``: ``--start-scan``, ``--stop-scan``; ``grow``: ``prior_map`` and
    ``initial_pose`` (``--map``, ``--initial-pose``)."""
    from laser_corners.slam import run_slam

    start = time.perf_counter()
    with RecordingProgress(input_path.name, span[1]) as progress:
        result = run_slam(
            input_path,
            options,
            topic=topics[0],
            odom_topic=topics[1],
            progress=progress,
            start_scan=span[0],
            stop_scan=span[1],
            **grow,
        )
    return result, time.perf_counter() - start


def _relation_metrics(result: SlamResult, relations: Any) -> dict[str, dict[str, float]]:
    from laser_corners.eval.relations import relation_metrics

    return {
        "trajectory": relation_metrics(result.stamps, result.poses, relations).to_dict(),
        "odometry": relation_metrics(result.stamps, result.odometry, relations).to_dict(),
    }


def relations_table(rows: dict[str, dict[str, float]], title: str) -> Any:
    """A rich table of relation metrics: one column per trajectory (``RelationMetrics.to_dict()``
    per name), one row per quantity (mean ± std)."""
    from rich.table import Table

    from laser_corners.viz.slam_report import RELATION_COLUMNS, relation_cells

    table = Table(title=title)
    table.add_column("", no_wrap=True)
    for name in rows:
        table.add_column(name, no_wrap=True)
    cells = [relation_cells(metrics) for metrics in rows.values()]
    for i, quantity in enumerate(RELATION_COLUMNS):
        table.add_row(quantity, *(column[i] for column in cells))
    return table


def _summary_table(summary: dict[str, Any], folder: Path) -> Any:
    from rich.table import Table

    from laser_corners.viz.slam_report import ms_text

    counts, timings, closures = summary["counts"], summary["timings"], summary["closures"]
    table = Table(title=summary["input"], show_header=False)
    table.add_row("scans / keyframes", f"{counts['scans']} / {counts['keyframes']}")
    table.add_row("landmarks", str(counts["landmarks"]))
    table.add_row(
        "loop closures",
        f"{closures['proposed']} proposed, {closures['accepted']} accepted, "
        f"{closures['rejected']} rejected",
    )
    if summary["closure_consistency"] is not None:
        table.add_row("contradicted closures", f"{100 * summary['closure_consistency']:.1f} %")
    rtf = timings["real_time_factor"]
    table.add_row(
        "time",
        f"{timings['total_s']:.1f} s for {timings['data_s']:.1f} s of data"
        + ("" if rtf is None else f" ({rtf:.1f}x real time)"),
    )
    if timings["ms_per_scan_mean"] is not None:
        table.add_row("ms per scan mean / p95 / max", ms_text(timings))
    table.add_row("peak memory", f"{timings['peak_rss_mb']:.0f} MB")
    table.add_row("output", str(folder))
    return table


@app.command("slam", cls=SlamKernelCommand)
def slam_command(
    input_path: InputArg,
    output: Annotated[
        Path, typer.Option("--output", "-o", help="Output folder (created).", show_default=False)
    ],
    relations: _Relations = None,
    topic: TopicOption = None,
    odom_topic: OdomTopicOption = None,
    set_: _Set = None,
    config: _Config = None,
    stop_scan: _StopScan = None,
    resolution: _Resolution = 0.05,
    mount: MountOption = None,
    start_scan: _StartScan = 0,
    prior_map: _PriorMap = None,
    initial_pose: _Pose = None,
) -> None:
    """Map a recording with odometry: trajectory, pose graph, corner landmarks, occupancy grid.

    Writes trajectory.tum, odometry.tum, graph.g2o, landmarks.csv, map.pgm + map.yaml, map.png,
    options.yaml, summary.json and report.md into the output folder (docs/slam.md), replacing
    a previous result there only once the new one is complete. Ctrl-C (SIGTERM, an error)
    writes what was mapped so far, marked partial (exit 130, 143, 1). With --map OLD, the run
    grows the map OLD (never modified) and writes the one grown map (docs/slam.md).
    """
    check_number("--resolution", resolution, minimum=0.001)
    if not input_path.exists():
        raise fail(f"{input_path}: no such file or folder")
    if stop_scan is not None and stop_scan <= start_scan:
        raise fail(f"--stop-scan ({stop_scan}) must be after --start-scan ({start_scan})")
    refuse_overlap(output, [input_path] + ([prior_map] if prior_map is not None else []))
    grow = _grow_arguments(prior_map, initial_pose)
    from rich.console import Console

    from laser_corners.errors import InvalidParamsError
    from laser_corners.eval.relations import closure_consistency, no_coverage, read_relations
    from laser_corners.io.base import skip_warning
    from laser_corners.registration.mapfolder import check_map_folder
    from laser_corners.slam.grid import check_grid_size
    from laser_corners.slam.output import SlamRunInfo, peak_rss_mb, slam_summary
    from laser_corners.viz.slam_report import write_slam_outputs

    options = slam_options(config, set_, mount)
    table = read_relations(relations) if relations is not None else None
    check_map_folder(output)
    try:
        check_grid_size(resolution, options.max_range)
    except InvalidParamsError as exc:
        raise fail(f"--resolution: {exc}") from None
    folder = new_folder(output)
    try:
        result, wall = _run(input_path, options, (topic, odom_topic), (start_scan, stop_scan), grow)
    except KeyboardInterrupt:  # before the first scan (run_slam keeps later interrupts)
        typer.echo(f"interrupted before the first scan; nothing written to {folder}", err=True)
        raise typer.Exit(130) from None
    info = SlamRunInfo(str(input_path), wall, peak_rss_mb(), resolution=resolution)
    skipped = skip_warning(input_path, getattr(result, "skipped", {}))
    info.warnings += [] if skipped is None else [skipped]
    if table is not None:
        info.relations_file = str(relations)
        info.relations = _relation_metrics(result, table)
        uncovered = no_coverage(result.stamps, table) if len(result.stamps) else None
        info.warnings += [] if uncovered is None else [f"{relations}: {uncovered}"]
    if any(c.accepted for c in result.closures):
        info.closure_consistency = float(closure_consistency(result))
    write_slam_outputs(result, folder, info)
    for warning in [*getattr(result, "warnings", []), *info.warnings]:
        typer.echo(f"laser-corners: warning: {warning}", err=True)
    console = Console()
    console.print(_summary_table(slam_summary(result, info), folder))
    if info.relations:
        console.print(relations_table(info.relations, f"relation metric ({relations})"))
    if result.interrupted:
        _stopped_early(result, folder)


def _grow_arguments(prior_map: Path | None, initial_pose: str | None) -> dict[str, Any]:
    """``run_slam``'s ``prior_map`` (read and checked now, before any mapping) and
    ``initial_pose``; an ``--initial-pose`` without ``--map`` is refused."""
    if prior_map is None:
        if initial_pose is not None:
            raise fail("--initial-pose: only with --map (the map the first scan is in)")
        return {}
    from laser_corners.slam.grow import load_prior_map

    pose = parse_pose(initial_pose, "--initial-pose") if initial_pose is not None else None
    return {"prior_map": load_prior_map(prior_map), "initial_pose": pose}


def _stopped_early(result: SlamResult, folder: Path) -> None:
    """One line on how far the run got and why it stopped; the exit code of the reason."""
    reason = getattr(result, "partial_reason", None)
    code = stop_exit_code(reason) or 130
    stamp = f" (t = {result.stamps[-1]:.3f} s)" if len(result.stamps) else ""
    where = f"{folder} holds the map up to there"
    if code == 1:
        raise fail(f"mapping stopped by {reason}; {where} (partial)", code=1)
    verb = "terminated" if code == 143 else "interrupted"
    typer.echo(f"{verb} after {len(result.stamps)} scans{stamp}; {where}", err=True)
    raise typer.Exit(code)


@evaluate_app.command("slam")
def evaluate_slam_command(
    trajectory: Annotated[
        Path,
        typer.Argument(
            metavar="TRAJECTORY", help="TUM trajectory (stamp x y z qx qy qz qw): trajectory.tum."
        ),
    ],
    relations: Annotated[
        Path,
        typer.Argument(
            metavar="RELATIONS", help="Relations file (t1 t2 x y z roll pitch yaw per line)."
        ),
    ],
    odometry: Annotated[
        Path | None, typer.Option("--odometry", help="A second TUM trajectory to compare with.")
    ] = None,
) -> None:
    """The relation metric of a trajectory (Kümmerle et al. 2009): mean ± std of |t|, t², |θ|, θ²
    over the relative poses between the stamps of a .relations file."""
    from rich.console import Console

    from laser_corners.eval.relations import no_coverage, read_relations, relation_metrics
    from laser_corners.io.trajectory import read_tum

    table = read_relations(relations)
    rows: dict[str, dict[str, float]] = {}
    for name, path in (("trajectory", trajectory), ("odometry", odometry)):
        if path is not None:
            stamps, poses = read_tum(path)
            problem = no_coverage(stamps, table)
            if problem is not None:
                raise fail(f"{relations}: {problem.replace('the trajectory', str(path))}")
            rows[f"{name} ({path.name})"] = relation_metrics(stamps, poses, table).to_dict()
    Console().print(relations_table(rows, f"relation metric ({relations})"))
