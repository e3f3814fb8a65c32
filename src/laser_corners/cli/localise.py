"""``localise MAP INPUT -o DIR``: the pose of a recording's robot in a map ``slam`` wrote
(a folder) or another package made (a ``map_server`` ``map.yaml``: virtual keyframes,
:mod:`laser_corners.registration.gridmap`).

See docs/localise.md. Parses the options, makes one call (``localise.run_localise``) that
writes ``online.tum`` as the estimates come (what the robot knew at each scan), then writes
``trajectory.tum`` (the smoothed trajectory, ``localise.smooth``; the online estimates with
``--set smooth.enabled=false``), ``summary.json`` and ``trajectory.png``
(:mod:`laser_corners.viz.localise`). Ctrl-C or SIGTERM stops between two scans, and an error
while localising ends the run: what was done is written, marked partial in ``summary.json``
(exit 130, 143, 1). The output folder is checked first (no overlap with the map or the
recording, writable); ``online.tum`` is renamed into place only when the run gets to its end,
so a failed run leaves an earlier run's file as it was. A partial map is a warning.
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

from laser_corners.cli.app import app, fail
from laser_corners.cli.common import (
    InputArg,
    MountOption,
    OdomTopicOption,
    RecordingProgress,
    TopicOption,
    new_folder,
    parse_pose,
    refuse_overlap,
    stop_exit_code,
)
from laser_corners.cli.kernels import SlamKernelCommand

if TYPE_CHECKING:
    from laser_corners.localise import LocaliseOptions

__all__ = ["localise_command", "localise_options"]

_MapArg = Annotated[
    Path,
    typer.Argument(
        metavar="MAP",
        help="Map folder written by `laser-corners slam -o`, or a map_server map.yaml "
        "(slam_toolbox, Cartographer, GMapping...; the mount: --mount, else the "
        "recording's, else zero).",
        show_default=False,
    ),
]
_Set = Annotated[
    list[str] | None,
    typer.Option("--set", help="Override a localisation option: key=value (repeatable)."),
]
_Config = Annotated[
    Path | None, typer.Option("--config", help="YAML file of localisation options (before --set).")
]
_Pose = Annotated[
    str | None,
    typer.Option(
        "--initial-pose", help="Base pose x,y,θ (m, m, rad) in the map at the first scan."
    ),
]


def localise_options(
    config: Path | None, overrides: list[str] | None, mount: str | None
) -> LocaliseOptions:
    """``LocaliseOptions`` from a YAML file (or the defaults), ``--set`` and ``--mount``."""
    from laser_corners.localise import LocaliseOptions

    options = LocaliseOptions.from_file(config) if config is not None else LocaliseOptions()
    if overrides:
        options = options.with_overrides(overrides)
    if mount is not None:
        options = options.with_overrides({"mount": parse_pose(mount, "--mount")})
    return options


@app.command("localise", cls=SlamKernelCommand)
def localise_command(
    map_folder: _MapArg,
    input_path: InputArg,
    output: Annotated[
        Path, typer.Option("--output", "-o", help="Output folder (created).", show_default=False)
    ],
    initial_pose: _Pose = None,
    start_scan: Annotated[
        int, typer.Option("--start-scan", min=0, help="Start at this scan index.")
    ] = 0,
    stop_scan: Annotated[
        int | None, typer.Option("--stop-scan", min=1, help="Stop before this scan index.")
    ] = None,
    set_: _Set = None,
    config: _Config = None,
    topic: TopicOption = None,
    odom_topic: OdomTopicOption = None,
    mount: MountOption = None,
) -> None:
    """Localise a recording with odometry in a map: global localisation with no initial pose,
    tracking, relocalisation when lost.

    Writes trajectory.tum (base pose in the map of every scan tied to a fix, smoothed: each
    scan placed using the whole recording), online.tum (the estimates as they came, from the
    first fix on), summary.json (first fix, relocalisations, lost count, ms per scan) and
    trajectory.png into the output folder.
    """
    if not input_path.exists():
        raise fail(f"{input_path}: no such file or folder")
    refuse_overlap(output, [map_folder, input_path], whole=False)
    if stop_scan is not None and stop_scan <= start_scan:
        raise fail(f"--stop-scan ({stop_scan}) must be after --start-scan ({start_scan})")
    from rich.console import Console

    from laser_corners.io.trajectory import TumWriter
    from laser_corners.localise import run_localise
    from laser_corners.registration.mapfolder import load_map
    from laser_corners.viz.localise import localise_summary, write_localise_outputs

    options = localise_options(config, set_, mount)
    pose = parse_pose(initial_pose, "--initial-pose") if initial_pose is not None else None
    saved = load_map(map_folder)
    if saved.partial_reason is not None:
        typer.echo(
            f"laser-corners: warning: {map_folder} is a partial map ({saved.partial_reason}): "
            "it covers only part of its recording",
            err=True,
        )
    folder = new_folder(output)
    header = f"laser-corners localise {input_path} in {map_folder}: base pose in the map frame"
    start = time.perf_counter()
    online = TumWriter(folder / "online.tum", header=header + ", online")
    with online as writer, RecordingProgress(input_path.name, stop_scan) as progress:
        run = run_localise(
            saved,
            input_path,
            options,
            topic=topic,
            odom_topic=odom_topic,
            start_scan=start_scan,
            stop_scan=stop_scan,
            initial_pose=pose,
            on_estimate=lambda e: writer.write(e.stamp, e.pose),
            progress=progress,
        )
    summary = localise_summary(run, str(input_path), str(map_folder), time.perf_counter() - start)
    summary["map_partial_reason"] = saved.partial_reason
    for warning in summary["warnings"]:
        typer.echo(f"laser-corners: warning: {warning}", err=True)
    write_localise_outputs(run, folder, saved.grid, summary, header)
    _report(Console(), summary, folder)
    if run.interrupted:
        _stopped(run.partial_reason, folder)


def _stopped(reason: str | None, folder: Path) -> None:
    """End a run that stopped early (Ctrl-C, SIGTERM, an error): one line, its exit code."""
    code = stop_exit_code(reason) or 130
    if code == 1:
        raise fail(
            f"localisation stopped by {reason}; {folder} holds the poses up to there (partial)",
            code=1,
        )
    verb = "terminated" if code == 143 else "interrupted"
    typer.echo(f"{verb}; {folder} holds the poses up to there", err=True)
    raise typer.Exit(code)


def _report(console, summary: dict, folder: Path) -> None:
    from rich.table import Table

    from laser_corners.viz.localise import initial_text
    from laser_corners.viz.slam_report import ms_text

    table = Table(title=summary["input"], show_header=False)
    fix, initial = summary["first_fix"], summary["initial_pose"]
    table.add_row("initial pose", initial_text(initial))
    if fix is not None:
        text = f"scan {fix['scan_index']}, t = {fix['stamp']:.3f} s, after {fix['travel_m']:.2f} m"
    else:
        text = "the initial pose" if initial and initial["accepted"] else "none"
    table.add_row("first fix", text)
    table.add_row(
        "relocalisations / lost", f"{len(summary['relocalisations'])} / {summary['lost']}"
    )
    counts = summary["counts"]
    table.add_row(
        "scans / estimates (local)",
        f"{counts['scans']} / {counts['estimates']} ({counts.get('local', 0)})",
    )
    if summary["ms_per_scan_mean"] is not None:
        table.add_row("ms per scan mean / p95 / max", ms_text(summary))
    table.add_row("output", str(folder))
    console.print(table)
