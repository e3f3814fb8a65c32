"""Exceptions raised by laser-corners.

Known, expected problems (bad input files, invalid parameters) raise a subclass of
:class:`LaserCornersError`; the CLI prints them as one line and exits with code 2.
Anything else is a bug and keeps its traceback.
"""

from __future__ import annotations


class LaserCornersError(Exception):
    """Base class of every error this package raises on purpose."""


class InvalidScanError(LaserCornersError, ValueError):
    """A :class:`~laser_corners.LaserScan` field has an invalid value."""


class InvalidParamsError(LaserCornersError, ValueError):
    """A :class:`~laser_corners.DetectorParams` field has an invalid value."""


class InputError(LaserCornersError):
    """An input file is missing, empty, truncated, corrupt or of the wrong kind."""
