"""Keypoint tables: CSV and Parquet writers.

Both have the calls of :class:`~laser_corners.io.base.KeypointWriter`. Output is written
incrementally under a temporary name beside the final one (``STEM.XXXXXXXX.partial.SUFFIX``):
CSV rows are flushed and Parquet row groups written every ``flush_every`` scans; ``close()``
finishes the file (the Parquet footer) and renames it, so an interrupted run (Ctrl-C) keeps
what was written, and a killed one leaves only the temporary file.

Table columns, one row per keypoint: ``stamp, scan_index, beam_index, x, y,
opening_angle_deg, orientation, n_scales, rmse, n_merged, cov_xx, cov_xy, cov_yy`` (sensor
frame; the keypoint covariance, m², see :mod:`laser_corners.kernel.covariance`), plus ``map_x,
map_y`` (the keypoint in the frame of the scan poses) when the recording has poses; empty
(CSV) or null (Parquet) for a scan without a pose.
"""

from __future__ import annotations

import csv
import math
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from laser_corners.errors import OutputError, first_line
from laser_corners.io.base import KeypointWriter, PartialOutput
from laser_corners.keypoints import Keypoints
from laser_corners.scan import LaserScan, transform_points

__all__ = [
    "TABLE_COLUMNS",
    "CsvKeypointWriter",
    "KeypointWriter",
    "ParquetKeypointWriter",
]

TABLE_COLUMNS: tuple[str, ...] = (
    "stamp",
    "scan_index",
    "beam_index",
    "x",
    "y",
    "opening_angle_deg",
    "orientation",
    "n_scales",
    "rmse",
    "n_merged",
    "cov_xx",
    "cov_xy",
    "cov_yy",
)
"""Columns of the CSV/Parquet keypoint tables (``map_x, map_y`` follow when poses are known)."""
MAP_COLUMNS: tuple[str, ...] = ("map_x", "map_y")
_INT_COLUMNS = frozenset({"scan_index", "beam_index", "n_scales", "n_merged"})


class _TableWriter(KeypointWriter):
    """Buffers keypoint rows and flushes them every ``flush_every`` scans."""

    def __init__(self, path: Path, with_map: bool, flush_every: int = 100) -> None:
        super().__init__()
        self.path = path
        self._partial = PartialOutput(path, overwrite=True)
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
                    mapped = transform_points(keypoints.xy, scan.pose)
                    block["map_x"], block["map_y"] = mapped[:, 0], mapped[:, 1]
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
                    transform_points(k.xy, pose)
                    if (pose := scans[i].pose) is not None
                    else np.full((len(k), 2), math.nan)
                    for i, k in zip(with_rows, found, strict=True)
                ]
                both = np.concatenate(mapped)
                block["map_x"], block["map_y"] = both[:, 0], both[:, 1]
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
        """Write the buffered rows, close the file and give it its final name."""
        if not self._closed:
            self._closed = True
            try:
                self.flush()
            finally:
                self._finish()
            assert self._partial is not None
            self._partial.publish()
            self.closed = True

    def _finish(self) -> None:
        raise NotImplementedError


class CsvKeypointWriter(_TableWriter):
    """Keypoints as CSV, one header row then one row per keypoint (flushed incrementally)."""

    def __init__(self, path: Path, with_map: bool, flush_every: int = 100) -> None:
        super().__init__(path, with_map, flush_every)
        assert self._partial is not None
        try:
            self._handle = self._partial.temporary.open("w", encoding="utf-8", newline="")
        except OSError as exc:
            self._partial.discard()
            raise OutputError(f"{path}: cannot write ({exc.strerror})") from None
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
        assert self._partial is not None
        try:
            self._writer = pq.ParquetWriter(str(self._partial.temporary), self._schema)
        except OSError as exc:
            self._partial.discard()
            raise OutputError(f"{path}: cannot write ({first_line(exc)})") from None

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
