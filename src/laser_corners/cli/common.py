"""Options shared by the commands, option checks, and the one-line handling of known errors.

Known errors (:class:`~laser_corners.errors.LaserCornersError`) print one line on stderr and
exit with code 2; the library's messages name files and fields, and these helpers add the
option names where the user needs them.
"""

from __future__ import annotations

import functools
import inspect
import math
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

from laser_corners.cli.app import fail
from laser_corners.errors import LaserCornersError

if TYPE_CHECKING:
    from laser_corners.pipeline import ParamsChoice

__all__ = [
    "InputArg",
    "ParamsOption",
    "PresetOption",
    "SetOption",
    "TopicOption",
    "check_number",
    "known_errors",
    "new_folder",
    "params_choice",
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
def known_errors() -> Iterator[None]:
    """Turn known errors into one line on stderr and exit code 2 (also under CliRunner)."""
    try:
        yield
    except LaserCornersError as exc:
        message = str(exc)
        topics = getattr(exc, "topics", None)  # io.TopicChoiceError: one option line per topic
        if isinstance(topics, list):
            message = message.splitlines()[0] + "".join(f"\n  --topic {t}" for t in topics)
        raise fail(message) from None


def params_choice(
    preset: str | None, params_file: Path | None, set_: list[str] | None
) -> ParamsChoice:
    """The options ``--preset``, ``--params`` and ``--set`` as one parameter choice."""
    from laser_corners.pipeline import ParamsChoice

    if preset is not None and params_file is not None:
        raise fail("give --preset or --params, not both")
    return ParamsChoice.from_options(preset, params_file, set_)


def check_number(option: str, value: float | None, minimum: float | None = None) -> None:
    """Reject a NaN or infinite option value, or one below ``minimum``, naming the option."""
    if value is None:
        return
    if not math.isfinite(value):
        raise fail(f"{option} must be a finite number, got {value}")
    if minimum is not None and value < minimum:
        raise fail(f"{option} must be >= {minimum:g}, got {value:g}")


def writable_file(path: Path, option: str = "--output") -> Path:
    """``path`` for a new file: its folder is created; an existing folder in the way fails."""
    if path.is_dir():
        raise fail(f"{path}: is a folder; {option} needs a file name")
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise fail(
            f"{path.parent}: cannot create the folder for {option} ({exc.strerror})"
        ) from None
    return path


def new_folder(path: Path, option: str = "--output") -> Path:
    """``path`` as an output folder (created); an existing file in the way fails."""
    if path.exists() and not path.is_dir():
        raise fail(f"{path}: is a file; {option} needs a folder")
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise fail(f"{path}: cannot create the folder for {option} ({exc.strerror})") from None
    return path


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
        with known_errors():
            choice = params_choice(preset, params_file, set_)
        command(*args, choice=choice, **kwargs)

    parameters = [*kept, *added]
    run.__signature__ = signature.replace(parameters=parameters)  # type: ignore[attr-defined]
    run.__annotations__ = {p.name: p.annotation for p in parameters}
    return run
