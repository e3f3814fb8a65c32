"""Persistent features: peaks of the N8 observability map (paper section IV)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.spatial import cKDTree

from laser_corners.eval.observability import ObservabilityMap

__all__ = ["PersistentFeatures", "persistent_features", "refine_positions", "take"]


@dataclass(frozen=True)
class PersistentFeatures:
    """Automatically selected persistent features (peaks of the N8 observability).

    Attributes
    ----------
    xy : ndarray, shape (F, 2)
        Map-frame positions (cell centres, refined by :func:`refine_positions` when used).
    ratio_n8 : ndarray, shape (F,)
        N8 observability of each feature's cell.
    in_view_n8 : ndarray of int, shape (F,)
        Scans in which each feature's cell was in view.
    cells : ndarray of int, shape (F, 2)
        ``(row, col)`` of each feature's cell.
    """

    xy: NDArray[np.float64]
    ratio_n8: NDArray[np.float64]
    in_view_n8: NDArray[np.int64]
    cells: NDArray[np.int64]

    def __len__(self) -> int:
        return int(self.xy.shape[0])

    def count_at_least(self, ratio: float) -> int:
        """Number of features whose N8 observability is ``>= ratio``."""
        return int(np.count_nonzero(self.ratio_n8 >= ratio - 1e-12))


def persistent_features(
    obs: ObservabilityMap,
    min_ratio: float = 0.25,
    min_views: int = 20,
    nms_radius: float = 0.2,
) -> PersistentFeatures:
    """Pick persistent features: peaks of the N8 observability with non-maximum suppression.

    A cell is a candidate when its N8 observability is at least ``min_ratio`` and it was in
    view in at least ``min_views`` scans. Candidates are taken greedily, best first (higher
    N8 ratio, then more views, then more hits in the cell itself), and every candidate within
    ``nms_radius`` of an accepted one is dropped.

    Parameters
    ----------
    obs : ObservabilityMap
        The map.
    min_ratio : float
        Lowest N8 observability of a persistent feature, in [0, 1].
    min_views : int
        Fewest scans that must have seen the cell (a cell seen once with a hit is not
        persistent).
    nms_radius : float
        Suppression radius, metres.

    Returns
    -------
    PersistentFeatures
    """
    ratio = np.nan_to_num(obs.ratio_n8, nan=0.0)
    ok = (ratio >= min_ratio) & (obs.in_view_n8 >= min_views) & (obs.hits_n8 > 0)
    rows, cols = np.nonzero(ok)
    cand_ratio = ratio[rows, cols]
    cand_views = obs.in_view_n8[rows, cols]
    cand_hits = obs.hits[rows, cols]
    order = np.lexsort((-cand_hits, -cand_views, -cand_ratio))
    cells = np.stack([rows, cols], axis=1)[order]
    centers = obs.grid.center_of(cells)
    keep = np.ones(len(cells), dtype=bool)
    if len(cells):
        tree = cKDTree(centers)
        for i in range(len(cells)):
            if not keep[i]:
                continue
            for j in tree.query_ball_point(centers[i], nms_radius):
                if j > i:
                    keep[j] = False
    cells = cells[keep]
    return PersistentFeatures(
        xy=centers[keep],
        ratio_n8=ratio[cells[:, 0], cells[:, 1]],
        in_view_n8=obs.in_view_n8[cells[:, 0], cells[:, 1]].astype(np.int64),
        cells=cells.astype(np.int64),
    )


def refine_positions(
    features: PersistentFeatures, keypoints_xy: NDArray[np.float64], radius: float
) -> PersistentFeatures:
    """Move each feature to the mean of the map-frame keypoints within ``radius`` of it.

    ``keypoints_xy`` (shape (M, 2)) holds all scans' map-frame keypoints stacked; features
    with no keypoint nearby keep their cell centre.
    """
    if len(features) == 0 or len(keypoints_xy) == 0:
        return features
    tree = cKDTree(keypoints_xy)
    xy = features.xy.copy()
    for i, near in enumerate(tree.query_ball_point(features.xy, radius)):
        if near:
            xy[i] = keypoints_xy[near].mean(axis=0)
    return PersistentFeatures(xy, features.ratio_n8, features.in_view_n8, features.cells)


def take(features: PersistentFeatures, index: NDArray[np.int64]) -> PersistentFeatures:
    """The features at ``index`` (an index array or a boolean mask), in that order."""
    return PersistentFeatures(
        features.xy[index],
        features.ratio_n8[index],
        features.in_view_n8[index],
        features.cells[index],
    )
