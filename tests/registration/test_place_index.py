"""The place index: corner keypoints of keyframes propose where a query could be."""

from __future__ import annotations

import math

import numpy as np
import pytest

from laser_corners.pose import between_many, compose_many
from laser_corners.registration.corner_grid import VIEWS_PER_CORNER, CornerGrid
from laser_corners.registration.corners import (
    Corners,
    QueryBuffer,
    corner_detector,
    nearest_corners,
    scan_corners,
)
from laser_corners.registration.correlative import ScoreGrid, search
from laser_corners.registration.place_index import (
    Candidate,
    PlaceIndex,
    PlaceOptions,
    build_index,
    dense_check,
    index_arrays,
    index_from_arrays,
)
from laser_corners.registration.points import scan_points, transform
from laser_corners.sim import UST_10LX, World

MOUNT = np.array([0.1, 0.0, 0.0])


def building() -> World:
    """Rooms with corners of several openings: no symmetry."""
    world = World().add_polygon([[0, 0], [14, 0], [14, 9], [0, 9]])
    world.add_polygon([[6, 0], [6.2, 0], [6.2, 3.5], [6, 3.5]])
    world.add_polygon([[6, 5.5], [6.2, 5.5], [6.2, 9], [6, 9]])
    world.add_polygon([[2.5, 2.5], [3.5, 2.5], [3.5, 3.1], [2.5, 3.1]])
    world.add_polygon([[9, 5.5], [10.2, 5.5], [9.5, 6.8]])
    world.add_polygon([[11, 1.5], [12.5, 1.5], [12.5, 2.0], [11, 2.0]])
    return world


def keyframe_poses() -> np.ndarray:
    """A lap of both rooms, a pose every 0.5 m, heading along the path."""
    corners = np.array([[1.5, 1.5], [12.5, 4.0], [12.5, 7.5], [1.5, 7.5]])
    poses = []
    for a, b in zip(corners, np.roll(corners, -1, axis=0), strict=True):
        heading = math.atan2(b[1] - a[1], b[0] - a[0])
        n = int(np.hypot(*(b - a)) / 0.5)
        poses += [(*(a + t * (b - a)), heading) for t in np.arange(n) / n]
    return np.array(poses)


def scan_at(world: World, base: np.ndarray, seed: int):
    laser = compose_many(base, MOUNT)
    return world.scan(tuple(laser), UST_10LX, noise_sigma=0.005, rng=np.random.default_rng(seed))


@pytest.fixture(scope="module")
def mapped():
    world = building()
    poses = keyframe_poses()
    scans = [scan_at(world, p, i) for i, p in enumerate(poses)]
    return world, poses, build_index(scans, MOUNT, PlaceOptions())


def _error(pose: np.ndarray, truth: np.ndarray) -> tuple[float, float]:
    d = between_many(truth, pose)
    return math.hypot(d[0], d[1]), abs(d[2])


def test_index_holds_every_keyframes_corners_in_its_base_frame(mapped) -> None:
    _, poses, index = mapped
    assert len(index) > 2 * len(poses) // 3  # corners in most keyframes
    corners = index.map_corners(poses)
    # the room's true corner (6, 3.5) (end of the partition) is among the mapped corners
    near = np.hypot(*(corners.xy - [6.0, 3.5]).T)
    assert near.min() < 0.1


@pytest.mark.parametrize("truth", [(4.0, 4.5, 0.3), (10.0, 3.0, 2.5), (8.0, 7.0, -2.0)])
def test_one_scan_is_placed_at_its_true_pose(mapped, truth) -> None:
    world, poses, index = mapped
    truth = np.array(truth)
    scan = scan_at(world, truth, 99)
    buffer = QueryBuffer(3.0)
    buffer.add(np.array([20.0, -7.0, 1.0]), _corners_of(scan, index))  # any odometry frame
    found = index.candidates(buffer.query(), poses)
    assert found, "no candidate"
    grid = ScoreGrid.build(_map_points(world, poses), 0.05, 0.1, 1.0)
    points = scan_points(scan, MOUNT, 0.1, 30.0, 0.1).xy
    best = dense_check(found, grid, points, PlaceOptions())[0]
    xy, yaw = _error(best.pose, truth)
    assert xy < 0.1 and yaw < math.radians(2.0)
    assert best.votes >= 2


