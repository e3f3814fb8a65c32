"""Keypoint-to-feature association (:mod:`laser_corners.eval.association`) on hand-made cases."""

from __future__ import annotations

import math

import numpy as np
import pytest

from laser_corners.eval.association import (
    associate,
    association_stats,
    observation_table,
    pair_distance_std,
)


def test_associate_nearest_one_to_one_within_radius() -> None:
    kps = [[0.0, 0.0], [1.05, 0.0], [2.0, 0.0]]
    feats = [[1.0, 0.0], [1.08, 0.0], [0.0, 0.1], [5.0, 5.0]]
    # keypoint 1 is nearest to feature 1 (0.03 m) and feature 0 (0.05 m): feature 1 wins it;
    # feature 2 is 0.1 m from keypoint 0: out of radius
    assert associate(kps, feats, 0.06).tolist() == [-1, 1, -1, -1]
    assert associate(np.zeros((0, 2)), feats, 0.06).tolist() == [-1, -1, -1, -1]


def test_pair_distance_std_known_values() -> None:
    features = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [9.0, 9.0]])
    shift = [
        np.array([0.01, -0.02]),
        np.array([-0.02, 0.0]),
        np.array([0.0, 0.01]),
        np.array([0.01, 0.0]),
    ]
    scans = []
    for s in range(4):
        a = features[0] + shift[s]  # features 0 and 1 move together: constant distance
        b = features[1] + shift[s]
        # distance of feature 2 to feature 0: 1 +- 0.05 (all within the 0.06 m radius)
        c = features[2] + np.array([0.0, 0.05 if s % 2 else -0.05]) + shift[s]
        kps = [a, b, c]
        if s == 0:
            kps = [a, b]  # feature 2 missing in scan 0
        scans.append(np.array(kps))
    scans.append(np.array([features[3]]))  # feature 3 alone
    table = observation_table(scans, features, 0.06)
    assert table.shape == (5, 4, 2)
    assert np.isnan(table[0, 2]).all() and np.isfinite(table[4, 3]).all()
    std, together = pair_distance_std(table)
    assert std[0, 1] == pytest.approx(0.0, abs=1e-12)
    # distances 0-2 over scans 1, 2, 3: 1.05, 0.95, 1.05 -> population std 0.0471
    d = np.array([1.05, 0.95, 1.05])
    assert std[0, 2] == pytest.approx(np.std(d), abs=1e-9)
    assert together[0, 1] == 4 and together[0, 2] == 3 and together[0, 3] == 0
    assert math.isnan(std[0, 3]) and math.isnan(std[1, 1])
    np.testing.assert_allclose(std, std.T, equal_nan=True)
    stats = association_stats(std, together, threshold=0.03)
    assert stats.n_pairs == 6
    assert stats.n_pairs_never_together == 3  # every pair with feature 3
    assert stats.n_pairs_with_std == 3
    assert stats.max_std == pytest.approx(np.std(d), abs=1e-9)
    assert stats.share_std_within == pytest.approx(1 / 3)
