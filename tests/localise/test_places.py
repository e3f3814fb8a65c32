"""The localiser's global search by corners (``localise.places``) on a real log: fr079.bag's
first 1,500 scans mapped, then localised with no initial pose from scans in the middle, and
across a 20 m odometry jump; the attempts' records (bounded) in the simulated building."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

pytest.importorskip("gtsam")

from test_localiser import building, loaded_building, noisy_odometry, scans_along

from conftest import real_file
from laser_corners.localise import LocaliseOptions, Localiser, estimate
from laser_corners.localise.mapmodel import MapModel
from laser_corners.localise.places import PlaceProposer
from laser_corners.localise.search import GLOBAL_SPACING
from laser_corners.pipeline.recording import open_recording
from laser_corners.pose import between_many, compose_many
from laser_corners.registration.mapfolder import load_map
from laser_corners.registration.place_index import PlaceOptions
from laser_corners.registration.points import scan_points
from laser_corners.slam import run_slam
from laser_corners.slam.output import SlamRunInfo
from laser_corners.viz.slam_report import write_slam_outputs

MAPPED = 1500


@pytest.fixture(scope="module")
def fr079(tmp_path_factory):
    """The map of fr079.bag's first scans, and every mapped scan with its odometry and the
    SLAM's pose (the reference)."""
    path = real_file("fr079.bag")
    result = run_slam(path, stop_scan=MAPPED)
    folder = tmp_path_factory.mktemp("fr079")
    write_slam_outputs(result, folder, SlamRunInfo(str(path), 1.0, 0.0))
    scans = []
    with open_recording(path, None) as rec:
        for scan in rec.scans():
            if len(scans) == len(result.stamps):
                break
            if scan.pose is not None:  # the scans the SLAM took (those with odometry)
                scans.append(scan)
    assert np.allclose([s.stamp for s in scans], result.stamps)
    return load_map(folder), scans, result.odometry, result.poses


def _drive(loc: Localiser, scans, odo, ref, order) -> tuple[list, float]:
    """Feed ``order``; every (index, estimate error m, deg) and the travel at the first fix."""
    travel, first, errors = 0.0, None, []
    for n, i in enumerate(order):
        if n:
            d = between_many(odo[order[n - 1]], odo[i])
            travel += math.hypot(d[0], d[1])
        e = loc.add(scans[i], odo[i], float(scans[i].stamp))
        if e is None:
            continue
        d = between_many(ref[i], e.pose)
        errors.append((i, math.hypot(d[0], d[1]), abs(math.degrees(d[2]))))
        first = travel if first is None else first
    return errors, first


def test_index_is_in_the_map_folder(fr079) -> None:
    saved, *_ = fr079
    assert saved.places is not None and len(saved.places) > 5 * len(saved)


@pytest.mark.parametrize("start", [300, 800, 1150])
def test_mid_log_start_without_a_pose_fixes_within_3_m(fr079, start: int) -> None:
    saved, scans, odo, ref = fr079
    loc = Localiser(saved)
    errors, first = _drive(loc, scans, odo, ref, np.arange(start, start + 250))
    assert first is not None and first <= 3.0
    assert max(e[1] for e in errors) < 0.5 and max(e[2] for e in errors) < 5.0
    assert loc.counts["searches"] == 0  # the index alone: no exhaustive search
    assert np.mean(loc.places.ms) < 100.0  # loose: a shared test machine (benchmark: 20 ms)


def test_a_20_m_odometry_jump_is_relocalised_by_corners(fr079) -> None:
    saved, scans, odo, ref = fr079
    odo = odo.copy()
    order = np.arange(200, 700)
    jump = 250  # from scan 450 on the odometry is 20 m off: a kidnap it reports
    odo[order[jump:]] = compose_many(np.array([20.0, 0.0, 0.0]), odo[order[jump:]])
    loc = Localiser(saved)
    errors, _ = _drive(loc, scans, odo, ref, order)
    assert loc.counts["lost"] >= 1 and len(loc.fixes) == 2
    after = [e for e in errors if e[0] >= order[jump]]
    assert after and max(e[1] for e in errors) < 0.5  # no wrong estimate, before or after
    back = between_many(odo[order[jump]], odo[after[0][0]])
    assert math.hypot(back[0], back[1]) <= 3.0


