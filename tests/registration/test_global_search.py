"""The whole-map search: its branch and bound returns the best distinct poses that scoring
every pose of the lattice returns."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from laser_corners.pose import compose_many, poses_apart, wrap_angle
from laser_corners.registration.correlative import ScoreGrid
from laser_corners.registration.global_search import (
    QUANT,
    Lattice,
    Pyramid,
    SlicedSearch,
    best_poses,
    carried,
)


def _exhaustive(grid: ScoreGrid, lattice: Lattice, pts, yaws):
    """Every (position, heading) of the lattice scored with numpy: poses (K, 3), mean scores."""
    res, (ny, nx), m = grid.resolution, grid.score.shape, lattice.cells
    i, j = np.nonzero(lattice.allowed)
    shift = lattice.origin - grid.origin
    poses, scores = [], []
    for yaw in yaws:
        c, s = math.cos(yaw), math.sin(yaw)
        cx = np.floor((c * pts[:, 0] - s * pts[:, 1] + shift[0]) / res).astype(int)
        cy = np.floor((s * pts[:, 0] + c * pts[:, 1] + shift[1]) / res).astype(int)
        iy, ix = cy[None, :] + m * i[:, None], cx[None, :] + m * j[:, None]
        inside = (iy >= 0) & (iy < ny) & (ix >= 0) & (ix < nx)
        values = np.where(inside, grid.score[np.clip(iy, 0, ny - 1), np.clip(ix, 0, nx - 1)], 0)
        scores.append(values.astype(np.float64).sum(axis=1) / len(pts))
        xy = lattice.positions(res)
        poses.append(np.column_stack([xy, np.full(len(xy), yaw)]))
    return np.concatenate(poses), np.concatenate(scores)


def _apart(poses: np.ndarray, p: np.ndarray, apart: tuple[float, float]) -> np.ndarray:
    """:func:`poses_apart` of each of ``poses`` from ``p``."""
    dyaw = np.abs((poses[:, 2] - p[2] + math.pi) % (2 * math.pi) - math.pi)
    return (np.hypot(*(poses[:, :2] - p[:2]).T) >= apart[0]) | (dyaw >= apart[1])


def _assert_greedy(found, poses, scores, count, apart) -> None:
    """``found`` is what :func:`~laser_corners.pose.distinct_poses` gives on the exhaustive
    scores sorted (taking the best pose apart from those taken before, ``count`` times; ties
    taken either way): each answer a lattice pose with
    its exhaustive score, the best of those apart from the answers before it; fewer than
    ``count`` only when no pose that scores is left."""
    left = scores > 0
    for p, score in found:
        same = np.flatnonzero(np.all(np.abs(poses - p) < 1e-9, axis=1))
        assert len(same) == 1 and left[same[0]]
        assert math.isclose(scores[same[0]], score, rel_tol=1e-9)
        assert math.isclose(scores[left].max(), score, rel_tol=1e-9)
        left &= _apart(poses, p, apart)
    assert len(found) == count or not left.any()


def _room(rng: np.random.Generator, size: float) -> np.ndarray:
    """Walls of a ``size`` square room, a wall inside and clutter."""
    t = np.linspace(0, size, int(size * 20))
    walls = [np.column_stack([t, np.full_like(t, y)]) for y in (0.0, size)]
    walls += [np.column_stack([np.full_like(t, x), t]) for x in (0.0, size)]
    inner = rng.uniform(0.2, 0.8) * size
    walls.append(np.column_stack([np.full_like(t[: len(t) // 2], inner), t[: len(t) // 2]]))
    walls.append(rng.uniform(0.5, size - 0.5, (30, 2)))
    return np.concatenate(walls)


def _scan(rng: np.random.Generator, xy: np.ndarray, truth: np.ndarray, n: int) -> np.ndarray:
    """``n`` map points seen from ``truth`` (base frame), with noise."""
    c, s = math.cos(truth[2]), math.sin(truth[2])
    pts = (xy[rng.choice(len(xy), n, replace=False)] - truth[:2]) @ np.array([[c, -s], [s, c]])
    return pts + rng.normal(0, 0.02, pts.shape)


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    seed=st.integers(0, 2**31 - 1),
    cells=st.integers(1, 3),
    count=st.integers(1, 6),
    resolution=st.sampled_from([0.1, 0.15]),
    share=st.floats(0.05, 1.0),
)
def test_branch_and_bound_returns_the_exhaustive_best_distinct_poses(
    seed: int, cells: int, count: int, resolution: float, share: float
) -> None:
    rng = np.random.default_rng(seed)
    xy = _room(rng, rng.uniform(4.0, 9.0))
    grid = ScoreGrid.build(xy, resolution, 0.2, 1.0)
    pyramid = Pyramid.build(grid, int(rng.integers(1, 4)), levels=int(rng.integers(1, 6)))
    step = cells * resolution
    origin = grid.origin + rng.uniform(-0.3, 0.3, 2)
    shape = (np.array(grid.score.shape) * resolution / step).astype(int) + 1
    allowed = rng.uniform(size=shape) < share
    lattice = Lattice(origin, cells, allowed)
    truth = np.array([*rng.uniform(1.0, xy.max() - 1.0, 2), rng.uniform(-3, 3)])
    pts = _scan(rng, xy, truth, int(rng.integers(5, 60)))
    yaws = np.sort(rng.uniform(-math.pi, math.pi, int(rng.integers(1, 12))))
    apart = (float(rng.uniform(0.3, 1.5)), float(rng.uniform(0.1, 0.5)))
    found = best_poses(pyramid, lattice, pts, yaws, count, apart)
    poses, scores = _exhaustive(grid, lattice, pts, yaws)
    _assert_greedy(found, poses, scores, count, apart)


def test_the_k_best_are_distinct_and_the_true_pose_is_first() -> None:
    rng = np.random.default_rng(3)
    xy = _room(rng, 12.0)
    grid = ScoreGrid.build(xy, 0.1, 0.2, 1.0)
    truth = np.array([4.0, 7.0, 1.0])
    pts = _scan(rng, xy, truth, 100)
    shape = np.array(grid.score.shape) // 2 + 1
    lattice = Lattice(grid.origin.copy(), 2, np.ones(shape, dtype=bool))
    lattice.origin += (truth[:2] - lattice.origin) % 0.2  # the truth is on the lattice
    yaws = 1.0 + 0.035 * np.arange(-90, 90)
    found = best_poses(Pyramid.build(grid), lattice, pts, yaws, 8, (1.0, 0.3))
    assert len(found) == 8
    assert np.hypot(*(found[0][0][:2] - truth[:2])) < 0.15 and abs(found[0][0][2] - 1.0) < 0.04
    assert [s for _, s in found] == sorted((s for _, s in found), reverse=True)
    for a, (p, _) in enumerate(found):
        assert all(poses_apart(p, q, 1.0, 0.3) for q, _ in found[:a])


def test_an_empty_scan_lattice_or_a_scan_off_the_map_gives_no_pose() -> None:
    rng = np.random.default_rng(5)
    xy = _room(rng, 6.0)
    grid = ScoreGrid.build(xy, 0.1, 0.2, 1.0)
    pyramid = Pyramid.build(grid)
    lattice = Lattice(grid.origin.copy(), 1, np.ones(grid.score.shape, dtype=bool))
    yaws = np.linspace(-3, 3, 7)
    assert best_poses(pyramid, lattice, np.zeros((0, 2)), yaws, 3, (1.0, 0.3)) == []
    empty = Lattice(grid.origin.copy(), 1, np.zeros((4, 4), dtype=bool))
    assert best_poses(pyramid, empty, _scan(rng, xy, np.zeros(3), 20), yaws, 3, (1, 0.3)) == []
    far = np.full((20, 2), 500.0) + rng.uniform(0, 1, (20, 2))  # never within the grid
    assert best_poses(pyramid, lattice, far, yaws, 3, (1.0, 0.3)) == []


def test_the_pooled_levels_hold_the_window_maxima() -> None:
    rng = np.random.default_rng(1)
    grid = ScoreGrid.build(rng.uniform(0, 3, (40, 2)), 0.1, 0.2, 0.5)
    pyramid = Pyramid.build(grid, 3, levels=4)
    ny, nx = grid.score.shape
    for e in range(4):
        w = (2**e - 1) * 3 + 1
        rows, cols = pyramid.shapes[e]
        level = pyramid.data[pyramid.offsets[e] : pyramid.offsets[e] + rows * cols]
        level = level.reshape(rows, cols)
        assert (rows, cols) == (ny + w - 1, nx + w - 1)
        for r, c in rng.integers(0, [rows, cols], (50, 2)):
            window = grid.score[max(r - w + 1, 0) : r + 1, max(c - w + 1, 0) : c + 1]
            top = float(window.max()) if window.size else 0.0
            assert top <= level[r, c] / QUANT < top + 1.0 / QUANT  # rounded up
    assert pyramid.nbytes == pyramid.data.nbytes


@settings(max_examples=30, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    seed=st.integers(0, 2**31 - 1),
    cells=st.integers(1, 3),
    count=st.integers(1, 6),
    budget=st.integers(1, 40),
)
def test_the_sliced_search_returns_exactly_the_one_shot_answers(
    seed: int, cells: int, count: int, budget: int
) -> None:
    rng = np.random.default_rng(seed)
    xy = _room(rng, rng.uniform(4.0, 9.0))
    grid = ScoreGrid.build(xy, 0.1, 0.2, 1.0)
    pyramid = Pyramid.build(grid, cells, levels=int(rng.integers(1, 6)))
    shape = (np.array(grid.score.shape) / cells).astype(int) + 1
    lattice = Lattice(grid.origin + rng.uniform(-0.3, 0.3, 2), cells, rng.uniform(size=shape) < 0.6)
    truth = np.array([*rng.uniform(1.0, xy.max() - 1.0, 2), rng.uniform(-3, 3)])
    pts = _scan(rng, xy, truth, int(rng.integers(5, 60)))
    yaws = np.sort(rng.uniform(-math.pi, math.pi, int(rng.integers(1, 12))))
    one_shot = best_poses(pyramid, lattice, pts, yaws, count, (0.8, 0.3))
    sliced = SlicedSearch(pyramid, lattice, pts, yaws, count, (0.8, 0.3))
    calls = 0
    while not sliced.done:
        spent = sliced.advance(budget)
        assert 1 <= spent <= budget
        calls += 1
    assert sliced.nodes <= calls * budget
    found = sliced.result()
    assert len(found) == len(one_shot)
    for (p, s), (q, r) in zip(found, one_shot, strict=True):
        assert np.array_equal(p, q) and s == r


def test_a_budget_of_one_node_finishes_in_a_bounded_number_of_calls() -> None:
    rng = np.random.default_rng(7)
    xy = _room(rng, 6.0)
    grid = ScoreGrid.build(xy, 0.1, 0.2, 1.0)
    lattice = Lattice(grid.origin.copy(), 2, np.ones(np.array(grid.score.shape) // 2, bool))
    yaws = np.linspace(-3, 3, 9)
    sliced = SlicedSearch(
        Pyramid.build(grid, 2), lattice, _scan(rng, xy, np.ones(3), 40), yaws, 4, (1.0, 0.3)
    )
    allowed, _, _ = lattice.blocks
    most = len(yaws) * int(allowed.sum())  # every node of every heading once
    calls = 0
    while not sliced.done and calls <= most:
        assert sliced.advance(1) == 1
        calls += 1
    assert sliced.done and calls <= most
    assert sliced.advance(5) == 0  # nothing left to do
    assert len(sliced.result()) == 4


def test_a_search_with_nothing_to_search_is_done_at_once() -> None:
    rng = np.random.default_rng(5)
    grid = ScoreGrid.build(_room(rng, 6.0), 0.1, 0.2, 1.0)
    lattice = Lattice(grid.origin.copy(), 1, np.zeros((4, 4), dtype=bool))
    sliced = SlicedSearch(Pyramid.build(grid), lattice, np.ones((5, 2)), np.zeros(3), 3, (1, 0.3))
    assert sliced.done and sliced.result() == [] and sliced.advance(10) == 0


def test_answers_are_carried_to_the_current_scan_by_the_odometry_since() -> None:
    rng = np.random.default_rng(11)
    then = np.array([3.0, -2.0, 2.5])  # the robot in the map at the scan searched
    motion = np.array([[0.0, 0.0, 0.0], [1.2, 0.3, 0.4], [-0.5, 2.0, -2.9]])
    now = compose_many(then, motion)  # where it is later
    frame = np.array([*rng.uniform(-50, 50, 2), rng.uniform(-3, 3)])  # the odometry's frame
    odo_then, odo_now = compose_many(frame, then), compose_many(frame, now)
    for k in range(len(motion)):
        [p] = carried([then], odo_then, odo_now[k])
        assert np.allclose(p[:2], now[k, :2]) and abs(wrap_angle(p[2] - now[k, 2])) < 1e-12
    two = carried([then, np.zeros(3)], odo_then, odo_now[1])
    assert np.allclose(two[1], motion[1])  # an answer at the map's origin moves by the motion
