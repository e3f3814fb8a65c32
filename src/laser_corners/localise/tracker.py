"""Tracking a fix in the saved map: :class:`Tracker` (the ``tracking`` state of
:class:`~laser_corners.localise.Localiser`).

Odometry predicts, ICP against the map corrects (the odometry noise is the prior), the
covariance is the inverse of the ICP information plus the prior's (with a floor for the map's
own error). A scan agreeing less than ``track_agreement``, with more than ``max_outside`` of its
beams outside the map, or whose last ``conflict_scans`` contradict the map's free space on more
than ``track_conflict`` of the beams on average (the track slid to a look-alike place, or the
robot left the map), gives no estimate; ``lost_scans`` such scans in a row and the track is
lost (:attr:`Tracker.lost`).

The scan is also aligned to a local submap of the recent scans' points that the map does not
explain (:mod:`.local`) and the two alignments are fused by their information: where the robot
drives out of the map the unmapped part of the scan holds the pose (a corridor whose far end is
unmapped cannot drag it back). A scan with more than ``partly_outside`` of its beams outside the
map that agrees with map and local submap together gets a ``"local"`` estimate (chained to the
last anchored pose, covariance growing); once the map explains it again the estimate is
anchored again.
"""

from __future__ import annotations

import math
from collections import deque

import numpy as np
from numpy.typing import NDArray

from laser_corners.localise.estimate import LocaliserEstimate
from laser_corners.localise.local import Fit, LocalMap, fuse
from laser_corners.localise.matcher import MapMatcher
from laser_corners.pose import between_many, compose_many, invert_many, rotate_covariance
from laser_corners.registration.points import ScanPoints, transform

__all__ = ["Tracker"]

COVARIANCE_FLOOR = np.diag([0.02, 0.02, 0.01]) ** 2
"""Added to every covariance: the map's own error (m, m, rad), which ICP does not see."""
RECOVER_DROP = 0.1
"""A tracked scan agreeing this much less than the recent ones (or less than
:data:`RECOVER_BELOW`) triggers a correlative search around the prediction."""
RECOVER_BELOW = 0.6
RECOVER_XY = 0.3
"""Half-width (m) of the recovery search window."""
RECOVER_YAW = 0.3
"""Half-width (rad) of the recovery search window."""
RECOVER_MOVED = 0.05
"""A recovered pose more than this (rad) or ``inlier_distance`` (m) from the tracked one gives an
estimate only when the scan agrees within :data:`RECOVER_DROP` of the recent scans there: on
fr079 (same log) a search moved a track 0.48 m along a corridor onto a pose agreeing 0.75-0.91
(usual 0.99), reported as tracking 0.4-0.7 m off with σ 0.03 m."""
LOCAL_SHARE = 0.05
"""The local submap (``localise.local``) takes part in a tracked scan's pose when it explains
at least this share of the scan's points (else stray clutter would)."""
LOCAL_DRIFT = 0.02
"""Growth of a local estimate's standard deviation per metre travelled (m/m, rad/m; and
rad per radian turned): scan matching chained from the last pose anchored in the map."""
FIX_COVARIANCE = np.diag([0.05, 0.05, 0.02]) ** 2
"""Covariance (m, m, rad) of a fresh fix of the global search."""


