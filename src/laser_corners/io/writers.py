"""Keypoint writers: CSV, Parquet, a copy of the input bag with keypoint topics, or nothing.

Every writer has the same two calls, ``write(scan_index, scan, keypoints)`` and ``close()``, so
the detection loop never asks which one it has (the base class writes nothing). Output is
written incrementally: CSV rows are flushed and Parquet row groups written every
``flush_every`` scans, so an interrupted run (Ctrl-C) keeps what was written once ``close()``
runs (use the writer as a context manager).

Table columns, one row per keypoint: ``stamp, scan_index, beam_index, x, y,
opening_angle_deg, orientation, n_scales, rmse, n_merged, cov_xx, cov_xy, cov_yy`` (sensor
frame; the keypoint covariance, m², see :mod:`laser_corners.covariance`), plus ``map_x,
map_y`` (the keypoint in the frame of the scan poses) when the recording has poses; empty
(CSV) or null (Parquet) for a scan without a pose.
"""

from __future__ import annotations

import csv
import math
from collections.abc import Sequence
from pathlib import Path
from types import TracebackType
from typing import Any

import numpy as np

from laser_corners.errors import InputError
from laser_corners.io.source import ScanSource
from laser_corners.keypoints import Keypoints
from laser_corners.scan import LaserScan

__all__ = [
    "TABLE_COLUMNS",
    "CsvKeypointWriter",
    "KeypointWriter",
    "ParquetKeypointWriter",
    "open_keypoint_writer",
]

TABLE_COLUMNS: tuple[str, ...] = (
    "stamp", "scan_index", "beam_index", "x", "y", "opening_angle_deg", "orientation",
    "n_scales", "rmse", "n_merged", "cov_xx", "cov_xy", "cov_yy",
)  # fmt: skip
"""Columns of the CSV/Parquet keypoint tables (``map_x, map_y`` follow when poses are known)."""
MAP_COLUMNS: tuple[str, ...] = ("map_x", "map_y")
_INT_COLUMNS = frozenset({"scan_index", "beam_index", "n_scales", "n_merged"})


class KeypointWriter:
    """Writes nothing: the writer used when no output is asked for (and the base class).

    Attributes
    ----------
    path : Path or None
        The output.
    n_scans, n_keypoints : int
        Scans and keypoints handed to :meth:`write` so far.
    """

    path: Path | None = None

    def __init__(self) -> None:
        self.n_scans = 0
        self.n_keypoints = 0

    def write(self, scan_index: int, scan: LaserScan, keypoints: Keypoints) -> None:
        """Record the keypoints of the scan of index ``scan_index``."""
        self.n_scans += 1
        self.n_keypoints += len(keypoints)

    def write_many(
        self, first_index: int, scans: Sequence[LaserScan], keypoints: Sequence[Keypoints]
    ) -> None:
        """Record consecutive scans at once: scan ``first_index + i`` found ``keypoints[i]``.

        Same result as calling :meth:`write` for each; table writers do it in one block.
        """
        for offset, (scan, found) in enumerate(zip(scans, keypoints, strict=True)):
            self.write(first_index + offset, scan, found)

    def close(self) -> None:
        """Flush and close the output (idempotent)."""

    def __enter__(self) -> KeypointWriter:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()


