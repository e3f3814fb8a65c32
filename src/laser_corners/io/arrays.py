"""Scans as plain arrays: ``.npz`` and ``.csv``, one scan per row plus the shared geometry.

NPZ layout (``numpy.savez``; arrays, no pickles):

========================  ===========  ===================================================
key                       shape        meaning
========================  ===========  ===================================================
``ranges``                (S, N)       ranges in metres, one scan per row (NaN: no return)
``angle_min``             ()           angle of beam 0, radians
``angle_increment``       ()           angle between beams, radians
``range_min``             () optional  default 0
``range_max``             () optional  default inf
``stamps``                (S,) opt.    seconds
``poses``                 (S, 3) opt.  sensor ``x, y, theta`` in a map frame
``frame_id``              () optional  string
========================  ===========  ===================================================

CSV layout: ``# key: value`` comment lines give the geometry (``angle_min``,
``angle_increment`` required; ``range_min``, ``range_max``, ``frame_id`` optional), then one
header row, then one scan per row. Header columns ``stamp`` and ``pose_x, pose_y, pose_theta``
are optional; every other column is a range, in beam order. Empty cells and ``nan`` are no
return. A row with the wrong number of cells or a cell that is not a number is a counted skip.

:func:`write_scans_npz` and :func:`write_scans_csv` write these layouts.
"""

from __future__ import annotations

import csv
import math
import zipfile
from collections.abc import Iterable, Iterator, Sequence
from pathlib import Path

import numpy as np

from laser_corners.errors import InputError, InvalidScanError, OutputError
from laser_corners.io.base import PartialOutput, ScanSource
from laser_corners.scan import LaserScan

__all__ = ["CsvSource", "NpzSource", "write_scans_csv", "write_scans_npz"]

_POSE_COLUMNS = ("pose_x", "pose_y", "pose_theta")


def _scalar(path: Path, data: dict[str, np.ndarray], key: str, default: float | None) -> float:
    if key not in data:
        if default is None:
            raise InputError(f"{path}: missing array {key!r} (see docs/io-and-cli.md)")
        return default
    value = np.asarray(data[key])
    if value.size != 1:
        raise InputError(f"{path}: {key!r} must be a scalar, has shape {value.shape}")
    try:
        return float(value.reshape(()))
    except (TypeError, ValueError):
        raise InputError(f"{path}: {key!r} must be a number") from None


_RECORDING_SUFFIXES = (".g2o", ".clf", ".log", ".gfs", ".carmen", ".txt", ".bag", ".csv", ".gz")


def _check_zip(path: Path) -> None:
    """Refuse, in one line saying what it is, a zip archive that holds no ``.npy`` array."""
    try:
        with zipfile.ZipFile(path) as archive:
            names = [n for n in archive.namelist() if not n.endswith("/")]
    except (OSError, zipfile.BadZipFile):
        return  # np.load says what is wrong
    if not names or any(n.endswith(".npy") for n in names):
        return
    held = ", ".join(names[:3]) + (f" and {len(names) - 3} more" if len(names) > 3 else "")
    recordings = [n for n in names if n.lower().endswith(_RECORDING_SUFFIXES)]
    hint = f"; unzip it and pass the {Path(recordings[0]).name}" if recordings else ""
    raise InputError(f"{path}: a zip archive holding {held}, not an .npz{hint}")


