"""Pair scorers of the place-recognition evaluation: one query against many candidate scans.

:func:`make_scorer` describes every scan once and returns ``score(query, candidates)``, which
registers the query against all candidates in one numba call and returns, per candidate, the
inliers and the query's sensor pose in the candidate's sensor frame. Two matchers:

* ``local`` (default): :mod:`laser_corners.eval.loop_descriptors` and
  :mod:`laser_corners.eval.loop_match` (shape context, k-nearest matches, exhaustive two-point
  hypotheses with orientation and opening-angle checks);
* ``matching``: :mod:`laser_corners.matching` (``csc`` descriptors, ``register_many``: RANSAC
  and covariance-weighted least squares), with ``min_inliers`` = the smallest swept threshold.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np
from numpy.typing import NDArray

from laser_corners.errors import InvalidParamsError
from laser_corners.eval.loop_descriptors import build_bank
from laser_corners.eval.loop_match import MatchOptions, score_pairs
from laser_corners.keypoints import Keypoints
from laser_corners.scan import LaserScan

__all__ = ["MATCHERS", "Scorer", "make_scorer"]

MATCHERS: tuple[str, ...] = ("local", "matching")
"""Names of the pair scorers."""

Scorer = Callable[
    [NDArray[np.int64], NDArray[np.int64]],
    tuple[NDArray[np.int64], NDArray[np.float64], NDArray[np.float64]],
]
"""``score(queries, candidates) -> (inliers, poses, rms)`` over pairs ``k`` (the pairs of one
query contiguous); ``poses[k]`` is the query's sensor pose in the candidate's sensor frame,
``rms`` breaks ties between equal inlier counts."""


def make_scorer(
    matcher: str,
    scans: Sequence[LaserScan],
    keypoints: Sequence[Keypoints],
    options: MatchOptions,
    min_inliers: int = 2,
) -> Scorer:
    """Describe every scan once and return the batch scorer of ``matcher``.

    Raises
    ------
    InvalidParamsError
        An unknown matcher name.
    """
    if matcher == "local":
        bank = build_bank(scans, keypoints)

        def local(q: NDArray[np.int64], cand: NDArray[np.int64]) -> tuple[NDArray[np.int64], ...]:
            return score_pairs(bank, q, cand, options)

        return local  # type: ignore[return-value]
    if matcher == "matching":
        return _matching_scorer(scans, keypoints, min_inliers)
    raise InvalidParamsError(f"unknown matcher {matcher!r}; known: {', '.join(MATCHERS)}")


def _matching_scorer(
    scans: Sequence[LaserScan], keypoints: Sequence[Keypoints], min_inliers: int
) -> Scorer:
    from laser_corners.matching import KeypointBank, describe, register_many
    from laser_corners.matching import MatchOptions as RegistrationOptions

    desc = [describe(s, k, "csc") for s, k in zip(scans, keypoints, strict=True)]
    bank = KeypointBank.from_lists(keypoints, desc)
    opt = RegistrationOptions(min_inliers=max(2, int(min_inliers)))

    def score(q: NDArray[np.int64], cand: NDArray[np.int64]) -> tuple[NDArray[np.int64], ...]:
        inliers = np.zeros(len(cand), dtype=np.int64)
        rel = np.zeros((len(cand), 3))
        starts = np.flatnonzero(np.r_[True, q[1:] != q[:-1]]) if len(q) else np.zeros(0, int)
        for lo, hi in zip(starts, [*starts[1:], len(q)], strict=True):
            r = register_many(keypoints[q[lo]], desc[q[lo]], bank, cand[lo:hi], opt)
            inliers[lo:hi] = np.where(r.accepted, r.n_inliers, 0)
            rel[lo:hi] = r.poses
        # r.poses: the candidate in the query's frame; invert to the query in the candidate's
        x, y, th = rel[:, 0], rel[:, 1], rel[:, 2]
        c, s = np.cos(th), np.sin(th)
        poses = np.stack([-c * x - s * y, s * x - c * y, -th], axis=1)
        return inliers, poses, np.zeros(len(cand))

    return score  # type: ignore[return-value]