def test_a_query_chained_by_odometry_is_in_the_newest_frame(mapped) -> None:
    world, poses, index = mapped
    truth = np.array([[3.0 + 0.1 * k, 5.0, 0.0] for k in range(15)])
    odometry = compose_many(np.array([-4.0, 2.0, 0.7]), truth)  # odometry's own frame
    buffer = QueryBuffer(3.0)
    for k, pose in enumerate(truth):
        buffer.add(odometry[k], _corners_of(scan_at(world, pose, k), index))
    query = buffer.query()
    # moved into the map by the newest true pose, every query corner lies on a map corner
    world_xy = transform(query.xy, truth[-1])
    mapped_xy = index.map_corners(poses).xy
    gap = np.array([np.hypot(*(mapped_xy - p).T).min() for p in world_xy])
    assert len(query) >= 3 and np.median(gap) < 0.05
    found = index.candidates(query, poses)
    assert any(_error(c.pose, truth[-1])[0] < 0.15 for c in found)


def test_keyframes_at_or_after_upto_are_left_out(mapped) -> None:
    world, poses, index = mapped
    half = len(poses) // 2
    truth = poses[-3]  # seen only by the last keyframes... and by the first ones' rooms
    query = _corners_of(scan_at(world, truth, 5), index)
    early = index.map_corners(poses, upto=half)
    assert len(early) < len(index)
    for c in index.candidates(query, poses, upto=half):
        assert np.isfinite(c.pose).all()


def test_no_corner_no_candidate(mapped) -> None:
    _, poses, index = mapped
    assert index.candidates(Corners.empty(61), poses) == []
    assert PlaceIndex().candidates(Corners.empty(61), poses) == []


def test_index_round_trips_through_arrays(mapped) -> None:
    _, poses, index = mapped
    arrays = index_arrays(index)
    again = index_from_arrays(arrays, PlaceOptions())
    assert again is not None and len(again) == len(index)
    np.testing.assert_array_equal(again.map_corners(poses).xy, index.map_corners(poses).xy)
    arrays["places_version"] = np.int64(99)
    assert index_from_arrays(arrays, PlaceOptions()) is None
    assert index_from_arrays({}, PlaceOptions()) is None


def test_keyframe_corners_form_a_query_in_a_keyframes_frame(mapped) -> None:
    _, poses, index = mapped
    own = np.array([10, 11, 12])
    query = index.keyframe_corners(own, poses, poses[12])
    found = index.candidates(query, poses, upto=None)
    assert found and _error(found[0].pose, poses[12])[0] < 0.05


def _corners_of(scan, index: PlaceIndex) -> Corners:
    return scan_corners(scan, corner_detector(index.options.detector_preset, scan), MOUNT)


def _map_points(world: World, poses: np.ndarray) -> np.ndarray:
    parts = []
    for i, p in enumerate(poses):
        parts.append(transform(scan_points(scan_at(world, p, i), MOUNT, 0.1, 30.0, 0.05).xy, p))
    return np.concatenate(parts)


def test_every_physical_corner_keeps_a_few_views(mapped) -> None:
    _, poses, index = mapped
    opt = index.options
    grid = CornerGrid.build(index.map_corners(poses), opt.consensus_radius, opt.consensus_yaw)
    seen = grid.landmark[grid.views]
    assert set(seen.tolist()) == set(grid.landmark.tolist())  # every corner compared
    assert np.bincount(seen).max() <= VIEWS_PER_CORNER < np.bincount(grid.landmark).max()


def test_damaged_index_arrays_are_refused(mapped) -> None:
    index = mapped[2]
    arrays = index_arrays(index)
    short = dict(arrays, places_opening=arrays["places_opening"][:-1])
    with pytest.raises(ValueError, match="inconsistent"):
        index_from_arrays(short, PlaceOptions())
    with pytest.raises(ValueError, match="inconsistent"):
        index_from_arrays(arrays, PlaceOptions(), n_keyframes=3)  # keyframes beyond the map's


