"""Persistent features (:mod:`laser_corners.eval.persistent`): peaks of the observability map,
suppression, levels."""

from __future__ import annotations

import numpy as np

from laser_corners.eval.grid import Grid
from laser_corners.eval.observability import ObservabilityMap
from laser_corners.eval.persistent import persistent_features


def test_persistent_features_peaks_nms_and_levels() -> None:
    grid = Grid(0.0, 0.0, 0.03, (50, 50))
    in_view = np.full(grid.shape, 40, dtype=np.int32)
    hits = np.zeros(grid.shape, dtype=np.int32)
    hits[10, 10] = 40  # 100 %
    hits[10, 12] = 36  # 90 %, 0.06 m from the first: suppressed
    hits[30, 30] = 24  # 60 %
    hits[40, 10] = 12  # 30 %
    hits[45, 45] = 5  # 12.5 %: below min_ratio
    in_view_rare = in_view.copy()
    in_view_rare[5, 40] = 2
    hits[5, 40] = 2  # 100 % but seen by 2 scans only
    obs = ObservabilityMap(grid, in_view_rare, hits, in_view_rare, hits, n_scans=40)
    feats = persistent_features(obs, min_ratio=0.25, min_views=20, nms_radius=0.2)
    assert len(feats) == 3
    assert sorted(map(tuple, feats.cells.tolist())) == [(10, 10), (30, 30), (40, 10)]
    assert feats.count_at_least(0.5) == 2
    assert feats.count_at_least(0.75) == 1
    assert feats.count_at_least(1.0) == 1
    np.testing.assert_allclose(feats.xy[0], grid.center_of([[10, 10]])[0])
