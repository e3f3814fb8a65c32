"""The SLAM's front end against a local map at known poses (laser_corners.slam.tracking)."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("gtsam")

from laser_corners.registration.points import scan_points
from laser_corners.sim import SICK_LMS_1DEG, World
from laser_corners.slam.counts import SlamCounts
from laser_corners.slam.keyframes import KeyframeStore
from laser_corners.slam.options import SlamOptions
from laser_corners.slam.tracking import Tracking, disagrees
from sim_drives import two_rooms

OPTIONS = SlamOptions()
TRUE = np.array([4.0, 4.0, 0.1])


def _points(world: World, pose, rng):
    scan = world.scan(tuple(pose), SICK_LMS_1DEG, noise_sigma=0.01, rng=rng)
    opt = OPTIONS
    return scan, scan_points(scan, np.zeros(3), opt.min_range, opt.max_range, opt.point_spacing)


def _tracking(world: World, options: SlamOptions = OPTIONS) -> tuple[Tracking, SlamCounts]:
    """A front end whose local map is three keyframes of ``world`` around :data:`TRUE`."""
    rng, store = np.random.default_rng(3), KeyframeStore()
    poses = np.array([[3.4, 4.0, 0.0], [3.7, 4.1, 0.05], [4.0, 4.0, 0.1]]) - [0.3, 0, 0]
    for i, pose in enumerate(poses):
        scan, pts = _points(world, pose, rng)
        store.add(scan, pts, i, float(i), pose, pose)
    store.estimate = poses
    counts = SlamCounts()
    tracking = Tracking(options, np.zeros(3), counts)
    tracking.new_local_map(*store.local_map(options.local_map_keyframes))
    return tracking, counts


def test_a_scan_is_aligned_to_the_local_map_from_a_prediction_a_little_off() -> None:
    tracking, counts = _tracking(two_rooms())
    _, pts = _points(two_rooms(), TRUE, np.random.default_rng(4))
    pred = TRUE + np.array([0.08, -0.05, 0.02])
    pose = tracking.track(pts, pred, np.array([0.3, 0.0, 0.0]), False, None, pred)
    assert np.hypot(*(pose[:2] - TRUE[:2])) < 0.02 and abs(pose[2] - TRUE[2]) < 0.005
    assert tracking.aligned and counts.alignment_failures == 0
    assert (
        tracking.fit_share(pts.xy, pose)
        > 0.9
        > tracking.fit_share(pts.xy, TRUE + np.array([0.5, 0, 0]))
    )


def test_a_scan_that_fits_nothing_keeps_the_prediction_counted() -> None:
    far = World().add_polygon([[100, 100], [101, 100], [101, 101], [100, 101]])
    tracking, counts = _tracking(far)
    _, pts = _points(two_rooms(), TRUE, np.random.default_rng(4))
    pose = tracking.track(pts, TRUE, np.zeros(3), False, None, TRUE)
    assert np.array_equal(pose, TRUE)
    assert counts.alignment_failures == 1 and not tracking.aligned
    tracking.new_local_map(tracking.local, tracking.local_all)  # a keyframe resets it
    assert tracking.aligned and not tracking.jumped and not tracking.lost


def test_without_a_local_map_the_prediction_stands_and_a_jump_is_counted() -> None:
    counts = SlamCounts()
    tracking = Tracking(OPTIONS, np.zeros(3), counts)
    _, pts = _points(two_rooms(), TRUE, np.random.default_rng(4))
    assert np.array_equal(tracking.track(pts, TRUE, np.zeros(3), True, None, TRUE), TRUE)
    assert counts.time_jumps == 1 and tracking.jumped and counts.alignment_failures == 0


def test_the_corner_front_end_without_a_registration_fails_the_scan() -> None:
    counts = SlamCounts()
    tracking = Tracking(SlamOptions(front_end="corners"), np.zeros(3), counts)
    _, pts = _points(two_rooms(), TRUE, np.random.default_rng(4))
    assert tracking.corner_guess(None, None, TRUE, TRUE) is None  # no corner front end
    assert np.array_equal(tracking.track(pts, TRUE, np.zeros(3), False, None, TRUE), TRUE)
    assert counts.alignment_failures == 1
    corner = TRUE + np.array([0.01, 0.0, 0.0])
    assert np.array_equal(tracking.track(pts, TRUE, np.zeros(3), False, corner, TRUE), corner)


def test_a_scan_of_a_bigger_place_sees_through_the_walls_lost() -> None:
    tracking, counts = _tracking(two_rooms())
    _, pts = _points(two_rooms(), TRUE, np.random.default_rng(4))
    assert not tracking.lost_at(pts, TRUE) and not tracking.lost
    hall = World().add_polygon([[-3, -3], [11, -3], [11, 11], [-3, 11]])
    _, kidnapped = _points(hall, TRUE, np.random.default_rng(4))  # walls 7 m away
    assert tracking.lost_at(kidnapped, TRUE)
    assert tracking.lost and counts.lost == 1
    off = Tracking(SlamOptions(relocalisation=False), np.zeros(3), SlamCounts())
    off.new_local_map(tracking.local, tracking.local_all)
    assert not off.lost_at(kidnapped, TRUE)


def test_disagrees_is_three_sigmas_off_the_prediction() -> None:
    sig = np.array([0.1, 0.1, 0.05])
    assert not disagrees(np.array([0.29, 0.0, 0.0]), np.zeros(3), sig)
    assert disagrees(np.array([0.0, 0.0, 0.16]), np.zeros(3), sig)
