"""CARMEN logs (plain or gzip): FLASER, ROBOTLASER1 and RAWLASER1-4 lines; also ``.g2o`` files.

Line layouts (whitespace separated; ``ipc_ts`` is the stamp):

* ``FLASER n r1..rn x y th odom_x odom_y odom_th ipc_ts host logger_ts`` -- 180 deg field of
  view from -90 deg, counter-clockwise; increment pi/n for an even n (180 beams: 1 deg, the
  last beam at +89 deg), pi/(n-1) for an odd n (181 beams: -90..+90 deg). The pose is
  ``x y th``; there is no declared maximum range, :data:`FLASER_MAX_RANGE` is used.
* ``ROBOTLASER1 type start_angle fov res max_range accuracy remission_mode n r1..rn n_rem
  rem1..rem_k laser_x laser_y laser_th robot_x robot_y robot_th tv rv fwd_safety side_safety
  turn_axis ipc_ts host logger_ts`` -- beam i at ``start_angle + i*res``; the pose is
  ``laser_x laser_y laser_th`` (the map-frame laser pose in the ``*-corrected`` logs). A
  negative ``res`` is kept: the beams then turn clockwise (the scan's ``angle_increment`` is
  negative, as a ``sensor_msgs/LaserScan`` of an upside-down scanner has it).
* ``RAWLASER1..4 type start_angle fov res max_range accuracy remission_mode n r1..rn n_rem
  rem1..rem_k ipc_ts host logger_ts`` -- no pose.

Readings at or beyond the maximum range mean "no return": the scan's ``range_max`` is the
declared maximum range, so they become gaps. Other record types (VERTEX2, EDGE2, ODOM, PARAM,
NEFF, ...) and comments are skipped silently; a malformed laser line is a counted skip.

A ``.g2o`` pose-graph file (as Freiburg's killian log ships, zipped) mixes ``VERTEX_*``,
``EDGE_*``, ``FIX`` and ``PARAMS_*`` lines with ROBOTLASER1 laser lines of the CARMEN layout:
it is read as a log, its graph lines skipped silently.
"""

from __future__ import annotations

import math
import zlib
from collections import Counter
from collections.abc import Iterator
from pathlib import Path

import numpy as np

from laser_corners.errors import InputError, InvalidScanError
from laser_corners.io.base import ScanSource, open_text
from laser_corners.scan import LaserScan

__all__ = [
    "CARMEN_SUFFIXES",
    "CARMEN_WORDS",
    "FLASER_MAX_RANGE",
    "CarmenSource",
    "MalformedLine",
    "parse_carmen_line",
]

CARMEN_SUFFIXES = frozenset({".clf", ".log", ".carmen", ".txt", ".gfs", ".g2o"})
"""Suffixes of CARMEN logs (and of ``.g2o`` files, read for their laser lines)."""
CARMEN_WORDS: tuple[bytes, ...] = (
    b"FLASER",
    b"ROBOTLASER1",
    b"RAWLASER",
    b"VERTEX",
    b"EDGE",
    b"ODOM",
    b"PARAM",
    b"#",
)
"""First words that make a file without a known suffix a CARMEN log."""

FLASER_MAX_RANGE = 80.0
"""Maximum range (m) of FLASER lines, which declare none: the SICK LMS value CARMEN uses."""

_RAWLASERS = ("RAWLASER1", "RAWLASER2", "RAWLASER3", "RAWLASER4")
_LASER_WORDS = ("FLASER", "ROBOTLASER1", *_RAWLASERS)
_IGNORED_WORDS = frozenset(
    {
        "VERTEX2",
        "VERTEX",
        "VERTEX_SE2",
        "EDGE2",
        "EDGE",
        "EDGE_SE2",
        "ODOM",
        "PARAM",
        "NEFF",
        "TRUEPOS",
        "RLASER",
        "ROBOTLASER2",
        "SYNC",
        "GPSNMEA",
        "POSITIONLASER",
        "FIX",
    }
)
_IGNORED_PREFIXES = ("VERTEX", "EDGE", "PARAMS_")  # g2o graph lines


def _ignored(word: str) -> bool:
    """Whether lines starting with ``word`` are skipped silently (not laser, not an error)."""
    return word in _IGNORED_WORDS or word.startswith(_IGNORED_PREFIXES)


class MalformedLine(ValueError):
    """A laser line that cannot be parsed (message says why)."""


def _floats(tokens: list[str], start: int, count: int, what: str) -> np.ndarray:
    if count < 0 or start + count > len(tokens):
        raise MalformedLine(f"{what}: needs {count} values, the line has {len(tokens) - start}")
    try:
        return np.array(tokens[start : start + count], dtype=np.float64)
    except ValueError:
        raise MalformedLine(f"{what}: not a number") from None


