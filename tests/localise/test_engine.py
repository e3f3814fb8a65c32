"""Localisation as the engine's other mode (:mod:`laser_corners.localise.engine`): the SLAM
engine on the frozen map gives the online poses, placed by the localiser's fixes; it holds the
pose where the map has nothing, never where the scan contradicts the map."""

from __future__ import annotations

import math

import numpy as np
import pytest
from test_localiser import (
    BUILDING_PATH,
    RATE,
    building,
    errors,
    loop_path,
    map_folder,
    noisy_odometry,
    scans_along,
)

from laser_corners.localise import EngineOptions, LocaliseOptions, Localiser
from laser_corners.localise.engine import engine_options
from laser_corners.pose import between_many, compose_many
from laser_corners.registration.mapfolder import load_map
from laser_corners.slam import Slam, SlamOptions


@pytest.fixture(scope="module")
def engine_map(tmp_path_factory) -> tuple:
    truth = loop_path(BUILDING_PATH)
    return map_folder(tmp_path_factory.mktemp("map"), building(), truth), truth


def test_the_engine_gives_the_tracked_estimates(engine_map) -> None:
    folder, truth = engine_map
    loc = Localiser(folder)
    assert loc.engine is not None and loc.engine.slam.frozen
    loc.set_pose(truth[0])
    odo = noisy_odometry(truth, 11)
    estimates = []
    for i, (s, o) in enumerate(zip(scans_along(building(), truth, 11), odo, strict=True)):
        estimates.append(loc.add(s, o, i / RATE))
    assert loc.engine.confirmed and loc.counts["engine_replaced"] == 0
    last = estimates[-1]
    assert last is not None
    np.testing.assert_allclose(last.pose, loc.engine.pose)  # the engine's pose, not the tracker's
    d, yaw = errors(estimates, truth)
    assert len(d) >= 0.98 * len(truth)
    assert np.mean(d) < 0.03 and d.max() < 0.1 and yaw.max() < math.radians(1.5)
    # off: the tracker's poses, as before the engine
    assert Localiser(folder, LocaliseOptions(engine=EngineOptions(enabled=False))).engine is None


def test_a_placed_engine_starts_a_segment_at_the_given_pose(engine_map) -> None:
    folder, truth = engine_map
    slam = Slam(SlamOptions(), prior_map=load_map(folder), frozen=True)
    assert not slam.options.relocalisation  # the localiser places it, not its own search
    odo = noisy_odometry(truth, 12)
    scans = scans_along(building(), truth, 12)
    for i in range(5):
        slam.add(scans[i], odo[i], i / RATE)
    assert not slam.placed  # no fix yet: the session's frame is the odometry's
    slam.place(truth[4], (0.05, 0.05, 0.02))
    pose, _ = slam.add(scans[5], odo[5], 0.5)
    assert slam.placed
    d = between_many(truth[5], pose)
    assert math.hypot(d[0], d[1]) < 0.05 and abs(d[2]) < 0.02
    for i in range(6, 60):
        pose, _ = slam.add(scans[i], odo[i], i / RATE)
    d = between_many(truth[59], pose)
    assert math.hypot(d[0], d[1]) < 0.1  # tracked against the map from there
    slam.cut()
    slam.add(scans[60], odo[60], 6.0)
    assert not slam.placed  # a new segment, unplaced until the next place()


def test_the_engine_holds_a_pose_only_once_the_map_confirmed_it(engine_map) -> None:
    # a wrong initial pose places the engine too: until a scan the map explains agrees with
    # it, it may not hold a scan the map gives no estimate for (tests/localise/
    # test_localiser.py: the wrong pose is replaced, no wrong estimate meanwhile)
    folder, truth = engine_map
    loc = Localiser(folder)
    engine = loc.engine
    assert engine is not None
    scans, odo = scans_along(building(), truth, 14), noisy_odometry(truth, 14)
    engine.place(truth[0], np.diag([0.05, 0.05, 0.02]) ** 2, odo[0])
    engine.add(scans[1], odo[1], 0.1)
    assert engine.placed and not engine.confirmed and not engine.holds()
    assert engine.disagrees(truth[1] + np.array([0.5, 0.0, 0.0]))  # beyond the gate: no
    assert not engine.confirmed
    assert not engine.disagrees(truth[1] + np.array([0.05, 0.0, 0.01]))  # within: confirmed
    assert engine.confirmed and engine.holds()
    alone = engine.alone(odo[1], 1, 0.1)
    assert alone is not None and alone.status == "local"
    engine.cut()  # an odometry jump: unplaced, and not fed until the next fix
    engine.add(scans[2], odo[2], 0.2)
    assert not engine.holds() and engine.alone(odo[2], 2, 0.2) is None
    assert engine.slam.counts.scans == 1
    engine.place(truth[2], np.diag([0.05, 0.05, 0.02]) ** 2, odo[2])
    assert not engine.confirmed  # placed again: confirmed again by the map first
    engine.add(scans[3], odo[3], 0.3)
    d = between_many(truth[3], engine.pose)
    assert math.hypot(d[0], d[1]) < 0.05  # moved from the fix by the odometry step


def test_a_scan_not_given_can_place_the_engine_by_its_odometry(engine_map) -> None:
    # a localiser places the engine at a fix on a scan it did not feed it (unplaced engines
    # are not fed): the next scan is moved from the fix by the odometry step since that scan
    folder, truth = engine_map
    slam = Slam(SlamOptions(), prior_map=load_map(folder), frozen=True)
    odo = noisy_odometry(truth, 15)
    scans = scans_along(building(), truth, 15)
    slam.place(truth[9], (0.05, 0.05, 0.02), odo[9])
    pose, _ = slam.add(scans[10], odo[10], 1.0)
    d = between_many(truth[10], pose)
    assert math.hypot(d[0], d[1]) < 0.05 and abs(d[2]) < 0.02
    assert slam.placed and slam.counts.scans == 1


