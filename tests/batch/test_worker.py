"""One batch job (:mod:`laser_corners.batch.worker`): writes what the detector finds with its
parameters recorded; an unexpected error is recorded with its traceback."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pyarrow.parquet as pq
import pytest

from conftest import real_file
from laser_corners import CornerDetector
from laser_corners.batch import (
    BatchJob,
    ParamsChoice,
    run_job,
)
from laser_corners.io import open_scans


def test_run_job_writes_what_the_detector_finds(tmp_path: Path) -> None:
    log = real_file("fr079-corrected.clf.gz")
    job = BatchJob(str(log), None, "fr079.parquet")
    result = run_job(job, tmp_path, ParamsChoice(), threads=2)
    assert result.status == "done", result.error
    assert not (tmp_path / "fr079.parquet.partial").exists()

    scans = list(open_scans(log))
    expected = CornerDetector().detect_many(scans)
    table = pq.read_table(tmp_path / "fr079.parquet")
    assert result.scans == len(scans)
    assert result.keypoints == table.num_rows == sum(len(k) for k in expected)
    assert 0.0 < result.read_seconds + result.detect_seconds + result.write_seconds
    assert result.read_seconds + result.detect_seconds + result.write_seconds <= result.seconds
    counts = np.bincount(table.column("scan_index").to_numpy(), minlength=len(scans))
    assert counts.tolist() == [len(k) for k in expected]
    xy = np.column_stack([table.column("x").to_numpy(), table.column("y").to_numpy()])
    np.testing.assert_allclose(xy, np.concatenate([k.xy for k in expected]))
    # the CARMEN log has map-frame laser poses, so the map columns are filled
    assert np.isfinite(table.column("map_x").to_numpy()).all()
    metadata = table.schema.metadata
    assert b"min_points" in metadata[b"laser_corners.params"]
    assert metadata[b"laser_corners.input"].decode() == str(log)
    assert b"M. F. Silva" in metadata[b"laser_corners.method"]


def test_run_job_with_auto_preset_and_overrides_records_them(tmp_path: Path) -> None:
    log = real_file("intel-corrected.clf.gz")
    choice = ParamsChoice(preset="auto", overrides=("min_points=6",))
    result = run_job(BatchJob(str(log), None, "intel.parquet"), tmp_path, choice, threads=1)
    assert result.status == "done", result.error
    params = pq.read_schema(tmp_path / "intel.parquet").metadata[b"laser_corners.params"]
    assert b"min_points: 6" in params
    assert b"scales:\n- 0.05\n" in params  # the auto preset's scales, not the paper's 5
    assert params.count(b"\n- ") > 5


def test_unexpected_error_is_recorded_with_its_traceback(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    log = real_file("fr079-corrected.clf.gz")

    def broken(self: CornerDetector, scan: object) -> None:
        raise RuntimeError("kernel exploded")

    monkeypatch.setattr(CornerDetector, "detect", broken)
    monkeypatch.setattr(CornerDetector, "detect_many", broken)
    result = run_job(BatchJob(str(log), None, "fr079.parquet"), tmp_path, threads=1)
    assert result.status == "failed"
    assert result.error.startswith("RuntimeError: kernel exploded")
    assert "\n" not in result.error
    traceback_text = (tmp_path / "errors" / "fr079.parquet.txt").read_text(encoding="utf-8")
    assert "Traceback" in traceback_text and "kernel exploded" in traceback_text
    assert not (tmp_path / "fr079.parquet").exists()
    assert not (tmp_path / "fr079.parquet.partial").exists()