class Tracker:
    """The tracked pose, its covariance and the recent scans' agreement (module notes).

    Parameters
    ----------
    matcher : MapMatcher
    local : LocalMap
        The recent scans' points that the map does not explain.
    counts : dict
        The localiser's counters (``no_agreement``, ``recoveries``, ``local``), updated here.
    """

    def __init__(self, matcher: MapMatcher, local: LocalMap, counts: dict[str, int]) -> None:
        opt = matcher.options
        self.matcher = matcher
        self.options = opt
        self.local = local
        self.counts = counts
        self.pose: NDArray[np.float64] | None = None
        """The tracked base pose in the map, None when there is no fix."""
        self.covariance = np.diag([1.0, 1.0, 0.5])
        self.recent: deque[float] = deque(maxlen=opt.recent_scans)
        """Agreements of the recent tracked scans (what the track usually agrees)."""
        self.conflicts: deque[float] = deque(maxlen=opt.conflict_scans)
        self.failed = 0
        """Scans in a row without an estimate."""
        self.since_jump = 0
        """Scans since the last odometry or time jump."""

    @property
    def lost(self) -> bool:
        """``lost_scans`` scans in a row gave no estimate."""
        return self.failed >= self.options.lost_scans

    def start(
        self,
        pose: NDArray,
        covariance: NDArray | None = None,
        recent: list[float] | tuple[float, ...] = (),
    ) -> None:
        """Track from ``pose`` (a fix, or a given initial pose); ``recent``: the agreements
        the new track starts with (its hypothesis's: the usual agreement of the new track,
        not 1.0)."""
        self.pose = np.asarray(pose, dtype=np.float64).reshape(3).copy()
        if covariance is not None:
            self.covariance = np.asarray(covariance, dtype=np.float64).reshape(3, 3)
        self.failed = 0
        self.recent.clear()
        self.recent.extend(recent)
        self.conflicts.clear()
        self.local.clear()

    def follow(self, pose: NDArray) -> None:
        """The scan gave no estimate here, but ``pose`` holds it (the engine, where the map
        does not explain the scan): track on from there, the failure not counted."""
        self.pose = np.asarray(pose, dtype=np.float64).reshape(3).copy()
        self.failed = 0

    def stop(self) -> NDArray[np.float64]:
        """Drop the track; its last (predicted) pose."""
        assert self.pose is not None
        pose, self.pose = self.pose, None
        self.failed = 0
        self.local.clear()
        return pose

    def estimate(
        self, odo: NDArray, index: int, stamp: float, status: str, agreement: float
    ) -> LocaliserEstimate:
        """The estimate of the tracked pose for scan ``index`` (odometry pose ``odo``)."""
        assert self.pose is not None
        return LocaliserEstimate(
            pose=self.pose.copy(),
            covariance=rotate_covariance(self.covariance, float(self.pose[2])),
            status=status,
            map_to_odom=compose_many(self.pose, invert_many(odo)),
            scan_index=index,
            stamp=stamp,
            agreement=float(agreement),
        )

    def step(
        self, pts: ScanPoints, delta: NDArray, jump: bool, odo: NDArray, index: int, stamp: float
    ) -> LocaliserEstimate | None:
        """One tracked scan: the map's and the local submap's alignments fused; an estimate
        anchored in the map, a local one (the scan sees much unmapped space and fits the
        recent scans), or none (counts towards :attr:`lost`)."""
        assert self.pose is not None
        opt = self.options
        self.since_jump = 0 if jump else self.since_jump + 1
        prior = self.matcher.prior(delta, jump)
        pred = compose_many(self.pose, delta)
        fit, moved = self._aligned(pts.xy, pred, prior, jump)
        usual = self.usual
        agreement = fit.explained(opt.partly_outside)
        self.conflicts.append(fit.support.conflict)
        floor = max(opt.track_agreement, usual - opt.track_drop)
        if moved and not jump:  # a pose off the tracked one: only if the scan fits as usual
            floor = max(floor, usual - RECOVER_DROP)
        anchored, unmapped = self._judge(fit, floor, jump)
        if not (anchored or (unmapped and agreement >= floor)):
            self.pose = pred
            self.failed += 1
            self.counts["no_agreement"] += 1
            return None
        self.failed = 0
        self.recent.append(agreement)
        self.pose = fit.pose
        step = math.hypot(delta[0], delta[1])
        self.local.add(fit.pose, pts, step + 0.5 * abs(delta[2]))
        if not anchored:  # chained to the last anchored pose: the covariance grows
            self.counts["local"] += 1
            grow = LOCAL_DRIFT * np.array([step, step, step + abs(delta[2])])
            self.covariance = self.covariance + np.diag(grow**2)
            return self.estimate(odo, index, stamp, "local", agreement)
        try:
            cov = np.linalg.inv(fit.information + prior)
        except np.linalg.LinAlgError:  # pragma: no cover - singular information
            cov = np.linalg.inv(prior)
        self.covariance = cov + COVARIANCE_FLOOR
        return self.estimate(odo, index, stamp, "tracking", agreement)

    @property
    def usual(self) -> float:
        """Mean agreement of the recent tracked scans (1.0 before any)."""
        return float(np.mean(self.recent)) if self.recent else 1.0

    def _aligned(self, xy: NDArray, pred: NDArray, prior: NDArray, jump: bool) -> tuple[Fit, bool]:
        """The fused fit, searched again around the prediction when the scan agrees much less
        than usual (or across a jump); whether the search moved it off the tracked pose."""
        opt = self.options
        fit = self.fused(xy, pred, prior, jump)
        if not (
            jump
            or fit.explained(opt.partly_outside) < max(self.usual - RECOVER_DROP, RECOVER_BELOW)
        ):
            return fit, False
        searched = self.recover(xy, pred, fit)
        step = between_many(fit.pose, searched.pose)
        moved = math.hypot(step[0], step[1]) > opt.inlier_distance or abs(step[2]) > RECOVER_MOVED
        return searched, moved

    def _judge(self, fit: Fit, floor: float, jump: bool) -> tuple[bool, bool]:
        """Whether the fit is anchored in the map, and whether it may be a local estimate."""
        opt = self.options
        support, mapped = fit.support, fit.mapped
        fits = float(np.mean(self.conflicts)) <= opt.track_conflict
        anchored = (
            fits
            and mapped + fit.local >= floor
            and mapped >= opt.hypothesis_agreement
            and support.outside <= opt.max_outside
        )
        unmapped = (  # no map anchor: the free-space test of a hypothesis (recent scans),
            fits
            and fit.unmapped > opt.partly_outside  # and the recent scans explain part of it
            and fit.local >= LOCAL_SHARE
            and support.conflict <= opt.track_conflict
            and float(np.mean(self.conflicts)) <= opt.max_conflict
            and not jump
        )
        return anchored, unmapped

    def fused(self, xy: NDArray, pred: NDArray, prior: NDArray, jump: bool) -> Fit:
        """ICP of the scan to the map and to the local submap (``localise.local``), fused
        by their information when the local submap explains at least ``LOCAL_SHARE`` of
        the scan."""
        aligned, mapped = self.matcher.align(xy, pred, prior)
        local = None if jump else self.local.align(xy, pred, prior, self.options)
        if local is None or local.overlap < LOCAL_SHARE:
            return self.fit(xy, aligned.pose, aligned.information, mapped, 0.0)
        pose, info = fuse(pred, prior, aligned, local)
        mapped = self.matcher.agreement(pose, xy)
        return self.fit(
            xy, pose, info, mapped, self.local.share(xy, pose, self.options.inlier_distance)
        )

    def fit(self, xy: NDArray, pose: NDArray, info: NDArray, mapped: float, local: float) -> Fit:
        """A :class:`Fit` with the free-space support and unmapped share at ``pose``."""
        unmapped = float(np.mean(self.local.unexplained(transform(xy, pose)))) if len(xy) else 0.0
        return Fit(pose, info, mapped, local, self.matcher.support(pose, xy), unmapped)

    def recover(self, xy: NDArray, pred: NDArray, current: Fit) -> Fit:
        """A correlative search around the prediction (wheel slip, a missed turn), then ICP
        from its best pose under a weak prior; kept when more of the scan's points agree
        with the map and the local submap together than at ``current``: judged on the map
        alone, a scan that partly sees unmapped space would be pulled onto the mapped part
        (a corridor's far end). Not on :meth:`Fit.explained`, which leaves out the points
        far from the map and so would favour poses that put more of the scan off the map."""
        self.counts["recoveries"] += 1
        guess = self.matcher.model.local_search(xy, pred, RECOVER_XY, RECOVER_YAW)
        weak = np.diag(1.0 / np.array([RECOVER_XY, RECOVER_XY, RECOVER_YAW]) ** 2)
        again, mapped = self.matcher.align(xy, guess, weak)
        local = self.local.share(xy, again.pose, self.options.inlier_distance)
        fit = self.fit(xy, again.pose, again.information, mapped, local)
        better = fit.mapped + fit.local > current.mapped + current.local
        return fit if better else current
