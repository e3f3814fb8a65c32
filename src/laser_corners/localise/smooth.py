"""The smoothed trajectory of a recording: the localiser's anchors on the SLAM front end's chain.

The localiser (:class:`~laser_corners.localise.Localiser`) is causal: each scan gets the pose
the map gives it then, or none (the robot outside the map, or not found yet). Over a recording
every scan can be placed better, in one pose graph (gtsam, Levenberg-Marquardt):

* **the chain**: the same scans run through :class:`~laser_corners.slam.Slam` (its front end,
  its loop closures, its scan pass), a trajectory that is accurate relative to itself (scan to
  scan, and across its own loops) but in a frame of its own and free to drift. Its step between
  two consecutive scans is a between factor, noise ``smooth.step_xy`` / ``smooth.step_yaw``
  plus ``smooth.drift`` per metre travelled (and per radian turned); its accepted loop
  closures are between factors too (``loop.sigma_*`` of its options). Where the SLAM cut its
  graph (a gap its alignment did not bridge, a kidnap) the chain is cut.
* **the anchors**: the localiser's estimates anchored in the map (``tracking`` and
  ``relocalised``; not the ``local`` ones, which are chained to the last anchor), each a prior
  on its scan's pose with its covariance. One anchor per ``smooth.anchor_travel`` metres of
  travel: consecutive scans see the same part of the map and share its error, so a
  per-scan anchor would count the map's error once per scan (on aces' later visit, where the
  half map bends away from the second half's own loops, per-scan anchors give a relation
  error 1.7x the full-log SLAM's, one per 0.4 m 1.3x).

Every factor is under the Huber kernel of the SLAM's loop closures: a step of the chain that
the anchors on both sides contradict by metres (the SLAM tracked a kidnap through) pulls with
a bounded force. A chain segment with no anchor has no place in the map: its scans are left
out. Every other scan is placed, those before the first fix too (in hindsight: the chain ties
them to the anchors after it), each using every scan of the recording, before and after it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from laser_corners.localise.localiser import LocaliserEstimate
from laser_corners.localise.options import LocaliseOptions
from laser_corners.pose import between_many, compose_many, rotate_covariance
from laser_corners.registration.graph import X, diagonal_noise, require_gtsam, robust_noise
from laser_corners.slam.result import SlamResult

__all__ = ["Smoothed", "smooth"]


@dataclass
class Smoothed:
    """What :func:`smooth` gives.

    Attributes
    ----------
    index : ndarray of int, shape (S,)
        Indices (into the scans given to both the localiser and the SLAM) of the scans placed,
        increasing: every scan of a chain segment with an anchor.
    poses : ndarray, shape (S, 3)
        Their base poses in the map frame.
    stamps : ndarray, shape (S,)
    anchors : int
        Localiser estimates used as anchors.
    closures : int
        The SLAM's accepted loop closures used.
    segments_dropped : int
        Chain segments left out: no anchor in them.
    """

    index: NDArray[np.int64]
    poses: NDArray[np.float64]
    stamps: NDArray[np.float64]
    anchors: int = 0
    closures: int = 0
    segments_dropped: int = 0


def _segments(n: int, cuts: NDArray[np.int64]) -> NDArray[np.int64]:
    """Segment label of each of ``n`` scans; a cut at scan ``i`` starts a new one there."""
    starts = np.zeros(n, dtype=np.int64)
    cuts = np.asarray(cuts, dtype=np.int64)
    starts[cuts[(cuts > 0) & (cuts < n)]] = 1
    return np.cumsum(starts)


def _anchors(
    estimates: list[LocaliserEstimate], index: NDArray[np.int64], travel: NDArray, spacing: float
) -> list[tuple[int, LocaliserEstimate]]:
    """``(scan, estimate)`` of the anchored estimates, one per ``spacing`` of chain travel."""
    kept: list[tuple[int, LocaliserEstimate]] = []
    last = -math.inf
    for i, estimate in zip(index.tolist(), estimates, strict=True):
        if i >= len(travel):  # a scan the SLAM did not get (stopped between the two)
            break
        if estimate.status == "local" or travel[i] - last < spacing:
            continue
        kept.append((i, estimate))
        last = travel[i]
    return kept


def _initial(
    chain: NDArray, segment: NDArray, at: NDArray[np.int64], pose: NDArray[np.float64]
) -> NDArray[np.float64]:
    """Initial poses: each scan placed by the chain from the nearest anchor (scans ``at``,
    poses ``pose``) of its segment."""
    init = np.full_like(chain, np.nan)
    for s in np.unique(segment[at]):
        scans = np.flatnonzero(segment == s)
        own = at[segment[at] == s]
        after = np.clip(np.searchsorted(own, scans), 0, len(own) - 1)
        before = np.clip(after - 1, 0, len(own) - 1)
        nearer = np.where(abs(own[before] - scans) < abs(own[after] - scans), before, after)
        k = np.searchsorted(at, own[nearer])
        init[scans] = compose_many(pose[k], between_many(chain[at[k]], chain[scans]))
    return init


def smooth(
    estimates: list[LocaliserEstimate],
    index: NDArray[np.int64],
    slam: SlamResult,
    options: LocaliseOptions | None = None,
) -> Smoothed:
    """The smoothed trajectory (see the module notes).

    Parameters
    ----------
    estimates : list of LocaliserEstimate
        The localiser's estimates, in order.
    index : array of int
        Index of each estimate's scan among the scans given (``len(estimates)`` values).
    slam : SlamResult
        :class:`~laser_corners.slam.Slam` run over the same scans (``slam.poses`` one per scan).
    options : LocaliseOptions, optional

    Returns
    -------
    Smoothed
        Empty when no estimate is anchored in the map.
    """
    require_gtsam()
    import gtsam

    opt = options or LocaliseOptions()
    chain = np.asarray(slam.poses, dtype=np.float64).reshape(-1, 3)
    index = np.asarray(index, dtype=np.int64)
    steps = between_many(chain[:-1], chain[1:])
    travel = np.r_[0.0, np.cumsum(np.hypot(steps[:, 0], steps[:, 1]) + 0.5 * abs(steps[:, 2]))]
    anchors = _anchors(estimates, index, travel, opt.smooth.anchor_travel)
    if not anchors:
        return Smoothed(np.zeros(0, dtype=np.int64), np.zeros((0, 3)), np.zeros(0))
    at = np.array([i for i, _ in anchors], dtype=np.int64)
    segment = _segments(len(chain), slam.cuts)
    anchored = np.isin(segment, segment[at])
    graph = gtsam.NonlinearFactorGraph()
    _chain_factors(graph, steps, segment, anchored, opt)
    closures = _closure_factors(graph, slam, anchored)
    for i, estimate in anchors:
        graph.add(_anchor_factor(i, estimate))
    values = gtsam.Values()
    init = _initial(chain, segment, at, np.array([e.pose for _, e in anchors], dtype=np.float64))
    keep = np.flatnonzero(anchored)
    for i in keep:
        values.insert(X(int(i)), gtsam.Pose2(*map(float, init[i])))
    params = gtsam.LevenbergMarquardtParams()
    params.setMaxIterations(100)
    result = gtsam.LevenbergMarquardtOptimizer(graph, values, params).optimize()
    poses = np.array([[*_xyt(result.atPose2(X(int(i))))] for i in keep]).reshape(-1, 3)
    dropped = len(np.setdiff1d(np.unique(segment), segment[at]))
    return Smoothed(keep, poses, slam.stamps[keep], len(anchors), closures, dropped)


def _xyt(pose: object) -> tuple[float, float, float]:
    return pose.x(), pose.y(), pose.theta()  # type: ignore[attr-defined]


def _chain_factors(graph, steps, segment, anchored, opt: LocaliseOptions) -> None:
    """A between factor per step of the chain inside an anchored segment."""
    import gtsam

    dist = np.hypot(steps[:, 0], steps[:, 1])
    sxy = opt.smooth.step_xy + opt.smooth.drift * dist
    syaw = opt.smooth.step_yaw + 0.5 * opt.smooth.drift * (dist + np.abs(steps[:, 2]))
    same = (segment[:-1] == segment[1:]) & anchored[:-1]
    for k in np.flatnonzero(same):
        noise = robust_noise(diagonal_noise(sxy[k], sxy[k], syaw[k]))
        step = gtsam.Pose2(*map(float, steps[k]))
        graph.add(gtsam.BetweenFactorPose2(X(int(k)), X(int(k + 1)), step, noise))


def _closure_factors(graph, slam: SlamResult, anchored: NDArray) -> int:
    """The SLAM's accepted loop closures between anchored scans (its loop noise, robust)."""
    import gtsam

    so = slam.options
    noise = robust_noise(diagonal_noise(so.loop.sigma_xy, so.loop.sigma_xy, so.loop.sigma_yaw))
    used = 0
    for closure in slam.closures:
        if not closure.accepted:
            continue
        a, b = int(slam.keyframes[closure.match]), int(slam.keyframes[closure.query])
        if anchored[a] and anchored[b]:
            rel = gtsam.Pose2(*map(float, closure.relative))
            graph.add(gtsam.BetweenFactorPose2(X(a), X(b), rel, noise))
            used += 1
    return used


def _anchor_factor(i: int, estimate: LocaliserEstimate) -> object:
    """A prior on scan ``i``'s pose: the estimate with its covariance (map frame, turned
    into the pose's own frame as gtsam's ``Pose2`` prior wants it), robust."""
    import gtsam

    cov = rotate_covariance(estimate.covariance, -float(estimate.pose[2]))
    noise = robust_noise(gtsam.noiseModel.Gaussian.Covariance(0.5 * (cov + cov.T)))
    return gtsam.PriorFactorPose2(X(i), gtsam.Pose2(*map(float, estimate.pose)), noise)
