"""The typer application, the entry point and the one-line error exit.

Help text is laid out for 120 columns whatever the terminal (no option text cut at 80).
"""

from __future__ import annotations

import os
import shutil
import sys

import typer
import typer.rich_utils

from laser_corners.errors import LaserCornersError

__all__ = ["HELP_WIDTH", "app", "evaluate_app", "fail", "main"]

HELP_WIDTH = 120
"""Columns of the ``--help`` layout (independent of the terminal)."""

if not os.environ.get("TERMINAL_WIDTH"):  # typer's rich help ignores click's width
    _columns = shutil.get_terminal_size((HELP_WIDTH, 24)).columns
    typer.rich_utils.MAX_WIDTH = max(_columns, HELP_WIDTH)

app = typer.Typer(
    name="laser-corners",
    help="Corner-like keypoints in 2D laser scans (Sousa, Sobreira, Silva and Moreira, "
    "ICARA 2024, doi:10.1109/ICARA60736.2024.10553006).",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
    context_settings={"max_content_width": HELP_WIDTH, "terminal_width": HELP_WIDTH},
)

evaluate_app = typer.Typer(
    help="Evaluate detectors: on simulated scans (sim) or real recordings with poses (real); "
    "SLAM trajectories against relations (slam).",
    no_args_is_help=True,
    context_settings={"max_content_width": HELP_WIDTH, "terminal_width": HELP_WIDTH},
)
app.add_typer(evaluate_app, name="evaluate")


def fail(message: str, code: int = 2) -> typer.Exit:
    """Print ``message`` as one line on stderr and return the exit to raise."""
    typer.echo(f"laser-corners: error: {message}", err=True)
    return typer.Exit(code)


def main() -> None:
    """Entry point: run the app, turning known errors into one line and exit code 2."""
    try:
        app(standalone_mode=True)
    except LaserCornersError as exc:
        typer.echo(f"laser-corners: error: {exc}", err=True)
        sys.exit(2)
