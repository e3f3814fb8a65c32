"""Tracking a fix (``localise.tracker``): estimates while the scans fit, lost after
``lost_scans`` scans that do not, in a simulated building."""

from __future__ import annotations

import numpy as np
import pytest
from test_localiser import building, loaded_building, noisy_odometry, scans_along

from laser_corners.localise import LocaliseOptions
from laser_corners.localise.local import LocalMap
from laser_corners.localise.mapmodel import GLOBAL_SIGMA, MapModel
from laser_corners.localise.matcher import MapMatcher
from laser_corners.localise.tracker import Tracker
from laser_corners.pose import between_many
from laser_corners.registration.points import scan_points


@pytest.fixture(scope="module")
def building_world(tmp_path_factory):
    return loaded_building(tmp_path_factory)


def _tracker(saved, options=None) -> tuple[Tracker, dict]:
    options = options or LocaliseOptions()
    model = MapModel(saved, options)
    counts = dict.fromkeys(("no_agreement", "recoveries", "local"), 0)
    return Tracker(
        MapMatcher(model, options, np.zeros(3)), LocalMap(model.grid, GLOBAL_SIGMA), counts
    ), counts


def _steps(tracker, scans, odo, options):
    out = []
    for i in range(len(scans)):
        pts = scan_points(scans[i], np.zeros(3), 0.1, 30.0, options.point_spacing)
        delta = np.zeros(3) if i == 0 else between_many(odo[i - 1], odo[i])
        out.append(tracker.step(pts, delta, False, odo[i], i, i / 10.0))
    return out


def test_a_started_track_follows_the_robot(building_world) -> None:
    saved, truth = building_world
    drive = truth[:120]
    tracker, counts = _tracker(saved)
    tracker.start(drive[0])
    estimates = _steps(
        tracker, scans_along(building(), drive, 4), noisy_odometry(drive, 4), tracker.options
    )
    assert all(e is not None and e.status == "tracking" for e in estimates)
    d = [np.hypot(*(e.pose[:2] - t[:2])) for e, t in zip(estimates, drive, strict=True)]
    assert max(d) < 0.1 and not tracker.lost and counts["no_agreement"] == 0
    assert np.all(np.linalg.eigvalsh(estimates[-1].covariance) > 0)


def test_scans_of_another_place_lose_the_track_after_lost_scans(building_world) -> None:
    saved, truth = building_world
    options = LocaliseOptions(lost_scans=4)
    tracker, counts = _tracker(saved, options)
    tracker.start(truth[0] + np.array([3.0, 2.0, 1.2]))  # far from where the scans are
    drive = truth[:6]
    estimates = _steps(
        tracker, scans_along(building(), drive, 5), noisy_odometry(drive, 5), options
    )
    assert estimates[:4] == [None] * 4 and tracker.lost
    assert counts["no_agreement"] >= 4
    last = tracker.stop()
    assert last.shape == (3,) and tracker.pose is None and not tracker.lost
