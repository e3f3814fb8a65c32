"""The map folder (laser_corners.registration.mapfolder): complete, partial and incomplete
folders, the pose graph read back."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

from fake_slam import fake_result
from laser_corners.errors import InputError
from laser_corners.registration.mapfolder import load_map
from laser_corners.viz.slam_report import SlamRunInfo, write_slam_outputs


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
