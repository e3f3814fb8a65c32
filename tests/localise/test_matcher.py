"""One scan against the saved map (``localise.matcher``): the odometry prior, ICP's
agreement and the free-space test, in a simulated building."""

from __future__ import annotations

import numpy as np
import pytest
from test_localiser import building, loaded_building, scans_along

from laser_corners.localise import LocaliseOptions
from laser_corners.localise.mapmodel import MapModel
from laser_corners.localise.matcher import MapMatcher
from laser_corners.registration.odometry import JUMP_SIGMAS
from laser_corners.registration.points import scan_points


@pytest.fixture(scope="module")
def building_world(tmp_path_factory):
    return loaded_building(tmp_path_factory)


@pytest.fixture(scope="module")
def matcher_and_scan(building_world):
    saved, truth = building_world
    options = LocaliseOptions()
    matcher = MapMatcher(MapModel(saved, options), options, np.zeros(3))
    scan = scans_along(building(), truth[40:41], seed=3)[0]
    xy = scan_points(scan, np.zeros(3), 0.1, 30.0, options.point_spacing).xy
    return matcher, xy, truth[40]


def test_the_odometry_prior_weakens_with_the_step_and_across_a_jump(matcher_and_scan) -> None:
    matcher, *_ = matcher_and_scan
    still = matcher.prior(np.zeros(3), False)
    moved = matcher.prior(np.array([1.0, 0.0, 0.5]), False)
    assert np.all(np.diag(moved) < np.diag(still))
    opt = matcher.options
    assert still[0, 0] == pytest.approx(1.0 / (opt.odometry.sigma_xy * 0.1) ** 2)
    assert np.allclose(matcher.prior(np.zeros(3), True), np.diag(1.0 / JUMP_SIGMAS**2))


def test_icp_pulls_a_shifted_guess_back_and_the_true_pose_is_admissible(matcher_and_scan) -> None:
    matcher, xy, truth = matcher_and_scan
    guess = truth + np.array([0.15, -0.1, 0.04])
    aligned, agreement = matcher.align(xy, guess, np.zeros((3, 3)))
    assert np.hypot(*(aligned.pose[:2] - truth[:2])) < 0.03
    assert agreement > 0.9
    assert matcher.admits(matcher.support(truth, xy))


def test_a_pose_that_sees_through_walls_is_not_admissible(matcher_and_scan) -> None:
    matcher, xy, truth = matcher_and_scan
    turned = truth + np.array([0.0, 0.0, np.pi / 2])  # the beams end in free space / walls
    support = matcher.support(turned, xy)
    assert support.conflict > matcher.options.max_conflict
    assert not matcher.admits(support)
