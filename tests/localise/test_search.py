"""The global search (``localise.search``): a winner only after ``fix_travel``; a restart
inside a lost track's window keeps its first hypothesis; a jump clears the hypotheses; a robot
starting at the map's frontier is not fixed at a look-alike inside the map."""

from __future__ import annotations

import numpy as np
import pytest
from test_localiser import building, loaded_building, map_folder, noisy_odometry, scans_along
from test_unmapped import scans_along as wide_scans_along

from laser_corners.localise import LocaliseOptions, estimate
from laser_corners.localise.local import LocalMap
from laser_corners.localise.mapmodel import GLOBAL_SIGMA, MapModel
from laser_corners.localise.matcher import MapMatcher
from laser_corners.localise.places import PlaceProposer
from laser_corners.localise.search import GlobalSearch
from laser_corners.localise.window import Window
from laser_corners.pose import between_many
from laser_corners.registration.mapfolder import load_map
from laser_corners.registration.points import scan_points
from laser_corners.sim import World


@pytest.fixture(scope="module")
def building_world(tmp_path_factory):
    return loaded_building(tmp_path_factory)


def _search(saved, options) -> GlobalSearch:
    model = MapModel(saved, options)
    matcher = MapMatcher(model, options, np.zeros(3))
    places = PlaceProposer(saved.places, saved.poses, model.grid, np.zeros(3), options.places)
    keys = ("searches", "search_slices", "place_attempts", "credited")
    counts = dict.fromkeys((*keys, "refused_free_space", "refused_history"), 0)
    return GlobalSearch(matcher, places, LocalMap(model.grid, GLOBAL_SIGMA), counts)


def _run(search, drive, seed, jump_at=None):
    scans, odo = scans_along(building(), drive, seed), noisy_odometry(drive, seed)
    for i, scan in enumerate(scans):
        pts = scan_points(scan, np.zeros(3), 0.1, 30.0, search.options.point_spacing)
        delta = np.zeros(3) if i == 0 else between_many(odo[i - 1], odo[i])
        winner = search.step(scan, pts, delta, i == jump_at, odo[i], i)
        if winner is not None:
            return i, winner
    return None, None


def test_the_winner_is_right_and_has_survived_fix_travel(building_world) -> None:
    saved, truth = building_world
    options = LocaliseOptions()
    search = _search(saved, options)
    drive = truth[150:450]
    at, winner = _run(search, drive, 8)
    assert winner is not None
    assert np.hypot(*(winner.pose[:2] - drive[at, :2])) < 0.3
    assert winner.travel >= options.fix_travel and winner.followed >= options.fix_followed_travel
    assert search.travel >= options.fix_followed_travel
    search.stop()
    assert search.hypotheses == [] and search.window is None


def test_a_restart_in_a_window_follows_the_lost_pose_and_a_jump_clears_it(building_world) -> None:
    saved, truth = building_world
    options = LocaliseOptions()
    search = _search(saved, options)
    drive = truth[150:160]
    window = Window.from_covariance(drive[0], np.diag([0.05, 0.05, 0.02]) ** 2)
    search.restart(drive[0], 0, window)
    assert len(search.hypotheses) == 1 and search.window is window and search.travel == 0.0
    _run(search, drive[:5], 9)
    assert any(np.hypot(*(h.pose[:2] - drive[4, :2])) < 0.3 for h in search.hypotheses)
    _run(search, drive[5:7], 10, jump_at=0)
    assert search.window is None  # a jump closes the window: the global search takes over


def test_a_sliced_exhaustive_search_carries_its_answers_to_the_scan_it_ends_on(
    building_world,
) -> None:
    # the exhaustive search alone (no place index), a few nodes a scan: a search spans many
    # scans; its answers, judged on the scan it started on, come as hypotheses at the pose
    # the odometry since carries them to, and the fix is as right as with one-shot searches
    saved, truth = building_world
    options = LocaliseOptions().with_overrides(["places.enabled=false"])
    search = _search(saved, options)
    search.slice_nodes = 40
    drive = truth[150:450]
    scans, odo = scans_along(building(), drive, 8), noisy_odometry(drive, 8)
    fresh_errors, winner = [], None
    for i, scan in enumerate(scans):
        pts = scan_points(scan, np.zeros(3), 0.1, 30.0, options.point_spacing)
        delta = np.zeros(3) if i == 0 else between_many(odo[i - 1], odo[i])
        winner = search.step(scan, pts, delta, False, odo[i], i)
        fresh = [h for h in search.hypotheses if h.followed == 0.0 and h.born < i]
        if fresh:  # answers of a search started on scan h.born, new on this scan
            moved = np.hypot(*(drive[i, :2] - drive[fresh[0].born, :2]))
            err = min(np.hypot(*(h.pose[:2] - drive[i, :2])) for h in fresh)
            fresh_errors.append((moved, err))
        if winner is not None:
            break
    assert winner is not None
    assert np.hypot(*(winner.pose[:2] - drive[i, :2])) < 0.3
    assert len(search.search_ms) >= 3 * search.counts["searches"]  # sliced over scans
    # the robot moved during a search, and its right answer came where the robot is now
    assert any(moved > 0.5 and err < 0.2 for moved, err in fresh_errors), fresh_errors