class _TableWriter(KeypointWriter):
    """Buffers keypoint rows and flushes them every ``flush_every`` scans."""

    def __init__(self, path: Path, with_map: bool, flush_every: int = 100) -> None:
        super().__init__()
        self.path = path
        self.columns = TABLE_COLUMNS + (MAP_COLUMNS if with_map else ())
        self.with_map = with_map
        self.flush_every = max(1, flush_every)
        self._buffer: list[dict[str, np.ndarray]] = []
        self._pending_scans = 0
        self._closed = False

    def write(self, scan_index: int, scan: LaserScan, keypoints: Keypoints) -> None:
        """Buffer the rows of one scan; flush every ``flush_every`` scans."""
        super().write(scan_index, scan, keypoints)
        m = len(keypoints)
        self._pending_scans += 1
        if m:
            stamp = scan.stamp if scan.stamp is not None else math.nan
            block = {
                "stamp": np.full(m, stamp),
                "scan_index": np.full(m, scan_index, dtype=np.int64),
                "beam_index": keypoints.beam_index,
                "x": keypoints.xy[:, 0],
                "y": keypoints.xy[:, 1],
                "opening_angle_deg": keypoints.opening_angle_deg,
                "orientation": keypoints.orientation,
                "n_scales": keypoints.n_scales,
                "rmse": keypoints.rmse,
                "n_merged": keypoints.n_merged,
                "cov_xx": keypoints.cov[:, 0, 0],
                "cov_xy": keypoints.cov[:, 0, 1],
                "cov_yy": keypoints.cov[:, 1, 1],
            }
            if self.with_map:
                if scan.pose is not None:
                    mapped = keypoints.transformed(scan.pose)
                    block["map_x"], block["map_y"] = mapped.xy[:, 0], mapped.xy[:, 1]
                else:
                    block["map_x"] = block["map_y"] = np.full(m, math.nan)
            self._buffer.append(block)
        if self._pending_scans >= self.flush_every:
            self.flush()

    def write_many(
        self, first_index: int, scans: Sequence[LaserScan], keypoints: Sequence[Keypoints]
    ) -> None:
        """Buffer the rows of consecutive scans as one block (as :meth:`write` for each)."""
        if len(scans) != len(keypoints):
            raise ValueError(f"{len(scans)} scans but {len(keypoints)} keypoint sets")
        counts = np.fromiter((len(k) for k in keypoints), dtype=np.int64, count=len(keypoints))
        self.n_scans += len(scans)
        self.n_keypoints += int(counts.sum())
        self._pending_scans += len(scans)
        with_rows = [i for i, m in enumerate(counts) if m]
        if with_rows:
            found = [keypoints[i] for i in with_rows]
            stamps = np.array(
                [math.nan if scans[i].stamp is None else scans[i].stamp for i in with_rows],
                dtype=np.float64,
            )
            indices = np.array(with_rows, dtype=np.int64) + first_index
            repeats = counts[with_rows]
            xy = np.concatenate([k.xy for k in found])
            block = {
                "stamp": np.repeat(stamps, repeats),
                "scan_index": np.repeat(indices, repeats),
                "beam_index": np.concatenate([k.beam_index for k in found]),
                "x": xy[:, 0],
                "y": xy[:, 1],
            }
            for name in ("opening_angle_deg", "orientation", "n_scales", "rmse", "n_merged"):
                block[name] = np.concatenate([getattr(k, name) for k in found])
            cov = np.concatenate([k.cov for k in found])
            block["cov_xx"] = cov[:, 0, 0]
            block["cov_xy"] = cov[:, 0, 1]
            block["cov_yy"] = cov[:, 1, 1]
            if self.with_map:
                mapped = [
                    k.transformed(pose).xy
                    if (pose := scans[i].pose) is not None
                    else np.full((len(k), 2), math.nan)
                    for i, k in zip(with_rows, found, strict=True)
                ]
                map_xy = np.concatenate(mapped)
                block["map_x"], block["map_y"] = map_xy[:, 0], map_xy[:, 1]
            self._buffer.append(block)
        if self._pending_scans >= self.flush_every:
            self.flush()

    def _take(self) -> dict[str, np.ndarray]:
        merged = {
            c: np.concatenate([b[c] for b in self._buffer])
            if self._buffer
            else np.zeros(0, dtype=np.int64 if c in _INT_COLUMNS else np.float64)
            for c in self.columns
        }
        self._buffer = []
        self._pending_scans = 0
        return merged

    def flush(self) -> None:
        """Write the buffered rows."""
        raise NotImplementedError

    def close(self) -> None:
        """Write the buffered rows and close the file."""
        if not self._closed:
            self._closed = True
            self.flush()
            self._finish()

    def _finish(self) -> None:
        raise NotImplementedError


