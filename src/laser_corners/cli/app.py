"""The typer application, the entry point, and the one place where known errors become a line.

Help text is laid out for 120 columns whatever the terminal (no option text cut at 80).

Known errors (evo's pattern): :class:`~laser_corners.errors.LaserCornersError` and the
operating system's file errors (missing file, no permission, a folder in the way, a full
disk) print one line on stderr, ``laser-corners: error: ...`` with every non-printable
character escaped, and exit with code 2. Anything else is a bug and keeps its traceback.
Commands raise; they do not catch (:class:`ErrorLineGroup` does, once for every command).
"""

from __future__ import annotations

import errno
from pathlib import Path
from typing import Any

import typer
import typer.core

from laser_corners import __version__
from laser_corners.errors import LaserCornersError, printable

__all__ = [
    "HELP_WIDTH",
    "ErrorLineGroup",
    "app",
    "created_folders",
    "error_line",
    "evaluate_app",
    "fail",
    "main",
]

HELP_WIDTH = 120
"""Columns of the ``--help`` layout (independent of the terminal)."""

_FILE_ERRNOS = frozenset({errno.ENOSPC, errno.EROFS, errno.EDQUOT, errno.EFBIG})
"""OS errors that are the user's situation even without a file name (full disk, read-only)."""


def error_line(exc: BaseException) -> str | None:
    """The one-line message of a known error, or None for anything else (a bug).

    A bag's several LaserScan (Odometry) topics (``io.TopicChoiceError``) keep one
    ready-to-paste ``--topic`` (``--odom-topic``) line each.
    """
    if isinstance(exc, LaserCornersError):
        message = str(exc).strip() or type(exc).__name__
        topics = getattr(exc, "topics", None)
        if isinstance(topics, list):
            head = printable(message.splitlines()[0])
            option = printable(str(getattr(exc, "option", "--topic")))
            return head + "".join(f"\n  {option} {printable(str(t))}" for t in topics)
        return printable(" ".join(message.split("\n")))
    if isinstance(exc, OSError) and (exc.filename is not None or exc.errno in _FILE_ERRNOS):
        where = f"{exc.filename}: " if exc.filename is not None else ""
        reason = exc.strerror or type(exc).__name__
        return printable(f"{where}{reason[:1].lower()}{reason[1:]}")
    return None


def _echo_error(line: str) -> None:
    typer.echo(f"laser-corners: error: {line}", err=True)


def fail(message: str, code: int = 2) -> typer.Exit:
    """Print ``message`` (an option's problem) as one line on stderr; the exit to raise."""
    _echo_error(printable(message))
    return typer.Exit(code)


_CREATED: list[Path] = []
"""Output folders the running command created, deepest first (see :func:`created_folders`)."""


def created_folders() -> list[Path]:
    """The output folders the running command created (``common.new_folder`` adds to it)."""
    return _CREATED


def _remove_empty_created() -> None:
    while _CREATED:
        try:
            _CREATED.pop(0).rmdir()  # only when empty
        except OSError:
            _CREATED.clear()


class ErrorLineGroup(typer.core.TyperGroup):
    """The command group that turns known errors of any command into one line and exit 2.

    When a command fails, the output folders it created and left empty are removed.
    """

    def invoke(self, ctx: typer.Context) -> Any:  # type: ignore[override]
        _CREATED.clear()
        try:
            return super().invoke(ctx)
        except typer.Exit as exc:
            if exc.exit_code != 0:
                _remove_empty_created()
            raise
        except BaseException as exc:
            _remove_empty_created()
            line = error_line(exc)
            if line is None:
                raise
            _echo_error(line)
            raise typer.Exit(2) from None


_CONTEXT = {"max_content_width": HELP_WIDTH, "terminal_width": HELP_WIDTH}

app = typer.Typer(
    name="laser-corners",
    cls=ErrorLineGroup,
    help="Corner-like keypoints in 2D laser scans (Sousa, Sobreira, Silva and Moreira, "
    "ICARA 2024, doi:10.1109/ICARA60736.2024.10553006).",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
    rich_markup_mode=None,
    context_settings=_CONTEXT,
)

evaluate_app = typer.Typer(
    help="Evaluate detectors: on simulated scans (sim), on real recordings with poses (real), "
    "place recognition on a log with corrected poses (loops); SLAM trajectories against "
    "relations (slam).",
    no_args_is_help=True,
    rich_markup_mode=None,
    context_settings=_CONTEXT,
)
app.add_typer(evaluate_app, name="evaluate")


def _version(value: bool) -> None:
    if value:
        typer.echo(f"laser-corners {__version__}")
        raise typer.Exit()


@app.callback()
def _options(
    version: bool = typer.Option(
        False, "--version", callback=_version, is_eager=True, help="Print the version and exit."
    ),
) -> None:
    """Corner-like keypoints in 2D laser scans (Sousa, Sobreira, Silva and Moreira, ICARA 2024,
    doi:10.1109/ICARA60736.2024.10553006)."""


def main() -> None:
    """Entry point (``laser-corners``): run the app; errors are handled by the group."""
    app()
