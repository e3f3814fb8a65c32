"""The ``laser-corners`` command line (typer + rich).

Heavy modules are imported inside the commands, so ``--help`` stays instant. Known errors
(:class:`~laser_corners.errors.LaserCornersError`, missing files) print one line and exit 2.
"""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Annotated

import typer

from laser_corners.errors import LaserCornersError

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


def main() -> None:
    """Entry point: run the app, turning known errors into one line and exit code 2."""
    try:
        app(standalone_mode=True)
    except LaserCornersError as exc:
        typer.echo(f"laser-corners: error: {exc}", err=True)
        sys.exit(2)
