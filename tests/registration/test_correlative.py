"""The correlative search: its branch and bound finds what scoring every pose finds."""

from __future__ import annotations

import math

import numpy as np
import pytest

from laser_corners.registration.correlative import ScoreGrid, search


def _exhaustive(grid: ScoreGrid, pts: np.ndarray, center: np.ndarray, n_xy: int, yaws):
    """Every pose of the lattice scored with numpy: (mean score, pose) of the best."""
    res, ny, nx = grid.resolution, *grid.score.shape
    best, pose = -1.0, None
    off = np.arange(-n_xy, n_xy + 1)
    for yaw in yaws:
        c, s = math.cos(yaw), math.sin(yaw)
        x = c * pts[:, 0] - s * pts[:, 1] + center[0] - grid.origin[0]
        y = s * pts[:, 0] + c * pts[:, 1] + center[1] - grid.origin[1]
        cx, cy = np.floor(x / res + 0.5).astype(int), np.floor(y / res + 0.5).astype(int)
        iy = cy[None, None, :] + off[:, None, None]
        ix = cx[None, None, :] + off[None, :, None]
        inside = (iy >= 0) & (iy < ny) & (ix >= 0) & (ix < nx)
        values = np.where(inside, grid.score[np.clip(iy, 0, ny - 1), np.clip(ix, 0, nx - 1)], 0)
        total = values.sum(axis=2)
        a, b = np.unravel_index(np.argmax(total), total.shape)
        if total[a, b] > best:
            best = total[a, b]
            pose = np.array([center[0] + off[b] * res, center[1] + off[a] * res, yaw])
    return best / len(pts), pose


def _room(seed: int):
    """A walled room with clutter, its grid, a true pose, the points seen there, a guess."""
    rng = np.random.default_rng(seed)
    walls = [np.column_stack([np.linspace(0, 8, 160), np.full(160, y)]) for y in (0.0, 5.0)]
    walls += [np.column_stack([np.full(100, x), np.linspace(0, 5, 100)]) for x in (0.0, 8.0)]
    walls.append(rng.uniform([1, 1], [7, 4], (40, 2)))  # clutter
    xy = np.concatenate(walls)
    xy = xy + rng.normal(0, 0.01, xy.shape)
    grid = ScoreGrid.build(xy, 0.05, 0.05, 1.0)
    truth = np.array([rng.uniform(2, 6), rng.uniform(1.5, 3.5), rng.uniform(-3, 3)])
    c, s = math.cos(truth[2]), math.sin(truth[2])
    pts = (xy[rng.choice(len(xy), 80, replace=False)] - truth[:2]) @ np.array([[c, -s], [s, c]])
    guess = truth + rng.uniform([-0.3, -0.3, -0.1], [0.3, 0.3, 0.1])
    return grid, truth, pts, guess


@pytest.mark.parametrize("seed", range(8))
def test_branch_and_bound_finds_the_best_pose_of_the_lattice(seed: int) -> None:
    grid, truth, pts, guess = _room(seed)
    score, pose = search(grid, pts, guess, 0.4, 0.12, yaw_step=0.02)
    n_yaw = math.ceil(0.12 / 0.02)
    yaws = guess[2] + 0.02 * np.arange(-n_yaw, n_yaw + 1)
    want_score, want_pose = _exhaustive(grid, pts, guess, math.ceil(0.4 / 0.05), yaws)
    assert score == pytest.approx(want_score, abs=1e-6)
    np.testing.assert_allclose(pose, want_pose, atol=1e-9)
    assert np.hypot(*(pose[:2] - truth[:2])) < 0.08  # and the lattice's best is the truth


@pytest.mark.parametrize("seed", range(4))
def test_a_floor_prunes_what_cannot_beat_it_and_keeps_what_can(seed: int) -> None:
    """With ``floor`` below the window's best the answer is unchanged; at or above it the
    search answers ``(floor, center)`` (nothing there beats it): what lets a caller keeping
    the k best of many windows skip the rest of a window that cannot enter them."""
    grid, _, pts, guess = _room(seed)
    best, pose = search(grid, pts, guess, 0.4, 0.12, yaw_step=0.02)
    below, same = search(grid, pts, guess, 0.4, 0.12, yaw_step=0.02, floor=best - 0.05)
    assert below == pytest.approx(best, abs=1e-9)
    np.testing.assert_allclose(same, pose)
    above, center = search(grid, pts, guess, 0.4, 0.12, yaw_step=0.02, floor=best + 1e-3)
    assert above == pytest.approx(best + 1e-3, abs=1e-9)
    np.testing.assert_allclose(center, guess)


@pytest.mark.parametrize(("resolution", "sigma"), [(0.05, 0.05), (0.15, 0.15), (0.1, 0.2)])
@pytest.mark.parametrize("stamp_cost", [1e9, 0.0])  # every grid stamped / transformed
def test_the_grid_scores_the_distance_to_the_nearest_point_either_way(
    monkeypatch: pytest.MonkeyPatch, resolution: float, sigma: float, stamp_cost: float
) -> None:
    """Stamped point by point or through the distance transform, every cell scores
    ``exp(-d² / 2σ²)`` (float32) of its distance to the nearest cell holding a point, bit for
    bit as scoring the transform's distances directly (far cells 0 where float32 is)."""
    from scipy.ndimage import distance_transform_edt

    from laser_corners.registration import correlative

    monkeypatch.setattr(correlative, "STAMP_COST", stamp_cost)
    rng = np.random.default_rng(int(resolution * 1000 + sigma * 100))
    for n in (1, 7, 300):
        xy = np.concatenate([rng.uniform(-3, 9, (n, 2)), rng.normal(4, 0.3, (n, 2))])
        grid = ScoreGrid.build(xy, resolution, sigma, 1.5)
        cells = np.floor((xy - grid.origin) / resolution).astype(int)
        empty = np.ones(grid.score.shape, dtype=bool)
        empty[cells[:, 1], cells[:, 0]] = False
        distance = distance_transform_edt(empty) * resolution
        want = np.exp(-0.5 * (distance / sigma) ** 2).astype(np.float32)
        np.testing.assert_array_equal(grid.score, want)
        assert grid.score.dtype == np.float32 and (grid.score == 0).any()
