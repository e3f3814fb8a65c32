"""Scan verification: the check accepts the true pose, refines a nearby one, rejects wrong ones."""

from __future__ import annotations

import math

import numpy as np
import pytest
from matching_world import corner_room

from laser_corners import CornerDetector, InvalidScanError
from laser_corners.matching import (
    PLACE_RECOGNITION,
    KeypointBank,
    MatchOptions,
    describe,
    register,
    register_keypoints,
    register_many,
)
from laser_corners.matching.verify import align, scan_agreement, scan_arrays, verify_pose
from laser_corners.sim import World

VOPT = MatchOptions(verify_scan=True).kernel_options("csc")  # the defaults, check on


@pytest.fixture(scope="module")
def room() -> World:
    return corner_room()


def _relative(pa: tuple[float, float, float], pb: tuple[float, float, float]) -> np.ndarray:
    c, s = math.cos(pa[2]), math.sin(pa[2])
    dx, dy = pb[0] - pa[0], pb[1] - pa[1]
    return np.array([c * dx + s * dy, -s * dx + c * dy, math.remainder(pb[2] - pa[2], 2 * math.pi)])


def test_check_accepts_truth_refines_and_rejects(room: World) -> None:
    rng = np.random.default_rng(4)
    pa, pb = (0.0, 0.0, 0.0), (0.5, -0.3, 0.4)
    a = scan_arrays(room.scan(pa, noise_sigma=0.01, rng=rng))
    b = scan_arrays(room.scan(pb, noise_sigma=0.01, rng=rng))
    truth = _relative(pa, pb)
    agreement, pose = verify_pose(a, b, tuple(truth), VOPT)
    assert agreement > 0.6
    assert np.allclose(pose, truth, atol=0.01)
    # a pose 8 cm and 1.5 deg off is pulled back by the alignment
    off = truth + np.array([0.06, -0.05, math.radians(1.5)])
    agreement, pose = verify_pose(a, b, tuple(off), VOPT)
    assert agreement > 0.6
    assert np.hypot(*(np.array(pose[:2]) - truth[:2])) < 0.01
    assert abs(pose[2] - truth[2]) < math.radians(0.3)
    # wrong poses: shifted by 1 m, turned by 0.5 rad, or turned around
    shifts = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 0.5], [0.0, 0.0, math.pi]])
    for wrong in truth + shifts:
        assert verify_pose(a, b, tuple(wrong), VOPT)[0] < 0.0, wrong
    # disabled: 1.0 and the pose unchanged
    assert verify_pose(a, b, tuple(off), VOPT._replace(verify_scan=False)) == (1.0, tuple(off))


def test_agreement_counts_agree_and_conflict() -> None:
    # scan A: a wall 2 m ahead; B's points 1 m ahead are seen through by A, 2 m agree,
    # 3 m are occluded (tested but neither)
    angles = np.radians(np.linspace(-30, 30, 61))
    ranges = 2.0 / np.cos(angles)
    geom = np.array([angles[0], angles[1] - angles[0], 0.05, 30.0])
    pts = np.array([[1.0, 0.0], [2.0, 0.1], [2.0, -0.3], [3.0, 0.0], [0.0, 2.0]])
    tested, agree, conflict = scan_agreement(ranges, geom, pts, (0.0, 0.0, 0.0), 0.1, 10)
    assert (tested, agree, conflict) == (4, 2, 1)  # (0, 2) is outside A's field of view
    # one straight wall does not fix the pose (sliding along it): the alignment leaves it
    wall = np.stack([ranges * np.cos(angles), ranges * np.sin(angles)], axis=1)
    assert align(ranges, geom, wall, (0.15, 0.0, 0.0), 3, 0.4) == (0.15, 0.0, 0.0)


def test_register_with_scan_check(room: World) -> None:
    rng = np.random.default_rng(8)
    pa, pb = (-1.0, 0.5, 1.0), (-0.2, -0.4, 0.5)
    a = room.scan(pa, noise_sigma=0.01, rng=rng)
    b = room.scan(pb, noise_sigma=0.01, rng=rng)
    reg = register(a, b, options=MatchOptions(verify_scan=True))
    assert reg.accepted and reg.agreement > 0.6
    truth = _relative(pa, pb)
    assert np.hypot(reg.pose[0] - truth[0], reg.pose[1] - truth[1]) < 0.01
    assert abs(math.remainder(reg.pose[2] - truth[2], math.tau)) < math.radians(0.5)
    # the same scans of another room: the keypoints may match, the scans do not
    other = World().add_polygon([[-3, -2], [3, -2], [3, 2], [-3, 2]])
    c = other.scan((0.0, 0.0, 0.3), noise_sigma=0.01, rng=rng)
    loose = MatchOptions(min_inliers=1, verify_scan=True)
    assert not register(a, c, options=loose).accepted
    det = CornerDetector()
    ka, kb = det.detect(a), det.detect(b)
    da, db = describe(a, ka), describe(b, kb)
    with pytest.raises(InvalidScanError, match="verify_scan"):
        register_keypoints(ka, da, kb, db, MatchOptions(verify_scan=True))
    bank = KeypointBank.from_lists([kb], [db])
    with pytest.raises(InvalidScanError, match="verify_scan"):
        register_many(ka, da, bank, options=PLACE_RECOGNITION, scan_a=a)
    bank = KeypointBank.from_lists([kb, kb], [db, db], [b, c])
    out = register_many(ka, da, bank, options=PLACE_RECOGNITION, scan_a=a)
    single = register_keypoints(ka, da, kb, db, PLACE_RECOGNITION, a, b)
    assert out.accepted[0] == single.accepted and out.n_inliers[0] == single.n_inliers
    assert out.agreement[0] == single.agreement and np.allclose(out.poses[0], single.pose)
    # candidate 1 carries b's keypoints but c's scan: the scans disagree
    assert not out.accepted[1] and out.status[1] == 4
