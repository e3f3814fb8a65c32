"""The batch manifest (:mod:`laser_corners.batch.manifest`): a line torn by a kill loses only
itself."""

from __future__ import annotations

from pathlib import Path

from laser_corners.batch import (
    JobResult,
    Manifest,
)


def test_manifest_survives_a_torn_line(tmp_path: Path) -> None:
    manifest = Manifest(tmp_path)
    done = JobResult("/a.bag", None, "a.parquet", "done", scans=3, keypoints=4)
    manifest.append(done)
    with manifest.path.open("a", encoding="utf-8") as handle:
        handle.write('{"input": "/b.bag", "topic": nu')  # killed while writing
    later = JobResult("/c.bag", None, "c.parquet", "failed", error="boom")
    manifest.append(later)
    records = manifest.load()
    assert set(records) == {"/a.bag", "/c.bag"}
    assert records["/a.bag"].keypoints == 4 and records["/c.bag"].error == "boom"
