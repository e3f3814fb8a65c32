"""``laser-corners view``: a headless .rrd recording, read back with rerun's RRD reader."""

from __future__ import annotations

import sys
from collections import defaultdict
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from conftest import real_file
from laser_corners import CornerDetector
from laser_corners.cli import app
from laser_corners.io import open_scans

rerun_chunk = pytest.importorskip("rerun.chunk", reason="needs rerun-sdk (laser-corners[viewer])")


def _read_rrd(path: Path) -> dict[str, dict[int, dict[str, list]]]:
    """entity path -> scan index -> column name -> values of that row."""
    rows: dict[str, dict[int, dict[str, list]]] = defaultdict(dict)
    for chunk in rerun_chunk.RrdReader(path).stream().to_chunks():
        if chunk.is_static or "scan" not in chunk.timeline_names:
            continue
        batch = chunk.to_record_batch()
        scans = batch.column("scan").to_pylist()
        columns = [n for n in batch.schema.names if ":" in n]
        for i, scan in enumerate(scans):
            rows[chunk.entity_path][scan] = {c: batch.column(c)[i].as_py() for c in columns}
    return rows


def _positions(row: dict[str, list], archetype: str = "Points2D") -> np.ndarray:
    return np.asarray(row[f"{archetype}:positions"], dtype=float).reshape(-1, 2)


def test_view_saves_scans_keypoints_and_map_frame(tmp_path: Path) -> None:
    log = real_file("fr079-corrected.clf.gz")  # CARMEN log with map-frame laser poses
    out = tmp_path / "fr079.rrd"
    result = CliRunner().invoke(
        app, ["view", str(log), "--save", str(out), "--max-scans", "40", "--every", "2"]
    )
    assert result.exit_code == 0, result.output
    assert "40 scans" in result.output and "40 scans with a pose" in result.output
    rows = _read_rrd(out)

    scans = list(open_scans(log))[:80:2]
    indices = list(range(0, 80, 2))
    detector = CornerDetector()
    assert sorted(rows["/sensor/scan"]) == indices
    assert sorted(rows["/stats/keypoints"]) == indices
    n_keypoints = 0
    for index, scan in zip(indices, scans, strict=True):
        keypoints = detector.detect(scan)
        n_keypoints += len(keypoints)
        xy, valid = scan.to_cartesian()
        np.testing.assert_allclose(_positions(rows["/sensor/scan"][index]), xy[valid], atol=1e-6)
        count = rows["/stats/keypoints"][index]["Scalars:scalars"]
        assert count == [float(len(keypoints))]
        if not len(keypoints):
            assert index not in rows["/sensor/keypoints"]
            continue
        np.testing.assert_allclose(
            _positions(rows["/sensor/keypoints"][index]), keypoints.xy, atol=1e-6
        )
        mapped = keypoints.transformed(scan.pose)
        np.testing.assert_allclose(_positions(rows["/map/keypoints"][index]), mapped.xy, atol=1e-5)
        arrows = rows["/sensor/keypoints/orientation"][index]
        origins = np.asarray(arrows["Arrows2D:origins"], dtype=float).reshape(-1, 2)
        np.testing.assert_allclose(origins, keypoints.xy, atol=1e-6)
        # the sensor arrow starts at the pose
        sensor = np.asarray(rows["/map/sensor"][index]["Arrows2D:origins"], dtype=float)
        np.testing.assert_allclose(sensor.reshape(2), scan.pose[:2], atol=1e-5)
    assert n_keypoints > 0
    assert f"{n_keypoints} keypoints" in result.output


def test_view_without_poses_logs_no_map(tmp_path: Path) -> None:
    bag = real_file("hokuyo270_rooms.bag")  # no odometry: scans have no pose
    out = tmp_path / "rooms.rrd"
    result = CliRunner().invoke(
        app, ["view", str(bag), "--topic", "/left_scan", "--save", str(out), "--max-scans", "5"]
    )
    assert result.exit_code == 0, result.output
    rows = _read_rrd(out)
    assert sorted(rows["/sensor/scan"]) == [0, 1, 2, 3, 4]
    assert not [entity for entity in rows if entity.startswith("/map/")]


def test_view_errors_are_one_line(tmp_path: Path) -> None:
    bag = real_file("hokuyo270_rooms.bag")
    several = CliRunner().invoke(app, ["view", str(bag), "--save", str(tmp_path / "x.rrd")])
    assert several.exit_code == 2 and "--topic /left_scan" in several.output
    log = real_file("fr079-corrected.clf.gz")
    nowhere = CliRunner().invoke(
        app, ["view", str(log), "--save", str(tmp_path / "no" / "such" / "x.rrd")]
    )
    assert nowhere.exit_code == 2
    assert "cannot write the recording" in nowhere.output
    assert len(nowhere.output.strip().splitlines()) == 1


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="display check is for Linux")
def test_view_without_display_says_to_save(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    log = real_file("fr079-corrected.clf.gz")
    result = CliRunner().invoke(app, ["view", str(log), "--max-scans", "2"])
    assert result.exit_code == 2
    assert "no display" in result.output and "--save" in result.output