def test_the_engine_is_fed_only_from_the_first_fix_on(engine_map) -> None:
    # no initial pose: the scans of the global search cost the engine nothing, and its first
    # keyframe is the scan after the fix, in the map's frame
    folder, truth = engine_map
    loc = Localiser(folder)
    assert loc.engine is not None
    scans, odo = scans_along(building(), truth, 16), noisy_odometry(truth, 16)
    first = None
    for i, (s, o) in enumerate(zip(scans, odo, strict=True)):
        if loc.add(s, o, i / RATE) is not None and first is None:
            first = i
    assert first is not None and first > 0
    assert loc.engine.slam.counts.scans == len(scans) - 1 - first
    kf = loc.engine.slam.kf
    session = np.asarray(kf.estimate[kf.first :])
    nearest = np.min(np.hypot(*(session[:, None, :2] - truth[None, :, :2]).transpose(2, 0, 1)), 1)
    assert nearest.max() < 0.2  # every session keyframe in the map's frame


def test_the_engine_takes_the_localisers_odometry_noise_but_keeps_the_slams_icp() -> None:
    options = LocaliseOptions().with_overrides(["odometry.sigma_xy=0.1", "icp.iterations=5"])
    engine = engine_options(options)
    assert engine.odometry == options.odometry  # a fact of the robot: one noise for both
    assert engine.icp == SlamOptions().icp  # tracks and closes loops as the map was made
    assert not engine.relocalisation


def test_the_estimates_do_not_depend_on_the_odometrys_frame(engine_map) -> None:
    # a later visit's odometry starts in a frame of its own: no initial pose, the same drive
    # with its odometry moved by a rigid transform gives the same estimates (the engine, not
    # fed before the first fix, has nothing in the odometry's frame to track against)
    folder, truth = engine_map
    scans, odo = scans_along(building(), truth, 17), noisy_odometry(truth, 17)
    moved = compose_many(np.array([50.0, -30.0, 1.0]), odo)
    runs = []
    for odometry in (odo, moved):
        loc = Localiser(folder)
        runs.append(
            [loc.add(s, o, i / RATE) for i, (s, o) in enumerate(zip(scans, odometry, strict=True))]
        )
    found = [i for i, e in enumerate(runs[0]) if e is not None]
    assert len(found) > len(truth) // 2
    assert found == [i for i, e in enumerate(runs[1]) if e is not None]
    for i in found:
        np.testing.assert_allclose(runs[0][i].pose, runs[1][i].pose, atol=1e-6)


def test_the_map_settles_a_disagreement_between_tracker_and_engine(engine_map) -> None:
    # the map sides with the engine (it explains the scan at least as well there): the engine
    # stands, confirmed; it is re-placed only after engine.gate_scans scans in a row on which
    # the map explains the scan better at the tracker's pose
    folder, truth = engine_map
    options = LocaliseOptions().with_overrides(["engine.gate_scans=3"])
    loc = Localiser(folder, options)
    engine = loc.engine
    assert engine is not None
    scans, odo = scans_along(building(), truth, 18), noisy_odometry(truth, 18)
    engine.place(truth[0], np.diag([0.05, 0.05, 0.02]) ** 2, odo[0])
    engine.add(scans[1], odo[1], 0.1)
    tracked = truth[1] + np.array([0.6, 0.0, 0.0])
    assert engine.disagrees(tracked) and not engine.confirmed

    def explains(tracker: float, engine: float):
        return lambda pose: tracker if np.allclose(pose, tracked) else engine

    assert engine.settle(tracked, explains(0.8, 0.8)) == "engine"  # a tie: the engine stands
    assert engine.confirmed
    sides = [engine.settle(tracked, explains(0.9, 0.6)) for _ in range(3)]
    assert sides == ["tracker", "tracker", "replace"]
    engine.settle(tracked, explains(0.9, 0.6))
    assert engine.settle(tracked, explains(0.5, 0.6)) == "engine"  # the run is broken
    assert [engine.settle(tracked, explains(0.9, 0.6)) for _ in range(3)][-1] == "replace"


def test_an_engine_gone_astray_is_placed_again_where_the_map_is(engine_map) -> None:
    # the engine moved 0.6 m off mid-drive (a wrong closure, say): the tracker, anchored in
    # the map, disagrees, the map explains the scans better at its pose, and after
    # engine.gate_scans scans the engine is placed again; the estimates are right again
    folder, truth = engine_map
    loc = Localiser(folder)
    loc.set_pose(truth[0])
    scans, odo = scans_along(building(), truth, 19), noisy_odometry(truth, 19)
    estimates = []
    for i, (s, o) in enumerate(zip(scans, odo, strict=True)):
        if i == 40:
            assert loc.engine is not None and loc.engine.confirmed
            off = compose_many(truth[39], np.array([0.6, 0.0, 0.0]))
            loc.engine.place(off, np.diag([0.05, 0.05, 0.02]) ** 2, odo[39])
        estimates.append(loc.add(s, o, i / RATE))
    assert loc.counts["engine_replaced"] == 1
    gate = loc.options.engine.gate_scans
    late = [e for e in estimates[40 + gate + 1 :] if e is not None]
    d = [math.hypot(*between_many(truth[e.scan_index], e.pose)[:2]) for e in late]
    assert len(late) > 0.9 * (len(truth) - 41 - gate) and max(d) < 0.1
    early = [e for e in estimates[40 : 40 + gate] if e is not None]
    assert all(math.hypot(*between_many(truth[e.scan_index], e.pose)[:2]) < 0.1 for e in early)