def _int(tokens: list[str], index: int, what: str) -> int:
    if index >= len(tokens):
        raise MalformedLine(f"line ends before {what}")
    try:
        value = int(tokens[index])
    except ValueError:
        raise MalformedLine(f"{what} {tokens[index]!r} is not an integer") from None
    if value < 0:
        raise MalformedLine(f"{what} is negative ({value})")
    return value


def _pose(values: np.ndarray) -> tuple[float, float, float] | None:
    if not np.all(np.isfinite(values)):
        raise MalformedLine("pose is not finite")
    return (float(values[0]), float(values[1]), float(values[2]))


def parse_carmen_line(tokens: list[str]) -> LaserScan:
    """Parse the tokens of one FLASER/ROBOTLASER1/RAWLASERk line into a scan.

    Raises
    ------
    MalformedLine
        (a ``ValueError``) when the line does not follow its layout.
    """
    word = tokens[0]
    if word == "FLASER":
        n = _int(tokens, 1, "number of readings")
        if n < 2:
            raise MalformedLine(f"needs at least 2 readings, declares {n}")
        ranges = _floats(tokens, 2, n, "readings")
        rest = _floats(tokens, 2 + n, 7, "pose and timestamp")
        increment = math.pi / (n - 1) if n % 2 else math.pi / n
        return LaserScan(
            ranges,
            -math.pi / 2,
            increment,
            0.0,
            FLASER_MAX_RANGE,
            stamp=float(rest[6]),
            frame_id="laser",
            pose=_pose(rest[0:3]),
        )
    # ROBOTLASER1 and RAWLASERk share the head
    geometry = _floats(tokens, 2, 5, "geometry")  # start fov res max_range accuracy
    start_angle, _fov, res, max_range, _accuracy = (float(v) for v in geometry)
    n = _int(tokens, 8, "number of readings")
    ranges = _floats(tokens, 9, n, "readings")
    n_rem = _int(tokens, 9 + n, "number of remissions")
    after = 10 + n + n_rem
    if after > len(tokens):
        raise MalformedLine(f"declares {n_rem} remissions, the line ends before them")
    if not (math.isfinite(max_range) and max_range > 0.0):
        raise MalformedLine(f"max_range must be positive, got {max_range}")
    if word == "ROBOTLASER1":
        rest = _floats(tokens, after, 12, "poses, velocities and timestamp")
        pose: tuple[float, float, float] | None = _pose(rest[0:3])
        stamp = float(rest[11])
        frame_id = "laser"
    else:
        rest = _floats(tokens, after, 1, "timestamp")
        pose = None
        stamp = float(rest[0])
        frame_id = "laser" + word[-1]
    if not math.isfinite(stamp):
        raise MalformedLine("timestamp is not finite")
    return LaserScan(ranges, start_angle, res, 0.0, max_range, stamp, frame_id, pose)


class CarmenSource(ScanSource):
    """Scans of a CARMEN log (plain text or gzip).

    Parameters
    ----------
    path : Path
        The log.
    """

    kind = "carmen"

    def __init__(self, path: Path) -> None:
        super().__init__(path)

    @property
    def n_scans(self) -> None:
        """Unknown without reading the log: ``None``."""
        return None

    def _lines(self) -> Iterator[tuple[int, str]]:
        line_no = 0
        try:
            with open_text(self.path) as handle:
                for line_no, line in enumerate(handle, start=1):
                    self.position = f"line {line_no}"
                    yield line_no, line
        except EOFError:
            raise InputError(
                f"{self.path}: truncated gzip stream: the file ends after line {line_no}"
            ) from None
        except (OSError, zlib.error) as exc:  # gzip.BadGzipFile is an OSError
            raise self.error(f"corrupt gzip data ({exc})") from None

    def _scans(self) -> Iterator[LaserScan]:
        for line_no, line in self._lines():
            tokens = line.split()
            if not tokens or tokens[0].startswith("#") or _ignored(tokens[0]):
                continue
            word = tokens[0]
            if word not in _LASER_WORDS:
                self._skip("unknown record type", f"line {line_no}", word[:20])
                continue
            try:
                yield parse_carmen_line(tokens)
            except (MalformedLine, InvalidScanError) as exc:
                self._skip(f"malformed {word} line", f"line {line_no}", str(exc))

    def record_counts(self) -> dict[str, int]:
        """Number of lines of each record type (first token), comments as ``#``."""
        counts: Counter[str] = Counter()
        for _, line in self._lines():
            tokens = line.split(maxsplit=1)
            if tokens:
                counts["#" if tokens[0].startswith("#") else tokens[0][:20]] += 1
        return dict(counts)

    def describe(self) -> dict[str, object]:
        """Kind, path, record counts and the number of laser lines."""
        counts = self.record_counts()
        info = super().describe()
        info["records"] = counts
        info["scans"] = sum(counts.get(word, 0) for word in _LASER_WORDS)
        return info
