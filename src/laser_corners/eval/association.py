"""Association distance between persistent features (paper section IV, fig. 5).

Each scan's map-frame keypoints are associated to the persistent features within a radius
(0.06 m in the paper). For every pair of features associated in the same scan, the distance
between the two *keypoints* is recorded; its standard deviation over the scans measures how
consistently the detector places the two corners relative to each other (it is independent of
the map frame, so pose errors common to both cancel).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = [
    "AssociationStats",
    "associate",
    "association_stats",
    "observation_table",
    "order_by_first_seen",
    "pair_distance_std",
]


def associate(keypoints_xy: ArrayLike, features_xy: ArrayLike, radius: float) -> NDArray[np.int64]:
    """Associate keypoints to features one-to-one, nearest pairs first, within ``radius``.

    Parameters
    ----------
    keypoints_xy : array_like, shape (M, 2)
        One scan's keypoints, map frame.
    features_xy : array_like, shape (F, 2)
        Persistent features, map frame.
    radius : float
        Largest keypoint-feature distance, metres.

    Returns
    -------
    ndarray of int64, shape (F,)
        Index of the keypoint associated to each feature, ``-1`` for none.

    Examples
    --------
    >>> associate([[0.0, 0.0], [1.02, 0.0]], [[1.0, 0.0], [5.0, 5.0]], 0.06).tolist()
    [1, -1]
    """
    kp = np.asarray(keypoints_xy, dtype=np.float64).reshape(-1, 2)
    ft = np.asarray(features_xy, dtype=np.float64).reshape(-1, 2)
    out = np.full(ft.shape[0], -1, dtype=np.int64)
    if kp.shape[0] == 0 or ft.shape[0] == 0:
        return out
    dist = np.linalg.norm(ft[:, None, :] - kp[None, :, :], axis=2)
    fi, ki = np.nonzero(dist <= radius)
    order = np.argsort(dist[fi, ki], kind="stable")
    used = np.zeros(kp.shape[0], dtype=bool)
    for f, k in zip(fi[order], ki[order], strict=True):
        if out[f] < 0 and not used[k]:
            out[f] = k
            used[k] = True
    return out


def observation_table(
    keypoints_xy: Sequence[ArrayLike], features_xy: ArrayLike, radius: float
) -> NDArray[np.float64]:
    """Positions of the keypoint associated to each feature in each scan.

    Returns
    -------
    ndarray, shape (S, F, 2)
        Map-frame position of the keypoint associated to feature ``f`` in scan ``s``; NaN
        where the feature was not observed.
    """
    ft = np.asarray(features_xy, dtype=np.float64).reshape(-1, 2)
    table = np.full((len(keypoints_xy), ft.shape[0], 2), np.nan)
    for s, kps in enumerate(keypoints_xy):
        kp = np.asarray(kps, dtype=np.float64).reshape(-1, 2)
        match = associate(kp, ft, radius)
        seen = match >= 0
        table[s, seen] = kp[match[seen]]
    return table


def pair_distance_std(
    observations: ArrayLike,
) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """Standard deviation over scans of the distance between every pair of features.

    Parameters
    ----------
    observations : array_like, shape (S, F, 2)
        As returned by :func:`observation_table` (NaN: not observed).

    Returns
    -------
    std : ndarray, shape (F, F)
        Population standard deviation (ddof 0) of the keypoint-keypoint distance over the
        scans in which both features were observed; NaN when they were seen together in
        fewer than 2 scans, and on the diagonal.
    n_together : ndarray of int64, shape (F, F)
        Scans in which both features were observed (diagonal: scans observing the feature).
    """
    obs = np.asarray(observations, dtype=np.float64)
    n_feat = obs.shape[1]
    std = np.full((n_feat, n_feat), np.nan)
    together = np.zeros((n_feat, n_feat), dtype=np.int64)
    seen = np.all(np.isfinite(obs), axis=2)  # (S, F)
    for f in range(n_feat):
        rows = np.flatnonzero(seen[:, f])  # only the scans that saw f (cost ~ observations)
        sub = obs[rows]
        dist = np.linalg.norm(sub[:, f : f + 1, :] - sub, axis=2)  # (S_f, F), NaN if unseen
        both = seen[rows]
        count = both.sum(axis=0)
        together[f] = count
        ok = count >= 2
        if np.any(ok):
            d = np.where(both, dist, 0.0)
            mean = d.sum(axis=0) / np.maximum(count, 1)
            var = (np.where(both, (dist - mean) ** 2, 0.0)).sum(axis=0) / np.maximum(count, 1)
            std[f, ok] = np.sqrt(var[ok])
    np.fill_diagonal(std, np.nan)
    return std, together


@dataclass(frozen=True)
class AssociationStats:
    """Summary of the pair-distance deviations (what the paper reports for fig. 5).

    Attributes
    ----------
    n_features : int
        Persistent features.
    n_pairs : int
        Feature pairs, ``F (F - 1) / 2``.
    n_pairs_with_std : int
        Pairs seen together in at least 2 scans.
    n_pairs_never_together : int
        Pairs never observed in the same scan.
    max_std : float
        Largest standard deviation (NaN when no pair has one), metres.
    median_std : float
        Median standard deviation, metres.
    share_std_within : float
        Share of the pairs with a standard deviation that is ``<= threshold``.
    threshold : float
        The threshold of ``share_std_within`` (0.03 m in the paper).
    """

    n_features: int
    n_pairs: int
    n_pairs_with_std: int
    n_pairs_never_together: int
    max_std: float
    median_std: float
    share_std_within: float
    threshold: float


def association_stats(
    std: NDArray[np.float64], together: NDArray[np.int64], threshold: float = 0.03
) -> AssociationStats:
    """Summarise :func:`pair_distance_std` over the upper triangle (each pair once)."""
    n_feat = std.shape[0]
    iu = np.triu_indices(n_feat, k=1)
    values = std[iu]
    values = values[np.isfinite(values)]
    n_pairs = len(iu[0])
    return AssociationStats(
        n_features=n_feat,
        n_pairs=n_pairs,
        n_pairs_with_std=int(values.size),
        n_pairs_never_together=int(np.count_nonzero(together[iu] == 0)),
        max_std=float(values.max()) if values.size else float("nan"),
        median_std=float(np.median(values)) if values.size else float("nan"),
        share_std_within=float(np.mean(values <= threshold)) if values.size else float("nan"),
        threshold=float(threshold),
    )


def order_by_first_seen(observations: NDArray[np.float64]) -> NDArray[np.int64]:
    """Feature order by the mean index of the scans that observed each (never seen: last).

    Features seen together get neighbouring numbers, so the pair matrix of
    :func:`pair_distance_std` shows blocks along its diagonal.
    """
    seen = np.all(np.isfinite(observations), axis=2)
    scan_index = np.arange(observations.shape[0], dtype=np.float64)[:, None]
    with np.errstate(invalid="ignore"):
        when = (seen * scan_index).sum(axis=0) / seen.sum(axis=0)
    return np.argsort(np.nan_to_num(when, nan=np.inf), kind="stable")
