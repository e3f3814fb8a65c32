"""``evaluate sim`` and ``evaluate real``.

See docs/simulation-and-accuracy.md and docs/real-evaluation.md. Each command: options -> one
library call (``eval.accuracy.run_sweep``, ``eval.real.evaluate_real``) -> tables on the
console and files in ``--output``. New evaluations add a command to
:data:`~laser_corners.cli.app.evaluate_app` in a module of their own or here.
"""

from __future__ import annotations

import math
import time
from dataclasses import asdict, is_dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any

import typer
from rich.console import Console
from rich.table import Table

from laser_corners.cli.app import evaluate_app, fail
from laser_corners.cli.common import (
    InputArg,
    OdomTopicOption,
    ParamsOption,
    PresetOption,
    SetOption,
    TopicOption,
    check_number,
    new_folder,
    new_table,
    params_choice,
    quoted,
)
from laser_corners.cli.kernels import KernelCommand
from laser_corners.errors import InvalidParamsError

if TYPE_CHECKING:
    from laser_corners.eval.accuracy import AccuracyStats
    from laser_corners.eval.real import RealEvalConfig, RealEvaluation

__all__ = [
    "TrajectoryOption",
    "evaluate_real_command",
    "evaluate_sim_command",
    "method_list",
]


def _split(text: str) -> list[str]:
    return [item.strip() for item in text.split(",") if item.strip()]


def method_list(methods: str) -> tuple[str, ...]:
    """The ``--methods`` list in registry names (else one line listing the known ones)."""
    from laser_corners.eval.methods import canonical_name, method_names

    names = _split(methods)
    if not names:
        raise fail(f"--methods: no method given; choose from: {', '.join(method_names())}")
    try:
        return tuple(canonical_name(name) for name in names)
    except InvalidParamsError as exc:
        raise fail(f"--methods: {exc}") from None


def _mount(text: str) -> tuple[float, float, float]:
    try:
        mount = tuple(float(v) for v in text.split(","))
    except ValueError:
        mount = ()
    if len(mount) != 3 or not all(map(math.isfinite, mount)):
        raise fail(f"--relations-mount needs x,y,theta, got {text!r}")
    return mount  # type: ignore[return-value]


TrajectoryOption = Annotated[
    Path | None,
    typer.Option(
        "--trajectory",
        help="TUM trajectory (t x y z qx qy qz qw) giving the "
        "sensor poses, instead of the recording's.",
    ),
]
_Relations = Annotated[
    Path | None,
    typer.Option(
        "--relations",
        help="Ground-truth relative poses (t1 t2 x y z roll pitch "
        "yaw) for repeatability. Default: <name>.relations beside a <name>.bag, "
        "else pairs from the poses.",
    ),
]
_RelationsMount = Annotated[
    str | None,
    typer.Option(
        "--relations-mount",
        help="Sensor pose x,y,theta in the robot frame of the relations (default: 0,0,0).",
    ),
]
_MaxScans = Annotated[
    int | None, typer.Option("--max-scans", min=1, help="Read at most this many scans.")
]
_MaxPairs = Annotated[
    int | None, typer.Option("--max-pairs", min=1, help="At most this many repeatability pairs.")
]
_MaxRange = Annotated[
    float | None,
    typer.Option(
        "--max-range",
        help="Only count cells/keypoints this close to the sensor "
        "as in view, metres (default: the sensor's range).",
    ),
]
_Resolution = Annotated[
    float | None, typer.Option("--resolution", help="Observability cell size, metres.")
]
_AssociationRadius = Annotated[
    float | None, typer.Option("--association-radius", help="Keypoint-feature radius, metres.")
]
_MinRatio = Annotated[
    float | None,
    typer.Option("--min-ratio", help="Lowest N8 observability of a persistent feature."),
]
_MinViews = Annotated[
    int | None,
    typer.Option("--min-views", help="Fewest scans that saw a persistent feature's cell."),
]
_Occlusion = Annotated[
    bool | None, typer.Option("--occlusion/--no-occlusion", help="Ray-cast against each scan.")
]
_Methods = Annotated[
    str | None,
    typer.Option(
        "--methods",
        help="Repeatability rows, comma-separated: paper, auto, robust, split-and-merge, "
        "falko-like (our reading of the FALKO paper, not falkolib; default: "
        "laser_corners.eval.methods.DEFAULT_METHODS).",
    ),
]