class NpzSource(ScanSource):
    """Scans of an ``.npz`` file (layout in the module docstring)."""

    kind = "npz"

    def __init__(self, path: Path) -> None:
        super().__init__(path)
        _check_zip(path)
        try:
            with np.load(path, allow_pickle=False) as archive:
                data = {key: archive[key] for key in archive.files}
        except (OSError, ValueError, EOFError, zipfile.BadZipFile, KeyError) as exc:
            raise InputError(f"{path}: not a readable .npz archive ({exc})") from None
        ranges = data.get("ranges")
        if ranges is None:
            raise InputError(f"{path}: missing array 'ranges' (see docs/io-and-cli.md)")
        if ranges.ndim != 2:
            raise InputError(f"{path}: 'ranges' must have shape (scans, beams), got {ranges.shape}")
        self.ranges = ranges
        self.angle_min = _scalar(path, data, "angle_min", None)
        self.angle_increment = _scalar(path, data, "angle_increment", None)
        self.range_min = _scalar(path, data, "range_min", 0.0)
        self.range_max = _scalar(path, data, "range_max", math.inf)
        n = ranges.shape[0]
        self.stamps = data.get("stamps")
        if self.stamps is not None and self.stamps.shape != (n,):
            raise InputError(f"{path}: 'stamps' must have shape ({n},), got {self.stamps.shape}")
        self.poses = data.get("poses")
        if self.poses is not None and self.poses.shape != (n, 3):
            raise InputError(f"{path}: 'poses' must have shape ({n}, 3), got {self.poses.shape}")
        self.frame_id = str(data["frame_id"]) if "frame_id" in data else ""

    @property
    def n_scans(self) -> int:
        """Number of rows of ``ranges``."""
        return int(self.ranges.shape[0])

    def _scans(self) -> Iterator[LaserScan]:
        for index in range(self.n_scans):
            self.position = f"row {index}"
            try:
                yield LaserScan(
                    self.ranges[index],
                    self.angle_min,
                    self.angle_increment,
                    self.range_min,
                    self.range_max,
                    float(self.stamps[index]) if self.stamps is not None else None,
                    self.frame_id,
                    tuple(self.poses[index]) if self.poses is not None else None,
                )
            except (InvalidScanError, TypeError, ValueError) as exc:
                self._skip("invalid row", f"row {index}", str(exc))


class CsvSource(ScanSource):
    """Scans of a ``.csv`` file (layout in the module docstring)."""

    kind = "csv"

    def __init__(self, path: Path) -> None:
        super().__init__(path)
        self.geometry: dict[str, str] = {}
        self.header: list[str] = []
        self._first_row_line = 0
        try:
            with path.open("r", encoding="utf-8", newline="") as handle:
                for line_no, line in enumerate(handle, start=1):
                    if line.startswith("#"):
                        key, sep, value = line[1:].partition(":")
                        if sep:
                            self.geometry[key.strip()] = value.strip()
                        continue
                    if not line.strip():
                        continue
                    self.header = [c.strip() for c in next(csv.reader([line]))]
                    self._first_row_line = line_no + 1
                    break
        except (OSError, UnicodeDecodeError) as exc:
            raise InputError(f"{path}: cannot read as text ({exc})") from None
        if not self.header:
            raise InputError(f"{path}: no header row (see docs/io-and-cli.md)")
        for key in ("angle_min", "angle_increment"):
            if key not in self.geometry:
                raise InputError(f"{path}: missing '# {key}: value' line (see docs/io-and-cli.md)")
        try:
            self.angle_min = float(self.geometry["angle_min"])
            self.angle_increment = float(self.geometry["angle_increment"])
            self.range_min = float(self.geometry.get("range_min", 0.0))
            self.range_max = float(self.geometry.get("range_max", math.inf))
        except ValueError as exc:
            raise InputError(f"{path}: geometry value is not a number ({exc})") from None
        self.frame_id = self.geometry.get("frame_id", "")
        columns = {name: i for i, name in enumerate(self.header)}
        self._stamp_col = columns.get("stamp")
        has_pose = [c in columns for c in _POSE_COLUMNS]
        if any(has_pose) and not all(has_pose):
            raise InputError(f"{path}: give all of {', '.join(_POSE_COLUMNS)} or none")
        self._pose_cols = [columns[c] for c in _POSE_COLUMNS] if all(has_pose) else None
        known = {"stamp", *_POSE_COLUMNS}
        self._range_cols = [i for i, name in enumerate(self.header) if name not in known]
        if len(self._range_cols) < 2:
            raise InputError(f"{path}: needs at least 2 range columns")
        self._n: int | None = None

    @property
    def n_scans(self) -> int:
        """Number of data rows (counted once, cheaply)."""
        if self._n is None:
            with self.path.open("r", encoding="utf-8", errors="replace") as handle:
                self._n = sum(
                    1
                    for line_no, line in enumerate(handle, start=1)
                    if line_no >= self._first_row_line and line.strip()
                )
        return self._n

    def _scans(self) -> Iterator[LaserScan]:
        width = len(self.header)
        with self.path.open("r", encoding="utf-8", errors="replace", newline="") as handle:
            for line_no, line in enumerate(handle, start=1):
                if line_no < self._first_row_line or not line.strip():
                    continue
                where = f"line {line_no}"
                self.position = where
                cells = next(csv.reader([line]))
                if len(cells) != width:
                    self._skip("wrong number of cells", where, f"{len(cells)} != {width}")
                    continue
                try:
                    values = np.array([c.strip() or "nan" for c in cells], dtype=np.float64)
                    stamp = float(values[self._stamp_col]) if self._stamp_col is not None else None
                    pose = (
                        tuple(float(values[i]) for i in self._pose_cols)
                        if self._pose_cols is not None
                        else None
                    )
                    yield LaserScan(
                        values[self._range_cols],
                        self.angle_min,
                        self.angle_increment,
                        self.range_min,
                        self.range_max,
                        stamp,
                        self.frame_id,
                        pose,
                    )
                except (ValueError, InvalidScanError) as exc:
                    self._skip("malformed row", where, str(exc)[:80])


