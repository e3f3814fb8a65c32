"""A SLAM result as a map folder (laser_corners.slam.output): its contents as plain data, the
folder written without pictures (the ROS node's), a grown map naming its OLD."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from fake_slam import fake_result
from laser_corners.registration.mapfolder import LANDMARK_COLUMNS, load_map
from laser_corners.slam.output import SlamRunInfo, map_contents, slam_summary, write_slam_map


def test_the_contents_are_plain_data_and_json_safe() -> None:
    result = fake_result(n_scans=30)
    info = SlamRunInfo("in.bag", 0.0, 1.0, closure_consistency=math.nan)
    contents = map_contents(result, info)
    assert contents.poses.shape == (30, 3) and contents.stamps.shape == (30,)
    assert contents.landmarks.shape[1] == len(LANDMARK_COLUMNS)
    assert contents.grid is not None and contents.summary["closure_consistency"] is None
    np.testing.assert_allclose(contents.keyframes["poses"], result.keyframe_poses)
    json.dumps(contents.summary, allow_nan=False)  # no NaN left


def test_a_map_without_pictures_loads_and_lists_what_it_holds(tmp_path: Path) -> None:
    paths = write_slam_map(fake_result(n_scans=30), tmp_path / "m", SlamRunInfo("in.bag", 1, 1))
    assert "map_png" not in paths and not (tmp_path / "m" / "map.png").exists()
    summary = json.loads((tmp_path / "m" / "summary.json").read_text())
    assert "map.png" not in summary["files"].values() and summary["format_version"] == 1
    assert len(load_map(tmp_path / "m")) == 5


def test_a_grown_maps_summary_names_its_old_map() -> None:
    result = fake_result(n_scans=30)
    info = SlamRunInfo("in.bag", 1.0, 1.0)
    assert slam_summary(result, info)["prior_map"] is None
    result.prior_map, result.prior_keyframes = "/maps/day1", 4
    assert slam_summary(result, info)["prior_map"] == {"folder": "/maps/day1", "keyframes": 4}