def test_a_corner_rich_query_is_capped_and_still_placed(mapped) -> None:
    """A query of many corners (a long stretch of keyframes) costs at most ``max_query``
    corners and ``max_query * matches`` proposed poses, whatever the map; the nearest
    corners still place it."""
    _, poses, index = mapped
    opt = PlaceOptions(max_query=4)
    capped = index_from_arrays(index_arrays(index), opt)
    assert capped is not None
    frame = poses[30]
    query = capped.keyframe_corners(np.arange(18, 31), poses, frame)
    assert len(query) > 5 * opt.max_query  # well over the cap
    found = capped.candidates(query, poses)
    work = capped.work
    assert 0 < work.corners <= opt.max_query
    assert work.proposals <= opt.max_query * opt.matches
    assert work.checked == len(found) <= opt.checked
    assert found and _error(found[0].pose, frame)[0] < 0.15  # before the dense check
    # without the cap the same query uses more corners: the cap is what bounds it
    free = index_from_arrays(index_arrays(index), PlaceOptions(max_query=1000))
    assert free is not None
    free.candidates(query, poses)
    assert free.work.corners > opt.max_query


def test_query_keeps_the_corners_nearest_the_robot(mapped) -> None:
    _, poses, index = mapped
    frame = poses[30]
    query = index.keyframe_corners(np.arange(18, 31), poses, frame)
    opt = PlaceOptions(max_query=5)
    kept = nearest_corners(query, opt.max_query)
    assert len(kept) == 5
    far = np.sort(np.hypot(*query.xy.T))
    np.testing.assert_allclose(np.sort(np.hypot(*kept.xy.T)), far[:5])
    assert nearest_corners(query, len(query) + 1) is query


def test_dense_check_keeps_the_best_scores_of_checking_every_candidate(mapped) -> None:
    """The dense check skips what cannot enter the ``candidates`` best (a floor on each
    search): the same poses and scores as searching around every candidate in full."""
    world, poses, index = mapped
    truth = np.array([8.0, 7.0, -2.0])
    scan = scan_at(world, truth, 7)
    found = index.candidates(_corners_of(scan, index), poses)
    rng = np.random.default_rng(3)
    found += [
        Candidate(np.array([rng.uniform(1, 13), rng.uniform(1, 8), rng.uniform(-3, 3)]), 1)
        for _ in range(40)
    ]
    grid = ScoreGrid.build(_map_points(world, poses), 0.05, 0.1, 1.0)
    points = scan_points(scan, MOUNT, 0.1, 30.0, 0.2).xy
    opt = PlaceOptions(candidates=5)
    full = [search(grid, points, c.pose, opt.check_xy, opt.check_yaw) for c in found]
    want = sorted(full, key=lambda sp: -sp[0])[: opt.candidates]
    got = dense_check(found, grid, points, opt)
    assert [c.score for c in got] == pytest.approx([sp[0] for sp in want], abs=1e-9)
    np.testing.assert_allclose([c.pose for c in got], [sp[1] for sp in want])
    assert _error(got[0].pose, truth)[0] < 0.1


def _answer(found: list[Candidate]) -> list[tuple]:
    return [(tuple(np.round(c.pose, 9)), c.votes) for c in found]


def test_options_replaced_after_a_query_are_used_by_the_next(mapped) -> None:
    """The localiser's proposer replaces the index's options (``PlaceProposer``): the next
    query must use the new consensus radius and yaw, not a grid cached with the old ones."""
    _, poses, index = mapped
    query = index.keyframe_corners(np.arange(18, 31), poses, poses[30])
    old, new = PlaceOptions(), PlaceOptions(consensus_radius=1.5, consensus_yaw=1.0)
    reused = index_from_arrays(index_arrays(index), old)
    assert reused is not None
    before = _answer(reused.candidates(query, poses))
    reused.options = new
    fresh = index_from_arrays(index_arrays(index), new)
    assert fresh is not None
    expected = _answer(fresh.candidates(query, poses))
    assert expected != before  # the options change the answer here
    assert _answer(reused.candidates(query, poses)) == expected
