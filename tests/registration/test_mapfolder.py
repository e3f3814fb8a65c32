"""The map folder (laser_corners.registration.mapfolder): complete, partial and incomplete
folders, the pose graph read back."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from fake_slam import fake_result
from laser_corners.errors import InputError
from laser_corners.io.occupancy import OccupancyGrid
from laser_corners.registration.mapfolder import (
    FORMAT_VERSION,
    MapContents,
    load_map,
    write_map_folder,
)
from laser_corners.slam.output import SlamRunInfo
from laser_corners.viz.slam_report import write_slam_outputs


def _map(folder: Path, partial_reason: str | None = None) -> Path:
    result = fake_result(n_scans=30)
    if partial_reason is not None:
        result.interrupted, result.partial_reason = True, partial_reason
    write_slam_outputs(result, folder, SlamRunInfo("sim.bag", 1.0, 1.0))
    return folder


def test_a_partial_map_loads_and_says_why(tmp_path: Path) -> None:
    assert load_map(_map(tmp_path / "whole")).partial_reason is None
    saved = load_map(_map(tmp_path / "part", "terminated (SIGTERM)"))
    assert saved.partial_reason == "terminated (SIGTERM)" and len(saved) == 5


def test_an_incomplete_folder_is_one_line(tmp_path: Path) -> None:
    folder = _map(tmp_path / "map")
    (folder / "map.pgm").unlink()  # listed in its summary
    with pytest.raises(InputError, match=r"map: incomplete map folder, map.pgm missing$"):
        load_map(folder)
    staging = tmp_path / ".map.abcd1234.partial"  # what a run killed while writing leaves
    shutil.copytree(_map(tmp_path / "again"), staging)
    with pytest.raises(InputError, match=r"partial: an incomplete map folder \(being written"):
        load_map(staging)
    (folder / "summary.json").write_text("{not json")
    (folder / "map.pgm").write_bytes(b"")
    with pytest.raises(InputError, match=r"summary.json: unreadable"):
        load_map(folder)


def test_a_folder_without_a_summary_still_loads(tmp_path: Path) -> None:
    folder = _map(tmp_path / "map")
    (folder / "summary.json").unlink()
    assert len(load_map(folder)) == 5 and load_map(folder).partial_reason is None


def _contents(n: int = 3, grid: bool = True) -> MapContents:
    """A small map folder's contents as plain data (no SLAM run)."""
    rng = np.random.default_rng(0)
    poses = np.column_stack([np.arange(n, dtype=float), np.zeros(n), np.zeros(n)])
    points = rng.uniform(-3, 3, (4 * n, 2))
    normals = np.tile([1.0, 0.0], (4 * n, 1))
    keyframes = {
        "format_version": np.int64(FORMAT_VERSION),
        "poses": poses,
        "stamps": np.arange(n, dtype=float),
        "scan_index": np.arange(n, dtype=np.int64) * 10,
        "offsets": np.arange(n + 1, dtype=np.int64) * 4,
        "points": points,
        "normals": normals,
        "has_normal": np.ones(4 * n, bool),
        "mount": np.array([0.1, 0.0, 0.0]),
    }
    stamps = np.linspace(0.0, n - 1.0, 10 * n)
    trajectory = np.column_stack([stamps, np.zeros_like(stamps), np.zeros_like(stamps)])
    return MapContents(
        source="plain.bag",
        keyframes=keyframes,
        stamps=stamps,
        poses=trajectory,
        odometry=trajectory,
        landmarks=np.zeros((0, 8)),
        options_yaml="max_range: 30.0\n",
        summary={"input": "plain.bag", "partial": False, "warnings": []},
        grid=OccupancyGrid(np.zeros((20, 30), np.int8), 0.1, (-1.0, -1.0, 0.0)) if grid else None,
    )


def test_a_map_folder_of_plain_data_round_trips(tmp_path: Path) -> None:
    contents = _contents()
    paths = write_map_folder(tmp_path / "map", contents)
    assert set(paths) >= {"trajectory", "odometry", "landmarks", "keyframes", "map_yaml"}
    saved = load_map(tmp_path / "map")
    for key in ("poses", "stamps", "scan_index", "offsets", "points", "normals", "mount"):
        np.testing.assert_array_equal(getattr(saved, key), contents.keyframes[key])
    assert saved.grid is not None and saved.grid.occupancy.shape == (20, 30)
    summary = json.loads((tmp_path / "map" / "summary.json").read_text())
    assert summary["format_version"] == FORMAT_VERSION
    assert sorted(summary["files"].values()) == sorted(
        p.name for p in (tmp_path / "map").iterdir() if p.name != "summary.json"
    )
    assert (tmp_path / "map" / "options.yaml").read_text() == contents.options_yaml
    assert [p.name for p in tmp_path.iterdir()] == ["map"]  # no staging folder left


def test_a_folder_of_another_format_version_is_refused_in_one_line(tmp_path: Path) -> None:
    folder = tmp_path / "map"
    write_map_folder(folder, _contents())
    summary = json.loads((folder / "summary.json").read_text())
    (folder / "summary.json").write_text(json.dumps({**summary, "format_version": 2}))
    with pytest.raises(InputError) as err:
        load_map(folder)
    message = str(err.value)
    assert "\n" not in message and "summary.json: format version 2" in message


def test_a_crash_mid_write_leaves_the_previous_folder_whole(tmp_path: Path) -> None:
    folder = tmp_path / "map"
    write_map_folder(folder, _contents(3))
    before = {p.name: p.read_bytes() for p in folder.iterdir()}

    def crash(staging: Path, contents: MapContents) -> dict[str, Path]:
        assert (staging / "keyframes.npz").is_file() and staging != folder  # half written
        raise RuntimeError("killed while rendering")

    with pytest.raises(RuntimeError, match="killed while rendering"):
        write_map_folder(folder, _contents(5), render=crash)
    assert {p.name: p.read_bytes() for p in folder.iterdir()} == before
    assert [p.name for p in tmp_path.iterdir()] == ["map"]  # the staging folder removed
    assert len(load_map(folder)) == 3


def test_a_graph_that_cannot_be_written_is_a_warning_not_a_lost_folder(tmp_path: Path) -> None:
    contents = _contents(grid=False)

    def refuse(path: Path) -> None:
        raise ValueError("no graph today")

    contents.write_graph = refuse
    paths = write_map_folder(tmp_path / "map", contents)
    assert "graph" not in paths and not (tmp_path / "map" / "graph.g2o").exists()
    summary = json.loads((tmp_path / "map" / "summary.json").read_text())
    assert summary["warnings"] == ["graph.g2o not written: no graph today"]
    assert len(load_map(tmp_path / "map")) == 3