def test_slice_times_keep_the_newest_and_the_counter_counts_every_slice(
    building_world, monkeypatch
) -> None:
    # a localiser running for days keeps the last TIMINGS_KEPT slice times, not one a scan
    # forever; how many slices ran comes from the counter
    monkeypatch.setattr(estimate, "TIMINGS_KEPT", 5)
    saved, truth = building_world
    search = _search(saved, LocaliseOptions().with_overrides(["places.enabled=false"]))
    search.slice_nodes = 40
    drive = truth[150:180]
    scans, odo = scans_along(building(), drive, 8), noisy_odometry(drive, 8)
    kept, checked = [], 0
    for i, scan in enumerate(scans):
        pts = scan_points(scan, np.zeros(3), 0.1, 30.0, search.options.point_spacing)
        delta = np.zeros(3) if i == 0 else between_many(odo[i - 1], odo[i])
        slices = search.counts["search_slices"]
        search.step(scan, pts, delta, False, odo[i], i)
        if search.counts["search_slices"] > slices and len(kept) == 5:
            # one slice more: the oldest time dropped, this slice's appended
            assert list(search.search_ms)[:-1] == kept[1:]
            checked += 1
        kept = list(search.search_ms)
    assert search.counts["search_slices"] > 10 and len(search.search_ms) == 5 and checked > 5


def _no_corner_matches() -> LocaliseOptions:
    # an index that never proposes (no descriptor is that close): where the robot sees too
    # few corners, the exhaustive search must take over after places.fallback_travel
    return LocaliseOptions().with_overrides(["places.max_descriptor_distance=1e-9"])


def test_the_fallback_search_starts_as_soon_as_the_index_has_had_fallback_travel(
    building_world,
) -> None:
    # the scan the fallback becomes due depends on the robot, not on the phase of a scan
    # counter: started at the next multiple of global_every, it came up to global_every - 1
    # scans late (aces, start 4428: 4 scans, 0.6 m, and the fix at 3.2 m of travel)
    saved, truth = building_world
    options = _no_corner_matches()
    search = _search(saved, options)
    drive = truth[150:450]
    scans, odo = scans_along(building(), drive, 8), noisy_odometry(drive, 8)
    due, winner = None, None
    for i, scan in enumerate(scans):
        pts = scan_points(scan, np.zeros(3), 0.1, 30.0, options.point_spacing)
        delta = np.zeros(3) if i == 0 else between_many(odo[i - 1], odo[i])
        winner = search.step(scan, pts, delta, False, odo[i], i)
        if due is None and search.travel >= options.places.fallback_travel:
            due = i
            assert search.running is not None and search.started == i
        if due is None or i < due + options.global_every:
            assert search.counts["searches"] == (due is not None), (i, due)
        if winner is not None:
            break
    assert due is not None and due % options.global_every != 0  # the case the old rule delays
    assert search.counts["place_attempts"] == i + 1  # the index was asked on every scan
    # the fix comes from the search of the scan where the fallback became due, and is right
    assert winner is not None and winner.born == due
    assert np.hypot(*(winner.pose[:2] - drive[i, :2])) < 0.3


def test_the_fallback_search_is_not_started_again_within_global_every_scans(
    building_world,
) -> None:
    # the other side of the rule: one exhaustive search at a time, and a new one only
    # global_every scans after the last one started, however few hypotheses are alive
    saved, truth = building_world
    options = _no_corner_matches()
    search = _search(saved, options)
    search.slice_nodes = 10**9  # each search ends on the scan it starts
    drive = truth[150:450]
    scans, odo = scans_along(building(), drive, 8), noisy_odometry(drive, 8)
    started = []
    for i, scan in enumerate(scans[:40]):
        pts = scan_points(scan, np.zeros(3), 0.1, 30.0, options.point_spacing)
        delta = np.zeros(3) if i == 0 else between_many(odo[i - 1], odo[i])
        before = search.counts["searches"]
        search.hypotheses = []  # nothing alive: the fallback stays needed on every scan
        search.step(scan, pts, delta, False, odo[i], i)
        if search.counts["searches"] > before:
            started.append(i)
    assert len(started) >= 2
    assert np.all(np.diff(started) == options.global_every), started