@evaluate_app.command("real", cls=KernelCommand)
def evaluate_real_command(
    input_path: InputArg,
    output: Annotated[
        Path, typer.Option("--output", "-o", help="Folder for the figures, arrays and report.md.")
    ] = Path("report"),
    topic: TopicOption = None,
    odom_topic: OdomTopicOption = None,
    preset: PresetOption = None,
    params_file: ParamsOption = None,
    set_: SetOption = None,
    trajectory: TrajectoryOption = None,
    relations: _Relations = None,
    relations_mount: _RelationsMount = None,
    max_scans: _MaxScans = None,
    max_pairs: _MaxPairs = None,
    max_range: _MaxRange = None,
    resolution: _Resolution = None,
    association_radius: _AssociationRadius = None,
    min_ratio: _MinRatio = None,
    min_views: _MinViews = None,
    occlusion: _Occlusion = None,
    methods: _Methods = None,
) -> None:
    """Paper section IV on a recording with poses (maps, features, association, repeatability).

    Writes the observability maps, persistent features, association matrix and histogram,
    the repeatability table and report.md into --output (docs/real-evaluation.md). Options
    left out take the defaults of the library's RealEvalConfig.
    """
    # the library is imported after the options are parsed, so that --help stays instant
    from laser_corners.eval.poses import read_relations
    from laser_corners.eval.real import RealEvalConfig, default_relations, evaluate_real, load_scans
    from laser_corners.viz.report import write_real_report

    console = Console(stderr=True)
    for option, value in (
        ("--max-range", max_range),
        ("--resolution", resolution),
        ("--association-radius", association_radius),
        ("--min-ratio", min_ratio),
    ):
        if value is not None:
            check_number(option, value, minimum=0.0)
    given = {
        "resolution": resolution,
        "association_radius": association_radius,
        "min_ratio": min_ratio,
        "min_views": min_views,
        "occlusion": occlusion,
        "max_range": max_range,
        "max_scans": max_scans,
        "max_pairs": max_pairs,
        "relations_mount": None if relations_mount is None else _mount(relations_mount),
        "methods": None if methods is None else method_list(methods),
    }
    config = RealEvalConfig(
        detector=params_choice(preset, params_file, set_),
        **{name: value for name, value in given.items() if value is not None},
    )
    new_folder(output)
    t0 = time.perf_counter()
    scans, pose_source = load_scans(input_path, topic, max_scans, trajectory, odom_topic)
    relations_path = relations if relations is not None else default_relations(input_path)
    result = evaluate_real(
        scans,
        config,
        relations=read_relations(relations_path) if relations_path is not None else None,
        source=input_path.name,
        pose_source=pose_source,
        progress=lambda message: console.print(quoted(message), highlight=False),
    )
    paths = write_real_report(result, output)
    _print_real(console, result, config)
    for warning in result.warnings:
        console.print(f"[yellow]warning:[/yellow] {quoted(warning)}", highlight=False)
    typer.echo(
        f"wrote {len(paths)} files to {output} ({paths['report.md']}) in "
        f"{time.perf_counter() - t0:.1f} s"
    )


def _print_real(console: Console, result: RealEvaluation, config: RealEvalConfig) -> None:
    from laser_corners.eval.real_summary import headline, repeatability_rows

    console.print(headline(result), highlight=False)
    table = new_table(f"repeatability, {result.n_pairs} pairs ({result.pairs_source})")
    table.add_column("method")
    table.add_column("kp/scan", justify="right")
    table.add_column("visible", justify="right")
    for r in config.radii:
        table.add_column(f"r={r:g} m", justify="right")
    for row in repeatability_rows(result):
        values = [row[f"repeatability_r{r:g}"] for r in config.radii]
        table.add_row(
            row["method"],
            f"{row['keypoints_per_scan']:.2f}",
            str(row["visible"]),
            *("n/a" if v is None else f"{100 * v:.1f} %" for v in values),
        )
    console.print(table)


