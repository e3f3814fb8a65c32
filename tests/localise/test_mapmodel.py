"""The map model's searches (``localise.mapmodel``): the whole-map, window and local
searches find a scan's pose on the lattice they are given, through the shared branch and
bound."""

from __future__ import annotations

import math

import numpy as np
import pytest
from test_localiser import building, loaded_building, scans_along

from laser_corners.localise import LocaliseOptions
from laser_corners.localise.mapmodel import GLOBAL_GRID, WALL_CLEARANCE, MapModel
from laser_corners.pose import poses_apart
from laser_corners.registration.points import scan_points


@pytest.fixture(scope="module")
def model_world(tmp_path_factory):
    saved, truth = loaded_building(tmp_path_factory)
    return MapModel(saved, LocaliseOptions()), truth


def _points(truth: np.ndarray, at: int) -> np.ndarray:
    scan = scans_along(building(), truth[at : at + 1], 4)[0]
    return scan_points(scan, np.zeros(3), 0.1, 30.0, 0.15).xy


def test_the_lattice_is_near_a_keyframe_and_clear_of_the_walls(model_world) -> None:
    model, _ = model_world
    options = LocaliseOptions()
    positions = model.positions
    assert len(positions) > 100
    step = model.lattice.cells * GLOBAL_GRID
    assert model.lattice.cells == round(options.global_resolution / GLOBAL_GRID)
    keyframes = model.saved.poses[:, :2]
    nearest = np.min(np.hypot(*(positions[:, None, :] - keyframes[None]).transpose(2, 0, 1)), 1)
    assert nearest.max() <= options.global_reach + step  # the keyframe rounded to the lattice
    wall = np.min(np.hypot(*(positions[:, None, :] - _map_points(model)[None]).T), axis=0)
    assert wall.min() > WALL_CLEARANCE - GLOBAL_GRID


def _map_points(model: MapModel) -> np.ndarray:
    xy, _, _ = model.saved.world_points()
    return xy[:: max(1, len(xy) // 3000)]


@pytest.mark.parametrize("at", [40, 200, 330])
def test_the_global_search_finds_the_true_pose_among_distinct_candidates(model_world, at) -> None:
    model, truth = model_world
    found = model.global_search(_points(truth, at), 0.035, 16)
    assert len(found) == 16
    assert [s for _, s in found] == sorted((s for _, s in found), reverse=True)
    for a, (p, _) in enumerate(found):
        assert all(poses_apart(p, q, 1.0, 0.3) for q, _ in found[:a])
    near = [
        p
        for p, _ in found[:3]
        if math.hypot(*(p[:2] - truth[at, :2])) < 0.35
        and abs((p[2] - truth[at, 2] + math.pi) % (2 * math.pi) - math.pi) < 0.06
    ]
    assert near


def test_the_window_search_stays_in_its_window(model_world) -> None:
    model, truth = model_world
    centre = truth[120] + np.array([0.3, -0.2, 0.05])
    search = model.window_slices(_points(truth, 120), centre, 1.0, 0.2, 0.02, 4, (0.5, 0.1))
    found = search.finish()
    assert found
    assert math.hypot(*(found[0][0][:2] - truth[120, :2])) < 0.3
    for p, _ in found:
        assert math.hypot(*(p[:2] - centre[:2])) <= 1.0 + 1e-9
        assert abs(p[2] - centre[2]) <= 0.2 + 0.02


def test_the_local_search_moves_to_the_pose_and_stays_put_off_the_map(model_world) -> None:
    model, truth = model_world
    centre = truth[250] + np.array([0.2, 0.2, -0.04])
    pose = model.local_search(_points(truth, 250), centre, 0.4, 0.1)
    assert math.hypot(*(pose[:2] - truth[250, :2])) < 0.15
    far = np.full((30, 2), 1000.0) + np.arange(30)[:, None]  # no point lands on the grid
    assert np.array_equal(model.local_search(far, centre, 0.4, 0.1), centre)