HALL_LENGTH, HALL_WIDTH, HALL_PERIOD = 60.0, 3.0, 5.0
MAPPED_TO = 14.0
"""The mapping robot drove from here to the hall's closed end (x = 0), its 180° scanner
looking ahead: the map holds little beyond x = 14 m."""


def long_hall() -> World:
    """A 60 x 3 m hall, closed at x = 0, with a box on each wall every 5 m: every stretch of
    it looks like the stretches 5 m away."""
    world = World().add_polygon(
        [[0, 0], [HALL_LENGTH, 0], [HALL_LENGTH, HALL_WIDTH], [0, HALL_WIDTH]]
    )
    for x in np.arange(2.0, HALL_LENGTH - 1.0, HALL_PERIOD):
        world.add_polygon([[x, 0], [x + 0.6, 0], [x + 0.6, 0.4], [x, 0.4]])
        top = HALL_WIDTH - 0.4
        world.add_polygon(
            [[x + 2, top], [x + 2.4, top], [x + 2.4, HALL_WIDTH], [x + 2, HALL_WIDTH]]
        )
    return world


def down_the_hall(x0: float, x1: float, speed: float = 0.5) -> np.ndarray:
    """Poses along the hall's middle from ``x0`` towards ``x1`` at ``speed`` (m/s), 10 Hz."""
    step = speed / 10.0 if x1 > x0 else -speed / 10.0
    x = np.arange(x0, x1, step)
    yaw = 0.0 if x1 > x0 else np.pi
    return np.column_stack([x, np.full_like(x, HALL_WIDTH / 2), np.full_like(x, yaw)])


@pytest.fixture(scope="module")
def hall_mapped_from_one_end(tmp_path_factory):
    folder = tmp_path_factory.mktemp("long_hall")
    return load_map(map_folder(folder, long_hall(), down_the_hall(MAPPED_TO, 1.0)))


def test_a_start_at_the_maps_frontier_is_not_fixed_at_a_look_alike_inside_it(
    hall_mapped_from_one_end,
) -> None:
    # the robot (a 270° scanner) starts near the end of the mapping robot's path: driving on
    # into the unmapped hall, or back towards the map from 1-2 m beyond its end; a third to
    # two thirds of its beams end where the map saw nothing. Scored by its plain share of
    # points near a map point, the right pose lost to a look-alike 5 or 10 m back, fully
    # inside the map: all 4 runs were fixed there (5-10 m off). Judged on the part of its
    # scans the map saw (seen_share), the right pose holds its own: no fix (the robot drives
    # off the map) or the right one. Not solved: from 3-4 m beyond the map's end, driving
    # back (x0 = 17, 17.5, 18), the look-alike 5 m back is fixed after 2 m. Measured: it
    # explains 0.97-1.00 of every scan, fully inside the map, with the right pose's conflict
    # (0.03-0.10: the same far grazing beams on a wall); the closed end at x = 0 stays beyond
    # its 11 m range. The right pose, 0.5-0.7 of its beams outside the map at first, is
    # refused as a hypothesis (max_outside) and is not among the exhaustive search's 16
    # answers before the fix; judged by seen_share it would still trail by 0.07-0.13. No
    # evidence in those 2 m refuses the look-alike but a rival beyond the map's edge
    options = LocaliseOptions().with_overrides(["places.enabled=false"])
    starts = [(12.0, 30.0), (13.0, 30.0), (15.0, 0.5), (16.0, 0.5)]
    outcomes = []
    for x0, x1 in starts:
        search = _search(hall_mapped_from_one_end, options)
        drive = down_the_hall(x0, x1)[:120]
        scans, odo = wide_scans_along(long_hall(), drive, 1), noisy_odometry(drive, 1)
        first = scan_points(scans[0], np.zeros(3), 0.1, 30.0, options.point_spacing)
        assert search.matcher.support(drive[0], first.xy).outside > options.partly_outside
        outcome = "none"
        for i, scan in enumerate(scans):
            pts = scan_points(scan, np.zeros(3), 0.1, 30.0, options.point_spacing)
            delta = np.zeros(3) if i == 0 else between_many(odo[i - 1], odo[i])
            winner = search.step(scan, pts, delta, False, odo[i], i)
            if winner is not None:
                off = np.hypot(*(winner.pose[:2] - drive[i, :2]))
                turn = abs((winner.pose[2] - drive[i, 2] + np.pi) % (2 * np.pi) - np.pi)
                outcome = "wrong" if off > 0.5 or turn > np.radians(5) else "right"
                break
        outcomes.append(outcome)
    assert "wrong" not in outcomes, outcomes
    assert outcomes.count("right") >= 2, outcomes
