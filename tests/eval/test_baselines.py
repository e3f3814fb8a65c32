"""The split-and-merge line-intersection baseline."""

from __future__ import annotations

import numpy as np
import pytest

from laser_corners import Keypoints
from laser_corners.errors import InvalidParamsError, InvalidScanError
from laser_corners.eval.baselines import SplitAndMergeDetector, SplitAndMergeParams
from laser_corners.sim import UST_10LX, World, corner_scan, rectangular_room


def test_clean_corner_gives_one_exact_keypoint() -> None:
    kps = SplitAndMergeDetector().detect(corner_scan((2.0, 1.0)))
    assert isinstance(kps, Keypoints)
    assert len(kps) == 1
    assert np.hypot(*(kps.xy[0] - [2.0, 1.0])) < 1e-6
    assert kps.opening_angle_deg[0] == pytest.approx(90.0, abs=1e-6)


def test_straight_wall_gives_no_keypoint_and_one_segment() -> None:
    world = World().add_polygon([[3.0, -4.0], [3.0, 4.0], [2.9, 4.0], [2.9, -4.0]])
    scan = world.scan((0.0, 0.0, 0.0), UST_10LX, noise_sigma=0.01, rng=np.random.default_rng(0))
    detector = SplitAndMergeDetector()
    assert len(detector.detect(scan)) == 0
    assert len(detector.segments(scan)) == 1


def test_room_corners_found_with_noise() -> None:
    world = rectangular_room(6.0, 4.0)
    pose = (-1.5, -1.0, 0.3)
    scan = world.scan(pose, UST_10LX, noise_sigma=0.01, rng=np.random.default_rng(5), stamp=3.0)
    truth = world.visible_corners(pose, UST_10LX)
    kps = SplitAndMergeDetector().detect(scan)
    assert kps.stamp == 3.0
    assert kps.frame_id == "laser"
    d = np.hypot(truth[:, None, 0] - kps.xy[None, :, 0], truth[:, None, 1] - kps.xy[None, :, 1])
    assert np.all(d.min(axis=1) < 0.03)  # every visible corner found within 3 cm
    assert np.all(d.min(axis=0) < 0.1)  # and nothing else


def test_split_distance_override_and_validation() -> None:
    scan = corner_scan((2.0, 1.0))
    assert len(SplitAndMergeDetector(SplitAndMergeParams(split_distance=0.05)).detect(scan)) == 1
    # a split threshold larger than the corner's distance from its chord finds no corner
    assert len(SplitAndMergeDetector(SplitAndMergeParams(split_distance=5.0)).detect(scan)) == 0
    with pytest.raises(InvalidParamsError):
        SplitAndMergeParams(split_distance=0.0)
    with pytest.raises(InvalidParamsError):
        SplitAndMergeParams(min_points=1)
    with pytest.raises(InvalidScanError):
        SplitAndMergeDetector().detect("not a scan")  # type: ignore[arg-type]


def test_detect_many_matches_detect() -> None:
    world = rectangular_room()
    rng = np.random.default_rng(1)
    scans = [world.scan((0.1 * i, 0.0, 0.2 * i), UST_10LX, 0.005, rng) for i in range(3)]
    detector = SplitAndMergeDetector()
    for got, scan in zip(detector.detect_many(scans), scans, strict=True):
        assert np.array_equal(got.xy, detector.detect(scan).xy)