@evaluate_app.command("sim", cls=KernelCommand)
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
        str, typer.Option(help="Comma-separated methods: presets and split-and-merge.")
    ] = "paper,robust,split-and-merge",
    sensor: Annotated[str, typer.Option(help="Sensor profile (see `simulate`).")] = "ust-10lx",
    match_radius: Annotated[float, typer.Option(help="Match distance, metres.")] = 0.1,
    seed: Annotated[int, typer.Option(help="Random seed.")] = 0,
) -> None:
    """Recall, false keypoints and localisation error against simulated ground truth."""
    from laser_corners.eval.accuracy import make_cases, run_sweep
    from laser_corners.eval.methods import method_factories
    from laser_corners.sim import get_sensor
    from laser_corners.viz.report import write_accuracy_report

    console = Console(width=max(Console().width, 120))
    try:
        sigmas = [float(v) for v in _split(noise)]
    except ValueError:
        raise fail(f"--noise: not a list of numbers: {noise!r}") from None
    for sigma in sigmas:
        check_number("--noise", sigma, minimum=0.0)
    check_number("--match-radius", match_radius, minimum=0.0)
    profile = get_sensor(sensor)
    factories = method_factories(method_list(methods))
    new_folder(output)
    t0 = time.perf_counter()
    cases = make_cases(worlds, poses, profile, seed=seed)
    stats, used = run_sweep(
        cases,
        factories,
        sigmas,
        profile,
        seed=seed,
        match_radius=match_radius,
        progress=console.print,
    )
    paths = write_accuracy_report(stats, output)
    console.print(
        _sim_table(f"{profile.name}: {len(cases)} poses in {worlds} random worlds", stats)
    )
    config = {
        "sensor": sensor,
        "worlds": worlds,
        "poses_per_world": poses,
        "noise_sigmas": sigmas,
        "match_radius": match_radius,
        "seed": seed,
        "params": {
            name: {f"{sigma:g}": _params_record(det) for sigma, det in per_sigma.items()}
            for name, per_sigma in used.items()
        },
    }
    _write_yaml(output / "config.yaml", config)
    for path in [*paths.values(), output / "config.yaml"]:
        typer.echo(f"wrote {path}")
    typer.echo(f"{time.perf_counter() - t0:.1f} s")


def _sim_table(title: str, stats: list[AccuracyStats]) -> Table:
    table = new_table(title)
    for name in (
        "sigma m",
        "method",
        "recall",
        "false kp",
        "false/scan",
        "median mm",
        "p95 mm",
        "kp/corner",
        "ms/scan",
    ):
        table.add_column(name, justify="left" if name == "method" else "right")
    for s in stats:
        r = s.row()
        table.add_row(
            f"{r['sigma_m']:g}",
            r["method"],
            f"{r['recall']:.3f}",
            f"{100 * r['false_rate']:.1f} %",
            f"{r['false_per_scan']:.2f}",
            f"{r['median_error_mm']:.1f}",
            f"{r['p95_error_mm']:.1f}",
            f"{r['keypoints_per_corner']:.3f}",
            f"{r['ms_per_scan']:.2f}",
        )
    return table


def _write_yaml(path: Path, data: dict[str, Any]) -> None:
    import yaml

    path.write_text(yaml.safe_dump(data, sort_keys=False), encoding="utf-8")


def _params_record(detector: object) -> dict[str, object]:
    params = getattr(detector, "params", None)
    if hasattr(params, "model_dump"):  # every options object (laser_corners.options)
        return params.model_dump(mode="json")  # type: ignore[union-attr,no-any-return]
    return asdict(params) if is_dataclass(params) else {}  # type: ignore[arg-type]
