"""Options shared by the commands, and option checks that name the option at fault.

Known errors (:class:`~laser_corners.errors.LaserCornersError`) become one line on stderr and
exit code 2 in one place, :class:`~laser_corners.cli.app.ErrorLineGroup`; the library's
messages name files and fields, and these helpers add the option names where the user needs
them.
"""

from __future__ import annotations

import functools
import inspect
import math
import os
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any

import typer

from laser_corners.cli.app import created_folders, fail

if TYPE_CHECKING:
    from laser_corners.pipeline import ParamsChoice

__all__ = [
    "InputArg",
    "MountOption",
    "OdomTopicOption",
    "ParamsOption",
    "PresetOption",
    "SetOption",
    "TopicOption",
    "check_number",
    "image_file",
    "new_folder",
    "params_choice",
    "parse_pose",
    "refuse_overlap",
    "stop_exit_code",
    "with_params_choice",
    "writable_file",
]

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
OdomTopicOption = Annotated[
    str | None,
    typer.Option(
        "--odom-topic",
        help="Odometry of a bag's scan poses: a nav_msgs/Odometry topic, or tf for /tf "
        "(default: the only Odometry topic, /tf when there is none).",
    ),
]
MountOption = Annotated[
    str | None,
    typer.Option("--mount", help="Base -> laser transform x,y,yaw (overrides the recording's)."),
]
PresetOption = Annotated[
    str | None,
    typer.Option(
        "--preset",
        help="Parameter preset: paper (published values, default), auto (adapted "
        "to the scan's angular resolution) or robust (adapted to the range noise estimated "
        "from the scan).",
    ),
]
ParamsOption = Annotated[
    Path | None, typer.Option("--params", help="YAML/TOML parameter file (instead of a preset).")
]
SetOption = Annotated[
    list[str] | None, typer.Option("--set", help="Override a parameter: key=value (repeatable).")
]


def params_choice(
    preset: str | None, params_file: Path | None, set_: list[str] | None
) -> ParamsChoice:
    """The options ``--preset``, ``--params`` and ``--set`` as one parameter choice."""
    from laser_corners.pipeline import ParamsChoice

    if preset is not None and params_file is not None:
        raise fail("give --preset or --params, not both")
    return ParamsChoice.from_options(preset, params_file, set_)


def parse_pose(text: str, option: str) -> tuple[float, float, float]:
    """``"x,y,yaw"`` as three finite floats (x, y within
    :data:`~laser_corners.pose.MAX_COORDINATE`), or a one-line failure naming ``option``."""
    from laser_corners.pose import pose_problem

    try:
        values = tuple(float(v) for v in text.strip("[]() ").split(","))
    except ValueError:
        raise fail(f"{option}: expected x,y,yaw numbers, got {text!r}") from None
    if len(values) != 3:
        raise fail(f"{option}: expected x,y,yaw (3 numbers), got {len(values)}")
    problem = pose_problem(values)
    if problem is not None:
        raise fail(f"{option}: {problem}")
    return values  # type: ignore[return-value]


def check_number(option: str, value: float | None, minimum: float | None = None) -> None:
    """Reject a NaN or infinite option value, or one below ``minimum``, naming the option."""
    if value is None:
        return
    if not math.isfinite(value):
        raise fail(f"{option} must be a finite number, got {value}")
    if minimum is not None and value < minimum:
        raise fail(f"{option} must be >= {minimum:g}, got {value:g}")


def writable_file(path: Path, option: str = "--output") -> Path:
    """``path`` for a new file: its folder is created; a folder in the way, or a folder that
    cannot be written into, fails naming ``option``."""
    if path.is_dir():
        raise fail(f"{path}: is a folder; {option} needs a file name")
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise fail(
            f"{path.parent}: cannot create the folder for {option} ({exc.strerror})"
        ) from None
    if not os.access(path.parent, os.W_OK):
        raise fail(f"{path}: cannot write into {path.parent} ({option})")
    return path


def image_file(path: Path, option: str = "--output") -> tuple[Path, str]:
    """``path`` for an image and its format: the suffix's (``.png``, ``.pdf``, ``.svg`` ...),
    PNG when there is none (the file is written under exactly ``path``)."""
    from matplotlib.backend_bases import FigureCanvasBase

    formats = FigureCanvasBase.get_supported_filetypes()
    kind = path.suffix[1:].lower()
    if kind and kind not in formats:
        raise fail(
            f"{path}: {option} cannot write {path.suffix!r} images; use one of: "
            + ", ".join(f".{k}" for k in sorted(formats))
        )
    return writable_file(path, option), kind or "png"


def new_folder(path: Path, option: str = "--output") -> Path:
    """``path`` as an output folder (created); an existing file in the way fails.

    The folders this creates are recorded (:func:`~laser_corners.cli.app.created_folders`):
    if the command then fails, the group removes those still empty, so an error leaves no
    empty output folder behind.
    """
    if path.exists() and not path.is_dir():
        raise fail(f"{path}: is a file; {option} needs a folder")
    missing = []
    for folder in (path, *path.parents):
        if folder.exists():
            break
        missing.append(folder)
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise fail(f"{path}: cannot create the folder for {option} ({exc.strerror})") from None
    created_folders().extend(missing)  # deepest first
    return path