def test_a_late_proposal_is_credited_with_the_scans_before_it(fr079) -> None:
    """Only the exhaustive search proposes (every 40 scans) and the first scan sees nothing:
    the right pose is proposed at the second search, 40 scans in. Credited with the scans
    before it that it explains (``localise.history``), it becomes the fix after
    ``fix_followed_travel`` more, not after ``fix_travel`` more."""
    saved, scans, odo, ref = fr079
    start = 800
    blank = dataclasses.replace(scans[start], ranges=np.full(scans[start].n_beams, np.inf))
    options = LocaliseOptions(global_every=40, places=PlaceOptions(enabled=False))
    loc = Localiser(saved, options)
    order = np.arange(start, start + 250)
    feed = [blank] + [scans[i] for i in order[1:]]
    travel, first, proposed_at = 0.0, None, None
    for n, i in enumerate(order):
        if n:
            d = between_many(odo[order[n - 1]], odo[i])
            travel += math.hypot(d[0], d[1]) + 0.5 * abs(d[2])  # the localiser's travel
        if n == 40:
            proposed_at = travel
        e = loc.add(feed[n], odo[i], float(scans[i].stamp))
        if e is not None:
            first = travel
            d = between_many(ref[i], e.pose)
            assert math.hypot(d[0], d[1]) < 0.5 and abs(d[2]) < math.radians(5)
            break
    assert proposed_at is not None and proposed_at > 0.5  # the robot did move before
    assert first is not None
    assert first < proposed_at + options.fix_travel - 0.25  # sooner than without the credit
    assert loc.counts["credited"] >= 1


def test_a_corner_rich_stretch_costs_a_bounded_query_and_still_fixes(fr079) -> None:
    """fr079 from scan 849: over 100 corner observations in the query's 3 m, more than 40
    once merged. The query uses at most ``places.max_query`` of them (the cap is reached
    here; the nearest the robot), each proposes ``matches`` poses,
    at most ``checked`` go to the dense check; the fix still comes within 3 m, right."""
    saved, scans, odo, ref = fr079
    loc = Localiser(saved)
    errors, first = _drive(loc, scans, odo, ref, np.arange(849, 1099))
    assert first is not None and first <= 3.0
    assert max(e[1] for e in errors) < 0.5 and max(e[2] for e in errors) < 5.0
    opt = loc.options.places
    work = loc.places.work
    assert len(work) == len(loc.places.ms) > 0
    assert max(w.corners for w in work) == opt.max_query
    assert all(w.proposals <= w.corners * opt.matches for w in work)
    assert all(w.checked <= opt.checked for w in work)


@pytest.fixture(scope="module")
def building_world(tmp_path_factory):
    return loaded_building(tmp_path_factory)


def _proposer(saved) -> PlaceProposer:
    options = LocaliseOptions()
    grid = MapModel(saved, options).grid
    return PlaceProposer(saved.places, saved.poses, grid, np.zeros(3), options.places)


def test_attempt_records_keep_the_newest_timings_kept(building_world, monkeypatch) -> None:
    """A localiser running for days keeps the last ``TIMINGS_KEPT`` attempts' times and work,
    not one an attempt forever: the newest, as an unbounded record's last ones."""
    saved, truth = building_world
    drive = truth[:40]  # the query grows from 2 corners to 4
    scans, odo = scans_along(building(), drive, 8), noisy_odometry(drive, 8)
    unbounded = _proposer(saved)
    monkeypatch.setattr(estimate, "TIMINGS_KEPT", 4)
    bounded = _proposer(saved)
    assert bounded.usable
    kept, checked = [], 0
    for scan, o in zip(scans, odo, strict=True):
        points = scan_points(scan, np.zeros(3), 0.1, 30.0, GLOBAL_SPACING).xy
        for proposer in (unbounded, bounded):
            proposer.observe(scan, o)
            proposer.propose(points)
        if len(kept) == 4:  # one attempt more: the oldest time dropped, the newest appended
            assert list(bounded.ms)[:-1] == kept[1:]
            checked += 1
        kept = list(bounded.ms)
    assert len(unbounded.ms) == len(unbounded.work) == len(drive) and checked > 30
    assert len(bounded.ms) == len(bounded.work) == 4
    work = list(unbounded.work)
    assert work[:4] != work[-4:] and list(bounded.work) == work[-4:]