def _stack(path: Path, scans: Sequence[LaserScan]) -> np.ndarray:
    if not scans:
        raise OutputError(f"{path}: no scans to write")
    first = scans[0]
    for scan in scans[1:]:
        if (scan.n_beams, scan.angle_min, scan.angle_increment) != (
            first.n_beams,
            first.angle_min,
            first.angle_increment,
        ):
            raise OutputError(f"{path}: scans written to one array file must share their geometry")
    return np.stack([s.ranges for s in scans])


def write_scans_npz(path: str | Path, scans: Iterable[LaserScan]) -> None:
    """Write scans of one geometry to ``path`` in the NPZ layout :class:`NpzSource` reads.

    ``.npz`` is appended to a ``path`` without it (as ``numpy.savez`` does). The file is
    written under a temporary name and renamed when complete.

    Raises
    ------
    OutputError
        No scans, scans of several geometries, or a path that cannot be written.
    """
    path = Path(path)
    if path.suffix != ".npz":
        path = path.with_name(path.name + ".npz")
    scans = list(scans)
    ranges = _stack(path, scans)
    first = scans[0]
    arrays: dict[str, np.ndarray] = {
        "ranges": ranges,
        "angle_min": np.float64(first.angle_min),
        "angle_increment": np.float64(first.angle_increment),
        "range_min": np.float64(first.range_min),
        "range_max": np.float64(first.range_max),
        "frame_id": np.str_(first.frame_id),
    }
    if all(s.stamp is not None for s in scans):
        arrays["stamps"] = np.array([s.stamp for s in scans], dtype=np.float64)
    if all(s.pose is not None for s in scans):
        arrays["poses"] = np.array([s.pose for s in scans], dtype=np.float64)
    with PartialOutput(path, overwrite=True).writing() as temporary:
        np.savez(temporary, **arrays)  # type: ignore[arg-type]


def write_scans_csv(path: str | Path, scans: Iterable[LaserScan]) -> None:
    """Write scans of one geometry to ``path`` in the CSV layout :class:`CsvSource` reads.

    The file is written under a temporary name and renamed when complete.

    Raises
    ------
    OutputError
        No scans, scans of several geometries, or a path that cannot be written.
    """
    path = Path(path)
    scans = list(scans)
    ranges = _stack(path, scans)
    first = scans[0]
    with_stamp = all(s.stamp is not None for s in scans)
    with_pose = all(s.pose is not None for s in scans)
    with (
        PartialOutput(path, overwrite=True).writing() as temporary,
        temporary.open("w", encoding="utf-8", newline="") as handle,
    ):
        for key in ("angle_min", "angle_increment", "range_min", "range_max"):
            handle.write(f"# {key}: {getattr(first, key)!r}\n")
        handle.write(f"# frame_id: {first.frame_id}\n")
        writer = csv.writer(handle)
        header = (["stamp"] if with_stamp else []) + (list(_POSE_COLUMNS) if with_pose else [])
        writer.writerow(header + [f"r{i}" for i in range(ranges.shape[1])])
        for scan, row in zip(scans, ranges, strict=True):
            lead = ([repr(scan.stamp)] if with_stamp else []) + (
                [repr(v) for v in scan.pose] if with_pose and scan.pose else []
            )
            writer.writerow(lead + [repr(float(r)) for r in row])
