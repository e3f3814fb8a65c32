"""Exceptions raised by laser-corners, one class per area.

Known, expected problems raise a subclass of :class:`LaserCornersError`; the CLI prints them as
one line and exits with code 2. Anything else is a bug and keeps its traceback. Messages name
the file, message or field at fault and never a command-line flag (the library does not know
how it was called).

=====================  ==========================================================
class                  area
=====================  ==========================================================
InvalidScanError       a ``LaserScan`` field (or scan geometry) is invalid
InvalidParamsError     a ``DetectorParams`` field, preset or option is invalid
InputError             an input file is missing, empty, truncated, corrupt or of
                       the wrong kind
OutputError            an output path cannot be written (missing folder, an
                       existing file in the way, no permission)
MissingDependencyError an optional package (an extra) is needed and not installed
ClusterError           a Dask scheduler or worker cannot be reached or failed
=====================  ==========================================================
"""

from __future__ import annotations


class LaserCornersError(Exception):
    """Base class of every error this package raises on purpose."""


class InvalidScanError(LaserCornersError, ValueError):
    """A :class:`~laser_corners.LaserScan` field has an invalid value."""


class InvalidParamsError(LaserCornersError, ValueError):
    """A :class:`~laser_corners.DetectorParams` field, a preset or an option is invalid."""


class InputError(LaserCornersError):
    """An input file is missing, empty, truncated, corrupt or of the wrong kind."""


class OutputError(LaserCornersError):
    """An output path cannot be written: missing folder, a file in the way, no permission."""


class MissingDependencyError(LaserCornersError, ImportError):
    """An optional package is needed and not installed; the message names the extra."""


class ClusterError(LaserCornersError):
    """A Dask scheduler or worker cannot be reached, or the cluster failed."""


def first_line(exc: BaseException) -> str:
    """The first line of an exception's message (its class name when the message is empty);
    an error whose message spans lines (a list of topics) gives its own ``one_line()``."""
    one_line = getattr(exc, "one_line", None)
    if callable(one_line):
        return str(one_line())
    text = str(exc).strip()
    return text.splitlines()[0] if text else type(exc).__name__


def printable(text: str) -> str:
    """``text`` with every non-printable character escaped (``\\x1b``, ``\\x07``, ``\\u009b``).

    Messages that quote input (a file name, a line of a log) pass through this before they
    reach a terminal, so bytes from a file cannot move the cursor, set the window title or
    ring the bell. Printable non-ASCII characters (``σ``, ``…``) are kept.

    Examples
    --------
    >>> printable("line 1: \\x1b]0;PWNED\\x07 1 2")
    'line 1: \\\\x1b]0;PWNED\\\\x07 1 2'
    """
    if text.isprintable():
        return text
    return "".join(c if c.isprintable() else _escaped(c) for c in text)


def _escaped(char: str) -> str:
    return char.encode("unicode_escape").decode("ascii")
