"""The final refinement pass (:mod:`laser_corners.slam.refine`) on simulated keyframes with known
poses: its links measure the true relative poses, a keyframe far off its place gets none, and
solving with them pulls a map bent between two laps back to the truth."""

from __future__ import annotations

import math

import numpy as np
import pytest

pytest.importorskip("gtsam")

from laser_corners.pose import between_many, compose, wrap_angle
from laser_corners.registration.points import scan_points
from laser_corners.sim import SICK_LMS_1DEG, World
from laser_corners.slam import Slam, SlamOptions
from laser_corners.slam.backend import Backend
from laser_corners.slam.refine import refine, refine_links

OPTIONS = SlamOptions()


def _building() -> World:
    world = World().add_polygon([[0, 0], [12, 0], [12, 8], [0, 8]])
    world.add_polygon([[6, 0], [6.1, 0], [6.1, 3], [6, 3]])
    world.add_polygon([[6, 5], [6.1, 5], [6.1, 8], [6, 8]])
    world.add_polygon([[2.5, 2.5], [3.3, 2.5], [3.3, 3.2], [2.5, 3.2]])
    world.add_polygon([[9, 5.5], [10, 5.5], [9.5, 6.4]])
    return world


def _keyframes(laps: int = 2) -> np.ndarray:
    """Keyframe poses 0.4 m apart around the rectangle through both rooms, ``laps`` times
    (the second lap 0.1 m to the side, heading wobbling, so no pose repeats exactly)."""
    corners = np.array([[1.5, 1.5], [10.5, 1.5], [10.5, 6.5], [1.5, 6.5]])
    poses = []
    for lap in range(laps):
        for a, b in zip(corners, np.roll(corners, -1, axis=0), strict=True):
            heading = math.atan2(b[1] - a[1], b[0] - a[0])
            side = 0.1 * lap * np.array([-math.sin(heading), math.cos(heading)])
            n = int(np.hypot(*(b - a)) / 0.4)
            for i in range(n):
                xy = a + side + (i / n) * (b - a)
                poses.append((xy[0], xy[1], heading + 0.05 * math.sin(len(poses))))
    return np.array(poses)


@pytest.fixture(scope="module")
def lap():
    truth = _keyframes()
    world = _building()
    rng = np.random.default_rng(5)
    points = [
        scan_points(
            world.scan(tuple(p), SICK_LMS_1DEG, noise_sigma=0.01, rng=rng),
            np.zeros(3),
            OPTIONS.min_range,
            OPTIONS.max_range,
            OPTIONS.point_spacing,
        )
        for p in truth
    ]
    travelled = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(truth[:, :2], axis=0).T))])
    return truth, points, travelled


def _bent(truth: np.ndarray) -> np.ndarray:
    """The truth with the second lap drifting away from the first: moved by up to 8 cm and
    0.1 degrees, growing along the lap (a map bent where the loop was closed badly), within
    what the pass may correct."""
    bent = truth.copy()
    second = len(truth) // 2
    share = np.linspace(0.0, 1.0, len(truth) - second)[:, None]
    drift = share * np.array([0.05, -0.06, math.radians(0.1)])
    bent[second:] = [compose(d, p) for d, p in zip(drift, truth[second:], strict=True)]
    return bent


def test_refine_links_measure_the_true_relative_poses(lap) -> None:
    truth, points, travelled = lap
    estimate = _bent(truth)
    far = len(truth) // 2 + 9
    estimate[far, :2] += 0.6  # one keyframe far off its place: no link may pass for it
    links = refine_links(points, estimate, travelled, OPTIONS)
    assert far not in set(links.match.tolist())  # not a submap anchor (its frame would be off)
    assert links.tried > len(truth) // 2 and len(links) > len(truth) // 3
    assert far not in set(links.query.tolist())
    # a submap never holds the keyframe it aligns (1.5 submap lengths on each side)
    assert np.abs(links.query - links.match).min() > 1.5 * OPTIONS.loop.submap_keyframes
    true_rel = between_many(truth[links.match], truth[links.query])
    err = between_many(true_rel, links.relative)
    assert np.percentile(np.hypot(err[:, 0], err[:, 1]), 90) < 0.015
    assert np.percentile(np.abs(np.degrees(wrap_angle(err[:, 2]))), 90) < 0.3


def test_refinement_straightens_a_map_bent_between_laps(lap) -> None:
    # the chain of keyframe links says the laps are as bent (a loop closed badly); the pass's
    # links across the laps, at least as many as the chain's, pull the map back to the truth
    truth, points, travelled = lap
    bent = _bent(truth)
    backend = Backend()
    for k, pose in enumerate(bent):
        backend.add_keyframe(pose)
        if k:
            rel = between_many(bent[k - 1], bent[k])
            backend.add_between(k - 1, k, rel, (0.02, 0.02, 0.005))
    backend.update()
    _, before = backend.optimise()
    _, _, counts = refine(backend, before, points, travelled, OPTIONS)
    assert counts["refine_links"] > len(truth) // 3
    assert counts["refine_pruned"] <= counts["refine_links"] // 20
    second = len(truth) // 2
    lap_truth = between_many(truth[:second], truth[second : 2 * second])
    lap_bent = between_many(bent[:second], bent[second : 2 * second])
    est = backend.estimate
    lap_after = between_many(est[:second], est[second : 2 * second])
    before_err = np.hypot(*(lap_bent - lap_truth)[:, :2].T).mean()
    after_err = np.hypot(*(lap_after - lap_truth)[:, :2].T).mean()
    assert before_err > 0.025 and after_err < before_err / 3, (before_err, after_err)


def test_refine_min_travel_keeps_only_links_across_the_loop(lap) -> None:
    truth, points, travelled = lap
    options = OPTIONS.with_overrides(["refine_min_travel=10"])
    links = refine_links(points, truth, travelled, options)
    apart = np.abs(travelled[links.query] - travelled[links.match])
    assert len(links) > 0 and apart.min() >= 10.0


def test_slam_with_the_refinement_pass(lap) -> None:
    # two laps at keyframe spacing with slightly wrong odometry: the option runs the pass
    # after the final optimisation, counts its links and keeps the map on the truth
    truth, _, _ = lap
    world = _building()
    rng = np.random.default_rng(9)
    steps = between_many(truth[:-1], truth[1:]) * np.array([1.02, 1.0, 1.01])
    odo = [truth[0]]
    for d in steps:
        odo.append(compose(odo[-1], d))
    results = {}
    for on in (False, True):
        slam = Slam(OPTIONS.with_overrides([f"refine_final={on}"]))
        for i, (pose, odom) in enumerate(zip(truth, odo, strict=True)):
            scan = world.scan(tuple(pose), SICK_LMS_1DEG, noise_sigma=0.01, rng=rng)
            slam.add(scan, odom, float(i))
        results[on] = slam.result()
    off, on = results[False], results[True]
    assert off.counts["refine_links"] == 0 and on.counts["refine_links"] > len(truth) // 3
    assert on.counts["refine_tried"] >= on.counts["refine_links"] + on.counts["refine_pruned"]
    error = np.hypot(*(on.poses[:, :2] - truth[:, :2]).T)
    assert error.max() < 0.1
