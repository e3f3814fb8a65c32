"""The observability map (:mod:`laser_corners.eval.observability`): how often each cell was in view
and seen, on cases known by hand."""

from __future__ import annotations

import math

import numpy as np
import pytest

from laser_corners.eval.grid import Grid
from laser_corners.eval.observability import observability_map
from laser_corners.eval.visibility import points_in_view
from laser_corners.scan import LaserScan


def wall_scan(distance: float, pose: tuple[float, float, float] | None = None) -> LaserScan:
    """181 beams over [-90, 90] deg, every beam hitting at ``distance`` (a circular wall)."""
    return LaserScan(np.full(181, distance), -math.pi / 2, math.radians(1.0), 0.05, 30.0, pose=pose)


def _grid() -> Grid:
    return Grid(x0=-3.0, y0=-3.0, resolution=0.03, shape=(200, 200))


def test_observability_three_of_four_scans_in_view() -> None:
    grid = _grid()
    cell = grid.cell_of([[2.0, 0.0]])[0]
    feature = grid.center_of([cell])[0]
    neighbour = grid.center_of([cell + np.array([0, 1])])[0]
    scans = [
        wall_scan(2.5, (0.0, 0.0, 0.0)),  # sees the feature, detects it
        wall_scan(2.5, (0.0, 0.0, 0.0)),  # sees it, detects it
        wall_scan(2.5, (0.0, 0.0, 0.0)),  # sees it, detects it
        wall_scan(2.5, (0.0, 0.0, 0.0)),  # sees it, keypoint lands in the neighbour cell
        wall_scan(1.0, (0.0, 0.0, 0.0)),  # occluded by a wall at 1 m
        wall_scan(2.5, (0.0, 0.0, math.pi)),  # looks away
    ]
    kps = [[feature], [feature], [feature], [neighbour], np.zeros((0, 2)), np.zeros((0, 2))]
    obs = observability_map(scans, kps, grid)
    r, c = cell
    assert obs.n_scans == 6
    assert obs.in_view[r, c] == 4
    assert obs.hits[r, c] == 3
    assert obs.ratio[r, c] == pytest.approx(0.75)
    assert obs.ratio_n8[r, c] == pytest.approx(1.0)  # the 4th keypoint is an 8-neighbour
    assert obs.ratio[r, c + 1] == pytest.approx(0.25)
    # a cell never in view is NaN, a cell in view without keypoints 0
    assert math.isnan(obs.ratio[0, 0])
    centre = grid.cell_of([[1.0, 0.5]])[0]
    assert obs.ratio[centre[0], centre[1]] == 0.0
    # without occlusion the occluded scan counts as a view: 3 of 5
    free = observability_map(scans, kps, grid, occlusion=False)
    assert free.ratio[r, c] == pytest.approx(0.6)


def test_observability_explicit_poses_and_skipped_scans() -> None:
    grid = _grid()
    feature = grid.center_of(grid.cell_of([[0.0, 2.0]]))[0]
    scans = [wall_scan(2.5), wall_scan(2.5)]
    # the sensor looks along +y, so the feature at (0, 2) is straight ahead
    obs = observability_map(scans, [[feature], []], grid, poses=[(0, 0, math.pi / 2)] * 2)
    r, c = grid.cell_of([feature])[0]
    assert obs.ratio[r, c] == pytest.approx(0.5)
    no_pose = observability_map(scans, [[feature], []], grid)  # scans have no pose: skipped
    assert no_pose.n_scans == 0
    assert np.all(no_pose.in_view == 0)


@pytest.mark.parametrize("occlusion", [True, False])
def test_observability_block_culling_matches_the_per_point_test(occlusion: bool) -> None:
    """The grid pass (culled by blocks of cells) counts exactly the cells points_in_view sees."""
    from laser_corners.sim import UST_10LX, rectangular_room

    world = rectangular_room()
    rng = np.random.default_rng(3)
    full_turn = LaserScan(np.full(360, 1.0), -math.pi, math.radians(1.0), 0.05, 30.0)
    scans = [
        world.scan((-1.0, -0.5, 0.4), UST_10LX, 0.01, rng),
        world.scan((2.0, 1.2, -2.5), UST_10LX, 0.01, rng),
        LaserScan(
            world.cast((0.5, -1.0, 3.0), full_turn.angles),
            -math.pi,
            math.radians(1.0),
            0.05,
            30.0,
            pose=(0.5, -1.0, 3.0),
        ),
    ]
    grid = Grid(-3.5, -2.5, 0.05, (100, 140))
    obs = observability_map(scans, [np.zeros((0, 2))] * 3, grid, occlusion=occlusion, max_range=4.0)
    rows, cols = np.indices(grid.shape)
    centres = grid.center_of(np.stack([rows.ravel(), cols.ravel()], axis=1))
    expected = np.zeros(grid.shape, dtype=int)
    for scan in scans:
        x, y, th = scan.pose
        c, s = math.cos(th), math.sin(th)
        local = (centres - [x, y]) @ np.array([[c, -s], [s, c]])
        seen = points_in_view(scan, local, occlusion=occlusion, max_range=4.0)
        expected += seen.reshape(grid.shape)
    np.testing.assert_array_equal(obs.in_view, expected)
    assert expected.max() == 3 and (expected == 0).any()
