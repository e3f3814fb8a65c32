"""Global relocalisation: a robot carried to another place of the map (a kidnap) is found
again, and the trajectory after the kidnap is right."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

pytest.importorskip("gtsam")


from laser_corners.pose import compose_many, invert, poses_apart
from laser_corners.registration.global_search import SlicedSearch
from laser_corners.registration.place_index import PlaceOptions
from laser_corners.registration.points import ScanPoints
from laser_corners.slam import Slam, SlamOptions, relocalise
from laser_corners.slam.relocalise import (
    CANDIDATES,
    CENTER_WINDOW,
    DISTINCT_XY,
    DISTINCT_YAW,
    OldMap,
    free_space_conflict,
    occupancy_keys,
)
from sim_drives import drive_slam, noisy_odometry, straight, two_rooms

RATE = 10.0


def _leg(a, b, turn_to: float | None = None) -> list[tuple[float, float, float]]:
    """:func:`straight` from ``a`` to ``b``, then a turn in place to ``turn_to``."""
    out = straight(a, b)
    heading = math.atan2(b[1] - a[1], b[0] - a[0])
    if turn_to is not None:
        steps = int(abs(turn_to - heading) / 0.15)
        out += [
            (b[0], b[1], heading + k * (turn_to - heading) / steps) for k in range(1, steps + 1)
        ]
    return out


def _kidnap_drive() -> tuple[np.ndarray, int]:
    """A lap of both rooms, the start of a second lap, then the robot is carried from the
    middle of the first leg (6 m along y = 1.5, heading east) to (10.5, 6.5) heading west and
    drives the last two legs: the true poses and the index of the first scan after it."""
    c = [(1.5, 1.5), (10.5, 1.5), (10.5, 6.5), (1.5, 6.5)]
    path = _leg(c[0], c[1], math.pi / 2) + _leg(c[1], c[2], math.pi)
    path += _leg(c[2], c[3], 1.5 * math.pi) + _leg(c[3], c[0], 2 * math.pi)
    path += [(x, y, 0.0) for x, y, _ in _leg(c[0], (4.5, 1.5))]
    kidnap = len(path)
    path += _leg(c[2], c[3], 1.5 * math.pi) + _leg(c[3], (1.5, 3.0))
    return np.array(path), kidnap


def _run(options: SlamOptions, gap: float):
    truth, kidnap = _kidnap_drive()
    odo = noisy_odometry(
        truth, np.random.default_rng(1), (1.02, 1.01, 0.001), (0.002,) * 3, still=(kidnap,)
    )
    index = np.arange(len(truth))
    stamps = index / RATE + np.where(index >= kidnap, gap, 0.0)
    slam = Slam(options)
    drive_slam(slam, two_rooms(), truth, odo, stamps, np.random.default_rng(2))
    return truth, kidnap, slam.result()


@pytest.mark.parametrize("gap", [0.0, 30.0], ids=["carried", "carried-30s-gap"])
def test_kidnapped_robot_is_relocalised(gap: float) -> None:
    truth, kidnap, result = _run(SlamOptions(), gap)
    err = np.hypot(*(result.poses[:, :2] - truth[:, :2]).T)
    after = err[kidnap:]
    # before the kidnap: the map is right; after it: found again and right
    assert np.median(err[:kidnap]) < 0.05
    assert np.median(after) < 0.1 and np.percentile(after[len(after) // 3 :], 95) < 0.1
    assert result.counts["lost"] + result.counts["time_jumps"] >= 1
    # the graph was cut at the kidnap (SlamResult.cuts: where a new segment starts)
    assert len(result.cuts) >= 1 and kidnap <= result.cuts[0] <= kidnap + 10, result.cuts
    assert result.counts["relocalisations_accepted"] >= 1
    assert result.counts["relocalisations_attempted"] >= result.counts["relocalisations_accepted"]


def test_the_exhaustive_search_alone_relocalises_the_kidnapped_robot() -> None:
    options = SlamOptions(places=PlaceOptions(enabled=False))
    truth, kidnap, result = _run(options, 0.0)
    after = np.hypot(*(result.poses[kidnap:, :2] - truth[kidnap:, :2]).T)
    assert np.median(after) < 0.1
    assert result.counts["relocalisations_exhaustive"] >= 1
    assert result.counts["relocalisations_accepted"] >= 1


def _l_room() -> np.ndarray:
    """Walls of an L-shaped room (map frame) every 5 cm."""
    corners = [(0, 0), (10, 0), (10, 4), (4, 4), (4, 9), (0, 9), (0, 0)]
    walls = []
    for (x0, y0), (x1, y1) in itertools.pairwise(corners):
        n = int(math.hypot(x1 - x0, y1 - y0) / 0.05)
        walls.append(np.column_stack([np.linspace(x0, x1, n), np.linspace(y0, y1, n)]))
    return np.concatenate([*walls, np.array([[6.0, 2.0], [6.05, 2.0], [2.0, 6.5]])])


def _seen(world: np.ndarray, pose: np.ndarray) -> ScanPoints:
    """The points of ``world`` in the frame of ``pose``."""
    xy = compose_many(invert(pose), np.column_stack([world, np.zeros(len(world))]))[:, :2]
    return ScanPoints(xy, np.zeros_like(xy), np.zeros(len(xy), bool))


def test_the_old_maps_search_finds_the_pose_among_distinct_candidates() -> None:
    world = _l_room()
    estimate = np.array([[1.0, 1.0, 0.0], [3.0, 1.5, 0.5], [7.0, 2.0, 1.0], [2.0, 6.0, -1.0]])
    old = OldMap.build([_seen(world, p) for p in estimate], estimate, len(estimate))
    truth = np.array([7.3, 2.4, 2.0])  # near the third keyframe, turned
    query = _seen(world, truth).xy[::3]
    found = old.search(query)
    assert len(found) == CANDIDATES
    assert [s for s, _ in found] == sorted((s for s, _ in found), reverse=True)
    pose = found[0][1]
    assert math.hypot(*(pose[:2] - truth[:2])) < 0.2 and abs(pose[2] - truth[2]) < 0.05
    for a, (_, p) in enumerate(found):
        assert all(poses_apart(p, q, DISTINCT_XY, DISTINCT_YAW) for _, q in found[:a])
        near = np.abs(old.centres - p[:2]).max(axis=1).min()
        assert near <= CENTER_WINDOW + old.grid.resolution  # in a centre's window


def test_without_relocalisation_the_kidnap_stays_wrong() -> None:
    truth, kidnap, result = _run(SlamOptions(relocalisation=False), 0.0)
    after = np.hypot(*(result.poses[kidnap:, :2] - truth[kidnap:, :2]).T)
    assert np.median(after) > 1.0  # the test above measures something
    assert result.counts["relocalisations_attempted"] == 0


def test_free_space_conflict_counts_beams_through_walls() -> None:
    wall = occupancy_keys(np.column_stack([np.full(200, 2.01), np.linspace(-5, 5, 200)]))
    origin = np.zeros(2)
    through = np.array([[3.0, 0.0], [3.0, 1.0]])  # beyond the wall
    before = np.array([[1.5, 0.0], [1.5, 1.0]])
    at = np.array([[2.02, 0.0], [2.02, 0.5]])  # ending on it
    assert free_space_conflict(wall, origin, through) == 1.0
    assert free_space_conflict(wall, origin, before) == 0.0
    assert free_space_conflict(wall, origin, at) == 0.0


def test_the_old_map_of_a_prior_map_takes_its_occupancy_from_the_grid() -> None:
    # keyframe 0 (a prior map's) saw a person at (2, 0) whom its grid cleared later; a
    # beam of a later visit through there is no conflict. Keyframe 1 is the new session's.
    wall = np.column_stack([np.full(41, 4.0), np.linspace(-1.0, 1.0, 41)])
    person = np.array([[2.0, 0.0], [2.02, 0.03]])
    first = ScanPoints(np.vstack([wall, person]), np.zeros((43, 2)), np.zeros(43, bool))
    second = ScanPoints(np.array([[1.0, 3.0]]), np.zeros((1, 2)), np.zeros(1, bool))
    estimate = np.zeros((2, 3))
    grid = occupancy_keys(wall)  # the grid's occupied cells: the wall only
    plain = OldMap.build([first, second], estimate, 2)
    old = OldMap.build([first, second], estimate, 2, prior=(1, grid))
    for keys, person_there in ((plain.occupied, True), (old.occupied, False)):
        assert np.isin(occupancy_keys(person), keys).all() == person_there
        assert np.isin(occupancy_keys(wall), keys).all()
        assert np.isin(occupancy_keys(second.xy), keys).all()
    beam = np.array([[3.9, 0.0]])  # from the origin through the person to the wall
    assert free_space_conflict(plain.occupied, np.zeros(3), beam) == 1.0
    assert free_space_conflict(old.occupied, np.zeros(3), beam) == 0.0


def test_the_exhaustive_search_runs_in_slices_and_still_relocalises(monkeypatch) -> None:
    # a few hundred nodes a scan: each search spans many scans, no scan spends more, and its
    # answers carried to the keyframe it ends on by the segment's estimate are right
    spent: list[int] = []
    advance = SlicedSearch.advance

    def counted(self, budget: int) -> int:
        spent.append(advance(self, budget))
        return spent[-1]

    monkeypatch.setattr(SlicedSearch, "advance", counted)
    monkeypatch.setattr(relocalise, "SLICE_NODES", 300)
    options = SlamOptions(places=PlaceOptions(enabled=False))
    truth, kidnap, result = _run(options, 0.0)
    after = np.hypot(*(result.poses[kidnap:, :2] - truth[kidnap:, :2]).T)
    assert np.median(after) < 0.1
    assert result.counts["relocalisations_accepted"] >= 1
    assert max(spent) <= 300
    assert len(spent) >= 3 * result.counts["relocalisations_exhaustive"] >= 3
