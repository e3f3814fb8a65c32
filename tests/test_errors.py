"""Errors (:mod:`laser_corners.errors`): one base class for the known ones, their first line,
and input text made safe for a terminal."""

from __future__ import annotations

import pytest

from laser_corners.errors import (
    ClusterError,
    InputError,
    InvalidParamsError,
    InvalidScanError,
    LaserCornersError,
    MissingDependencyError,
    OutputError,
    first_line,
    printable,
)


@pytest.mark.parametrize(
    ("error", "also"),
    [
        (InvalidScanError, ValueError),
        (InvalidParamsError, ValueError),
        (MissingDependencyError, ImportError),
        (InputError, LaserCornersError),
        (OutputError, LaserCornersError),
        (ClusterError, LaserCornersError),
    ],
)
def test_every_known_error_is_a_laser_corners_error(error: type, also: type) -> None:
    assert issubclass(error, LaserCornersError) and issubclass(error, also)
    with pytest.raises(LaserCornersError):
        raise error("x")


def test_first_line_of_a_message() -> None:
    assert first_line(InputError("a.bag: truncated\n  at byte 12")) == "a.bag: truncated"
    assert first_line(ValueError("  \n")) == "ValueError"
    assert first_line(KeyError()) == "KeyError"


def test_first_line_prefers_the_errors_own_one_line() -> None:
    class Listing(InputError):
        def one_line(self) -> str:
            return "several topics: /a, /b (--topic)"

    assert first_line(Listing("several topics:\n  /a\n  /b")) == (
        "several topics: /a, /b (--topic)"
    )


def test_printable_escapes_controls_and_keeps_printable_text() -> None:
    assert printable("σ = 0.01 m …") == "σ = 0.01 m …"
    assert printable("a\x1b[2Jb\x07") == "a\\x1b[2Jb\\x07"
    assert printable("\u009b31m\ttab\n") == "\\x9b31m\\ttab\\n"
    for text in ("\x00", "x\x7fy", "\u009b"):
        assert printable(text).isprintable()