class CsvKeypointWriter(_TableWriter):
    """Keypoints as CSV, one header row then one row per keypoint (flushed incrementally)."""

    def __init__(self, path: Path, with_map: bool, flush_every: int = 100) -> None:
        super().__init__(path, with_map, flush_every)
        try:
            self._handle = path.open("w", encoding="utf-8", newline="")
        except OSError as exc:
            raise InputError(f"{path}: cannot write ({exc.strerror})") from None
        self._csv = csv.writer(self._handle)
        self._csv.writerow(self.columns)
        self._handle.flush()

    def flush(self) -> None:
        """Write the buffered rows and flush the file."""
        if not self._buffer:
            return
        data = self._take()
        cells = [
            data[c].astype(str)
            if c in _INT_COLUMNS
            else np.array([repr(float(v)) if math.isfinite(v) else "" for v in data[c]])
            for c in self.columns
        ]
        self._csv.writerows(zip(*cells, strict=True))
        self._handle.flush()

    def _finish(self) -> None:
        self._handle.close()


class ParquetKeypointWriter(_TableWriter):
    """Keypoints as Parquet (pyarrow), one row group per flush.

    ``metadata`` (str -> str) goes into the file's schema metadata.
    """

    def __init__(
        self,
        path: Path,
        with_map: bool,
        flush_every: int = 200,
        metadata: dict[str, str] | None = None,
    ) -> None:
        super().__init__(path, with_map, flush_every)
        import pyarrow as pa
        import pyarrow.parquet as pq

        self._pa = pa
        fields = [
            pa.field(c, pa.int64() if c in _INT_COLUMNS else pa.float64(), nullable=True)
            for c in self.columns
        ]
        self._schema = pa.schema(fields, metadata=metadata or {})
        try:
            self._writer = pq.ParquetWriter(str(path), self._schema)
        except OSError as exc:
            raise InputError(f"{path}: cannot write ({exc})") from None

    def flush(self) -> None:
        """Write the buffered rows as one row group."""
        if not self._buffer:
            return
        data = self._take()
        arrays = [
            self._pa.array(data[c], type=f.type, from_pandas=f.type == self._pa.float64())
            for c, f in zip(self.columns, self._schema, strict=True)
        ]
        self._writer.write_table(self._pa.Table.from_arrays(arrays, schema=self._schema))

    def _finish(self) -> None:
        self._writer.close()


def open_keypoint_writer(
    path: str | Path | None,
    source: ScanSource,
    *,
    with_map: bool,
    metadata: dict[str, str] | None = None,
    **options: Any,
) -> KeypointWriter:
    """The writer for ``path``, chosen by its suffix.

    Parameters
    ----------
    path : str, Path or None
        ``.csv``, ``.parquet``, ``.bag`` (ROS 1 input) or ``.mcap`` (ROS 2/MCAP input); None:
        a writer that writes nothing.
    source : ScanSource
        The recording being processed (the bag writers copy it).
    with_map : bool
        Add ``map_x, map_y`` columns (the recording has poses).
    metadata : dict of str to str, optional
        Stored in the Parquet schema metadata.
    **options
        Passed on to the writer (``flush_every``; ``ns``, ``lifetime`` for bags).

    Raises
    ------
    InputError
        Unknown suffix, a bag output for a non-bag input, or a path that cannot be written.
    """
    if path is None:
        return KeypointWriter()
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix == ".csv":
        return CsvKeypointWriter(path, with_map, **options)
    if suffix in (".parquet", ".pq"):
        return ParquetKeypointWriter(path, with_map, metadata=metadata, **options)
    if suffix in (".bag", ".mcap"):
        from laser_corners.io.bagwriter import BagKeypointWriter

        return BagKeypointWriter(path, source, **options)
    raise InputError(
        f"{path}: unknown output kind {suffix or '(no suffix)'!r}; "
        "use .csv, .parquet, .bag or .mcap"
    )