def refuse_overlap(
    path: Path, inputs: Sequence[Path], option: str = "--output", whole: bool = True
) -> None:
    """Refuse an output folder before any work when it is unnamed (``-o ""``, ``.``: the
    working folder), when it and an input are one another or one holds the other (writing
    would replace or bury an input), or when it cannot be written: the nearest existing folder
    above it (``whole``: it is written beside itself and renamed), else it or that folder.

    Raises
    ------
    typer.Exit
        After one line naming ``option`` and the input (exit 2).
    """
    if path.name in ("", ".", "..") or path.resolve() == Path.cwd().resolve():
        raise fail(f"{option} needs a folder name, got {str(path)!r} (the folder is replaced)")
    out = path.resolve()
    for source in inputs:
        src = source.resolve()
        if src == out or src in out.parents or out in src.parents:
            raise fail(
                f"{path}: {option} would write over the input {source}; choose another folder"
            )
    for folder in out.parents if whole else (out, *out.parents):
        if folder.exists():
            if not os.access(folder, os.W_OK | os.X_OK):
                raise fail(f"{path}: cannot write into {folder} ({option})")
            break


def stop_exit_code(reason: str | None) -> int:
    """The exit code of a run that stopped early for ``reason`` (``partial_reason``): 128 +
    the signal for a stop request (130 Ctrl-C, 143 SIGTERM), 1 for an error, 0 for none."""
    from laser_corners.pipeline.interrupt import STOP_REASONS

    if reason is None:
        return 0
    codes = {text: 128 + int(signum) for signum, text in STOP_REASONS.items()}
    return codes.get(reason, 1)


def with_params_choice(command: Callable[..., None]) -> Callable[..., None]:
    """Give a command the options ``--params``, ``--set`` and ``--preset`` as one argument.

    The command declares a parameter ``choice`` (a
    :class:`~laser_corners.pipeline.ParamsChoice`) instead of the three options; typer sees the
    three options, and the command receives them checked and combined (one definition of the
    detector-parameter options for every command that detects).
    """
    signature = inspect.signature(command)
    kept = []
    for name, parameter in signature.parameters.items():
        if name == "choice":
            continue
        annotation = parameter.annotation
        if isinstance(annotation, str):  # postponed annotations: typer needs the objects
            annotation = eval(annotation, command.__globals__)
        kept.append(parameter.replace(annotation=annotation))
    keyword = inspect.Parameter.KEYWORD_ONLY
    added = [
        inspect.Parameter("params_file", keyword, default=None, annotation=ParamsOption),
        inspect.Parameter("set_", keyword, default=None, annotation=SetOption),
        inspect.Parameter("preset", keyword, default=None, annotation=PresetOption),
    ]

    @functools.wraps(command)
    def run(
        *args: object,
        params_file: Path | None = None,
        set_: list[str] | None = None,
        preset: str | None = None,
        **kwargs: object,
    ) -> None:
        choice = params_choice(preset, params_file, set_)
        command(*args, choice=choice, **kwargs)

    parameters = [*kept, *added]
    run.__signature__ = signature.replace(parameters=parameters)  # type: ignore[attr-defined]
    run.__annotations__ = {p.name: p.annotation for p in parameters}
    return run


def quoted(value: object) -> str:
    """``value`` as text for a rich console: non-printable characters and markup escaped."""
    from rich.markup import escape

    from laser_corners.errors import printable

    return escape(printable(str(value)))


def new_table(title: str, *headers: str, **options: Any) -> Any:
    """A rich table that keeps file names whole at any width (80 columns off a terminal).

    Its columns fold long values onto the next line instead of cutting them with an
    ellipsis, and it is at least as wide as its title, so the title does not wrap mid-word.
    """
    from rich.table import Table

    table = Table(title=quoted(title), min_width=len(title) + 4, **options)
    for header in headers:
        table.add_column(header, overflow="fold")
    return table


def stop_progress(bar: Any) -> None:
    """Stop a rich progress bar if it was started (rich's ``stop`` on a bar that never
    started still prints an empty line off a terminal, before the error that follows)."""
    if bar.live.is_started:
        bar.stop()


class RecordingProgress:
    """A progress bar on stderr for a run over a recording (``slam``, ``localise``): scans
    done of the recording's (or of ``stop_scan``), the real-time factor and the time.

    Called as the runs' ``progress(done, n_scans, stamp)``; the bar starts at the first scan
    and stops on the way out of ``with``.
    """

    def __init__(self, name: str, stop_scan: int | None = None) -> None:
        from rich.console import Console
        from rich.progress import (
            BarColumn,
            MofNCompleteColumn,
            Progress,
            TextColumn,
            TimeElapsedColumn,
        )

        self.bar = Progress(
            TextColumn("[bold]{task.description}"),
            BarColumn(),
            MofNCompleteColumn(),
            TextColumn("{task.fields[rtf]:.1f}x real time"),
            TimeElapsedColumn(),
            console=Console(stderr=True),
        )
        self.task = self.bar.add_task(quoted(name), total=None, rtf=0.0)
        self.stop_scan = stop_scan
        self.start = time.perf_counter()
        self.first: float | None = None

    def __call__(self, done: int, n_scans: int | None, stamp: float) -> None:
        if self.first is None:
            self.first = stamp
            self.bar.start()
        elapsed = time.perf_counter() - self.start
        total = (
            n_scans if self.stop_scan is None or n_scans is None else min(n_scans, self.stop_scan)
        )
        rtf = (stamp - self.first) / elapsed if elapsed > 0 else 0.0
        self.bar.update(self.task, completed=done, total=total, rtf=rtf)

    def __enter__(self) -> RecordingProgress:
        return self

    def __exit__(self, *exc: object) -> None:
        stop_progress(self.bar)
