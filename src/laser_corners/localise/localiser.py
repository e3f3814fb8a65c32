"""The incremental localiser: :class:`Localiser` (``add(scan, odometry, stamp) -> estimate``).

Three states (:attr:`Localiser.status`):

``global``
    No fix yet. On every scan the map's place index (corner keypoints of the last metres,
    :mod:`.places`) proposes poses; where it has none for ``places.fallback_travel`` (or the
    map has no index), every ``global_every`` scans the exhaustive search over the whole map
    (:meth:`~laser_corners.localise.mapmodel.MapModel.global_search`) does. Each pose becomes
    a hypothesis, refined by ICP against the map's points. Every scan, every hypothesis is
    moved by the odometry step, aligned again (point-to-line ICP,
    :func:`~laser_corners.registration.align.icp`) and scored by its *agreement*: the share of
    the scan's points within ``inlier_distance`` of a map point. Hypotheses whose recent agreement
    falls below ``hypothesis_agreement`` are dropped; two that meet are merged. The fix is
    declared only when one hypothesis has survived ``fix_travel`` metres and ``fix_scans``
    scans, agrees at least ``fix_agreement`` and every other surviving hypothesis agrees less
    by ``fix_margin``: in a symmetric or ambiguous map several hypotheses keep agreeing and no
    fix is given (no estimate is better than a confident wrong one).
    A hypothesis, and the fix, must also not contradict the map's free space (beams ending
    where the map saw free space, or seeing through its walls: :mod:`.freespace`) on more
    than ``max_conflict`` of the beams (what the map is sure of) nor ``max_loose_conflict``
    (any evidence), nor over the history since the search started (the search's past scans
    chained back from the winner by odometry); a winner whose scans partly end outside the map
    needs ``outside_travel`` times the travel.
``tracking``
    Odometry predicts, ICP against the map corrects (the odometry noise is the prior), the
    covariance is the inverse of the ICP information plus the prior's (with a floor for the
    map's own error). A scan agreeing less than ``track_agreement``, with more than
    ``max_outside`` of its beams outside the map, or whose last ``conflict_scans`` contradict
    the map's free space on more than ``track_conflict`` of the beams on average (the track
    slid to a look-alike place, or the robot left the map), gives no estimate.
    The scan is also aligned to a local submap of the recent scans' points that the map
    does not explain (:mod:`.local`) and the two alignments are fused by their information:
    where the robot drives out of the map the unmapped part of the scan holds the pose (a
    corridor whose far end is unmapped cannot drag it back). A scan with more than
    ``partly_outside`` of its beams outside the map that agrees with map and local submap
    together gets a ``"local"`` estimate (chained to the last anchored pose, covariance
    growing); once the map explains it again the estimate is anchored again.
``lost``
    ``lost_scans`` such scans in a row: the fix is dropped and the search starts again; the
    next fix is reported as ``relocalised``. Unless the loss followed an odometry or time
    jump, the search first looks only inside the *window* of the lost track's dead-reckoned
    pose (:mod:`.window`: 3σ of an uncertainty growing with the travel), where a winner needs
    ``reacquire_travel`` instead of ``fix_travel``, is scored among the points the map could
    explain and is not judged on the scans since the loss; once the window is wider than
    ``reacquire_xy`` / ``reacquire_yaw``, the global search over the whole map takes over (a
    kidnapped robot).
"""

from __future__ import annotations

import math
import time
from collections import deque
from collections.abc import Iterator
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike, NDArray

from laser_corners.localise.estimate import Fix, LocaliserEstimate
from laser_corners.localise.freespace import Support
from laser_corners.localise.history import Replayed, SearchHistory
from laser_corners.localise.hypotheses import Hypothesis, choose_winner, merged
from laser_corners.localise.local import Fit, LocalMap, explained_share, fuse
from laser_corners.localise.mapmodel import GLOBAL_SIGMA, MapModel
from laser_corners.localise.options import LocaliseOptions
from laser_corners.localise.places import PlaceProposer
from laser_corners.localise.window import Window
from laser_corners.pose import (
    between_many,
    compose_many,
    invert_many,
    poses_apart,
    rotate_covariance,
)
from laser_corners.registration.align import Alignment, icp, match_share
from laser_corners.registration.points import scan_points, transform
from laser_corners.scan import LaserScan
from laser_corners.slam.mapfile import SavedMap, load_map

__all__ = ["Fix", "Hypothesis", "Localiser", "LocaliserEstimate"]

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
GLOBAL_SPACING = 0.2
"""Spacing (m) of the scan points given to the global search."""
LOCAL_SHARE = 0.05
"""The local submap (``localise.local``) takes part in a tracked scan's pose when it explains
at least this share of the scan's points (else stray clutter would)."""
LOCAL_DRIFT = 0.02
"""Growth of a local estimate's standard deviation per metre travelled (m/m, rad/m; and
rad per radian turned): scan matching chained from the last pose anchored in the map."""


class Localiser:
    """Localisation in a saved map with odometry (see the module notes).

    Parameters
    ----------
    map_data : str, Path or SavedMap
        A map folder written by ``laser-corners slam`` (or one already loaded).
    options : LocaliseOptions, optional
    mount : tuple of float, optional
        Base -> laser transform ``(x, y, yaw)``; default the map's (``options.mount``
        overrides both).

    Raises
    ------
    InputError
        The map folder is missing, incomplete or of another format version.
    """

    def __init__(
        self,
        map_data: str | Path | SavedMap,
        options: LocaliseOptions | None = None,
        mount: ArrayLike | None = None,
    ) -> None:
        self.options = options or LocaliseOptions()
        saved = map_data if isinstance(map_data, SavedMap) else load_map(map_data)
        chosen = self.options.mount if self.options.mount is not None else mount
        self.mount = np.asarray(saved.mount if chosen is None else chosen, float).reshape(3)
        self.map = MapModel(saved, self.options)
        self.places = PlaceProposer(
            saved.places, saved.poses, self.map.grid, self.mount, self.options.places
        )
        """The map's place index: global candidates from corner keypoints (``places``)."""
        self.hypotheses: list[Hypothesis] = []
        self.fixes: list[Fix] = []
        self.counts = {"scans": 0, "estimates": 0, "lost": 0, "searches": 0, "no_agreement": 0}
        self.counts["recoveries"] = 0
        self.counts["refused_free_space"] = 0
        self.counts["refused_history"] = 0
        self.counts["local"] = 0
        self.counts["reacquired"] = 0
        self.counts["place_attempts"] = 0
        self.counts["credited"] = 0
        self.local = LocalMap(self.map.grid, GLOBAL_SIGMA)
        """Recent scans' points the map does not explain (tracking into unmapped space)."""
        self._recent: deque = deque(maxlen=self.options.recent_scans)
        self._conflicts: deque = deque(maxlen=self.options.conflict_scans)
        self.ms_per_scan: list[float] = []
        self.search_ms: list[float] = []
        """Milliseconds of every exhaustive correlative search (global or window)."""
        self.pose: NDArray[np.float64] | None = None
        self._cov = np.diag([1.0, 1.0, 0.5])
        self._searching = "global"
        self._bad = 0
        self._last_odom: NDArray | None = None
        self._last_stamp = -math.inf
        self._since_search = 0
        self._search_travel = 0.0
        self._history = SearchHistory(self.options.history_travel)
        """The current search's past scans (the history check, the credit of new hypotheses)."""
        self.window: Window | None = None
        """The lost track's dead-reckoned pose, searched around while it is narrow enough."""
        self._since_jump = 0

    @property
    def status(self) -> str:
        """``"global"`` (no fix yet), ``"tracking"`` or ``"lost"`` (searching again)."""
        return "tracking" if self.pose is not None else self._searching

    def set_pose(self, pose: ArrayLike, covariance: ArrayLike | None = None) -> None:
        """Start tracking from ``pose`` (base in the map frame), e.g. an initial pose."""
        self.pose = np.asarray(pose, dtype=np.float64).reshape(3).copy()
        if covariance is not None:
            self._cov = np.asarray(covariance, dtype=np.float64).reshape(3, 3)
        self.hypotheses = []
        self.window = None
        self._bad = 0
        self._recent.clear()
        self._conflicts.clear()
        self.local.clear()

    # ------------------------------------------------------------------ per scan
    def add(
        self, scan: LaserScan, odometry_pose: ArrayLike, stamp: float
    ) -> LocaliserEstimate | None:
        """Add one scan with the base's odometry pose at its stamp.

        Returns
        -------
        LocaliserEstimate or None
            None while there is no fix, or when this scan does not agree with the map.
        """
        start = time.perf_counter()
        opt = self.options
        odo = np.asarray(odometry_pose, dtype=np.float64).reshape(3)
        delta = np.zeros(3) if self._last_odom is None else between_many(self._last_odom, odo)
        jump = (
            math.hypot(delta[0], delta[1]) > opt.odometry_jump
            or abs(delta[2]) > opt.odometry_jump
            or abs(stamp - self._last_stamp) > opt.time_jump
        ) and self._last_odom is not None
        self._last_odom, self._last_stamp = odo, float(stamp)
        pts = scan_points(scan, self.mount, opt.min_range, opt.max_range, opt.point_spacing)
        index = self.counts["scans"]
        self.counts["scans"] += 1
        if self.pose is not None:
            estimate = self._track(pts, delta, jump, odo, index, float(stamp))
        else:
            estimate = self._search(scan, pts, delta, jump, odo, index, float(stamp))
        self.ms_per_scan.append((time.perf_counter() - start) * 1e3)
        if estimate is not None:
            self.counts["estimates"] += 1
        return estimate

    def _prior(self, delta: NDArray, jump: bool) -> NDArray:
        """Information of the odometry prediction (a weak one across a jump)."""
        opt = self.options
        if jump:
            return np.diag(1.0 / np.array([1.0, 1.0, 0.5]) ** 2)
        dist = math.hypot(delta[0], delta[1])
        sxy = opt.odometry_sigma_xy * (dist + 0.1)
        syaw = opt.odometry_sigma_yaw * (abs(delta[2]) + dist + 0.1)
        return np.diag(1.0 / np.array([sxy, sxy, syaw]) ** 2)

    def _align(self, xy: NDArray, guess: NDArray, prior: NDArray) -> tuple[Alignment, float]:
        """ICP of ``xy`` against the map from ``guess``, and the agreement of its result."""
        opt = self.options
        aligned = icp(
            xy,
            self.map.lines,
            guess,
            prior,
            max_distance=opt.icp_max_distance,
            inlier_distance=opt.inlier_distance,
            iterations=opt.icp_iterations,
            sigma=opt.match_sigma,
            overlap_map=self.map.every,
        )
        return aligned, aligned.overlap

    def _track(
        self, pts, delta: NDArray, jump: bool, odo: NDArray, index: int, stamp: float
    ) -> LocaliserEstimate | None:
        """One tracked scan: the map's and the local submap's alignments fused; an estimate
        anchored in the map, a local one (the scan sees much unmapped space and fits the
        recent scans), or none (counts towards lost)."""
        assert self.pose is not None
        opt = self.options
        self._since_jump = 0 if jump else self._since_jump + 1
        prior = self._prior(delta, jump)
        pred = compose_many(self.pose, delta)
        fit = self._fused(pts.xy, pred, prior, jump)
        usual = float(np.mean(self._recent)) if self._recent else 1.0
        partly = opt.partly_outside
        moved = False  # the recovery search moved the pose off the tracked one
        if jump or fit.explained(partly) < max(usual - RECOVER_DROP, RECOVER_BELOW):
            searched = self._recover(pts.xy, pred, fit)
            step = between_many(fit.pose, searched.pose)
            moved = (
                math.hypot(step[0], step[1]) > opt.inlier_distance or abs(step[2]) > RECOVER_MOVED
            )
            fit = searched
        pose, support, mapped = fit.pose, fit.support, fit.mapped
        agreement = fit.explained(partly)
        self._conflicts.append(support.conflict)
        floor = max(opt.track_agreement, usual - opt.track_drop)
        if moved and not jump:  # a pose off the tracked one: only if the scan fits as usual
            floor = max(floor, usual - RECOVER_DROP)
        fits = float(np.mean(self._conflicts)) <= opt.track_conflict
        anchored = (
            fits
            and mapped + fit.local >= floor
            and mapped >= opt.hypothesis_agreement
            and support.outside <= opt.max_outside
        )
        unmapped = (  # no map anchor: the free-space test of a hypothesis (recent scans),
            fit.unmapped > partly  # and the recent scans explain part of this one
            and fit.local >= LOCAL_SHARE
            and support.conflict <= opt.track_conflict
            and float(np.mean(self._conflicts)) <= opt.max_conflict
            and not jump
        )
        if not (anchored or (fits and unmapped and agreement >= floor)):
            self.pose = pred
            self._bad += 1
            self.counts["no_agreement"] += 1
            if self._bad >= opt.lost_scans:
                self._lose(index)
            return None
        self._bad = 0
        self._recent.append(agreement)
        self.pose = pose
        step = math.hypot(delta[0], delta[1])
        self.local.add(pose, pts, step + 0.5 * abs(delta[2]))
        if not anchored:  # chained to the last anchored pose: the covariance grows
            self.counts["local"] += 1
            grow = LOCAL_DRIFT * np.array([step, step, step + abs(delta[2])])
            self._cov = self._cov + np.diag(grow**2)
            return self._estimate(odo, index, stamp, "local", agreement)
        try:
            cov = np.linalg.inv(fit.information + prior)
        except np.linalg.LinAlgError:  # pragma: no cover - singular information
            cov = np.linalg.inv(prior)
        self._cov = cov + COVARIANCE_FLOOR
        return self._estimate(odo, index, stamp, "tracking", agreement)

    def _fused(self, xy: NDArray, pred: NDArray, prior: NDArray, jump: bool) -> Fit:
        """ICP of the scan to the map and to the local submap (``localise.local``), fused
        by their information when the local submap explains at least ``LOCAL_SHARE`` of
        the scan."""
        aligned, mapped = self._align(xy, pred, prior)
        local = None if jump else self.local.align(xy, pred, prior, self.options)
        if local is None or local.overlap < LOCAL_SHARE:
            return self._fit(xy, aligned.pose, aligned.information, mapped, 0.0)
        pose, info = fuse(pred, prior, aligned, local)
        inlier = self.options.inlier_distance
        mapped = match_share(xy, self.map.every, pose, inlier)
        return self._fit(xy, pose, info, mapped, self.local.share(xy, pose, inlier))

    def _fit(self, xy: NDArray, pose: NDArray, info: NDArray, mapped: float, local: float) -> Fit:
        """A :class:`Fit` with the free-space support and unmapped share at ``pose``."""
        unmapped = float(np.mean(self.local.unexplained(transform(xy, pose)))) if len(xy) else 0.0
        return Fit(pose, info, mapped, local, self._support(pose, xy), unmapped)

    def _support(self, pose: NDArray, xy: NDArray) -> Support:
        """Outside / conflict shares of the scan ``xy`` at ``pose`` (``freespace``)."""
        return self.map.space.support(pose, xy, self.mount)

    def _fits(self, pose: NDArray, xy: NDArray) -> bool:
        """Whether the scan at ``pose`` neither contradicts the map's free space nor lies
        mostly outside the map (counted in ``refused_free_space`` when not)."""
        s = self._support(pose, xy)
        opt = self.options
        ok = (
            s.conflict <= opt.max_conflict
            and s.loose <= opt.max_loose_conflict
            and s.outside <= opt.max_outside
        )
        self.counts["refused_free_space"] += not ok
        return ok

    def _recover(self, xy: NDArray, pred: NDArray, current: Fit) -> Fit:
        """A correlative search around the prediction (wheel slip, a missed turn), then ICP
        from its best pose under a weak prior; kept when more of the scan's points agree
        with the map and the local submap together than at ``current``: judged on the map
        alone, a scan that partly sees unmapped space would be pulled onto the mapped part
        (a corridor's far end). Not on :meth:`Fit.explained`, which leaves out the points
        far from the map and so would favour poses that put more of the scan off the map."""
        self.counts["recoveries"] += 1
        guess = self.map.local_search(xy, pred, RECOVER_XY, RECOVER_YAW)
        weak = np.diag(1.0 / np.array([RECOVER_XY, RECOVER_XY, RECOVER_YAW]) ** 2)
        again, mapped = self._align(xy, guess, weak)
        local = self.local.share(xy, again.pose, self.options.inlier_distance)
        fit = self._fit(xy, again.pose, again.information, mapped, local)
        better = fit.mapped + fit.local > current.mapped + current.local
        return fit if better else current

    def _estimate(
        self, odo: NDArray, index: int, stamp: float, status: str, agreement: float
    ) -> LocaliserEstimate:
        assert self.pose is not None
        return LocaliserEstimate(
            pose=self.pose.copy(),
            covariance=rotate_covariance(self._cov, float(self.pose[2])),
            status=status,
            map_to_odom=compose_many(self.pose, invert_many(odo)),
            scan_index=index,
            stamp=stamp,
            agreement=float(agreement),
        )

    def _lose(self, index: int) -> None:
        """Drop the fix: back to the global search, with the predicted pose as the first
        hypothesis (a robot that stops agreeing with the map is most often still where the
        odometry says: a look-alike elsewhere must then beat it by ``fix_margin``). Unless the
        loss followed an odometry or time jump, the search stays inside the window of the
        dead-reckoned pose while it is narrow enough (``localise.window``)."""
        assert self.pose is not None
        self.hypotheses = [Hypothesis(self.pose.copy(), index)]
        recent_jump = self._since_jump <= self.options.lost_scans
        self.window = None if recent_jump else Window.from_covariance(self.pose, self._cov)
        self.pose = None
        self._searching = "lost"
        self._bad = 0
        self._since_search = 0
        self._search_travel = 0.0
        self._history.clear()
        self.local.clear()
        self.counts["lost"] += 1

    # ------------------------------------------------------------------ global search
    def _search(
        self, scan, pts, delta: NDArray, jump: bool, odo: NDArray, index: int, stamp: float
    ) -> LocaliserEstimate | None:
        opt = self.options
        if jump:
            self.hypotheses = []
            self._since_search = 0
            self._history.clear()
            self.places.clear()
        self._move_window(delta, jump)
        step = math.hypot(delta[0], delta[1]) + 0.5 * abs(delta[2])
        self._search_travel += step
        self._history.remember(self._search_travel, index, pts.xy, odo)
        self.places.observe(scan, odo)
        self._follow(pts.xy, delta, step)
        self._propose(scan, pts.xy, odo, index)
        self._since_search += 1
        needed = opt.fix_travel if self.window is None else opt.reacquire_travel
        winner = choose_winner(self.hypotheses, opt, needed)
        # inside the window the winner continues the lost track by odometry: the scans since
        # the loss are those that did not fit the map (a blocked view, a closed door), and
        # judging it on them would refuse every right fix there
        history = self.window is None
        if winner is not None and history and not self._history_fits(winner, odo):
            self.hypotheses.remove(winner)
            self.counts["refused_history"] += 1
            winner = None
        if winner is None:
            return None
        self.pose = winner.pose.copy()
        self.hypotheses = []
        self._conflicts.clear()
        self._recent.clear()  # the usual agreement of the new track: its hypothesis's, not 1.0
        self._recent.extend(winner.recent)
        self.local.clear()
        windowed = self.window is not None
        self.counts["reacquired"] += windowed
        self.window = None
        pose = tuple(winner.pose.tolist())
        self.fixes.append(Fix(index, stamp, self._search_travel, pose, windowed))
        self._cov = np.diag([0.05, 0.05, 0.02]) ** 2
        agreement = winner.recent[-1]
        return self._estimate(odo, index, stamp, "relocalised", agreement)

    def _move_window(self, delta: NDArray, jump: bool) -> None:
        """Move the lost track's window by the odometry step; close it (global search from
        now on) across a jump or once it is wider than ``reacquire_xy`` / ``reacquire_yaw``."""
        if self.window is None:
            return
        opt = self.options
        self.window.move(delta, opt.odometry_sigma_xy, opt.odometry_sigma_yaw)
        if jump or not self.window.open(opt.reacquire_xy, opt.reacquire_yaw):
            self.window = None
            for h in self.hypotheses:  # scored from now on as the global search scores
                h.recent.clear()

    def _agreement(self, xy: NDArray, pose: NDArray, mapped: float) -> float:
        """A hypothesis's agreement: ``mapped`` (the share of the scan's points near a map
        point); inside a lost track's window, where the robot often sees space the map does
        not cover, the share among the points the map could explain when more than
        ``partly_outside`` of them are far from every map point, as a tracked scan is
        judged (``Fit.explained``). The global search keeps the plain share: among the
        explainable points only, a look-alike that puts the scan off the map would gain."""
        if self.window is None or len(xy) == 0:
            return mapped
        unmapped = float(np.mean(self.local.unexplained(transform(xy, pose))))
        return explained_share(mapped, 0.0, unmapped, self.options.partly_outside)

    def _follow(self, xy: NDArray, delta: NDArray, step: float) -> None:
        """Move every hypothesis by the odometry step, align it, score it, prune, merge."""
        opt = self.options
        prior = self._prior(delta, False)
        for h in self.hypotheses:
            aligned, agreement = self._align(xy, compose_many(h.pose, delta), prior)
            h.pose = aligned.pose
            h.remember(
                self._agreement(xy, h.pose, agreement), self._support(h.pose, xy), opt.recent_scans
            )
            h.travel += step
            h.followed += step
            h.scans += 1
        alive = [
            h
            for h in self.hypotheses
            if h.score() >= opt.hypothesis_agreement
            and np.mean(h.conflict) <= opt.max_conflict
            and np.mean(h.loose) <= opt.max_loose_conflict
            and (self.window is None or self.window.contains(h.pose))
        ]
        self.hypotheses = merged(alive, self.options)

    def _history_fits(self, winner: Hypothesis, odo: NDArray) -> bool:
        """Whether the search's past scans, chained back from ``winner`` by odometry (each
        aligned to the map under the odometry prior), never contradict the map's free space
        on more than ``track_conflict`` of the beams over ``conflict_scans`` kept scans: what
        tracking would have required had the winner been followed from the search's start.
        A look-alike of an unmapped place often fits the map only from where the robot is
        now (issue 20, later visit). The check stops at the first past scan that lies
        mostly outside the map (more than ``max_outside``): before it the chain is dead
        reckoning through unknown space. The threshold is tracking's, not the fix's: a right
        fix of aces' later visit had 2 m of its history at 0.22-0.29 (agreeing 0.84-0.94:
        the building had changed)."""
        opt = self.options
        conflicts: list[float] = []
        for past in self._replay(winner.pose, odo):
            if past.support.outside > opt.max_outside:
                break  # the robot came from outside the map: further back is dead reckoning
            conflicts.append(past.support.conflict)
        if not conflicts:
            return True
        n = min(len(conflicts), opt.conflict_scans)  # fewer scans: their mean
        window = np.convolve(conflicts, np.ones(n) / n, "valid")
        return float(window.max()) <= opt.track_conflict

    def _replay(self, pose: NDArray, odo: NDArray, before: int | None = None) -> Iterator[Replayed]:
        """The search's past scans chained back from ``pose`` (``localise.history``)."""
        return self._history.replay(
            pose,
            odo,
            self._align,
            lambda delta: self._prior(delta, False),
            self._support,
            self.options.hypothesis_agreement,
            before,
        )

    def _credit(self, h: Hypothesis, odo: NDArray, index: int) -> None:
        """Credit a new hypothesis of the global search with the past scans it explains
        (newest first, up to ``fix_travel`` back, stopping at the first that agrees less
        than ``hypothesis_agreement`` or that contradicts the map's free space as a
        hypothesis may not): their agreements and shares join its recent ones, their travel
        and scans its own (``localise.history``)."""
        opt = self.options
        credited = []
        for past in self._replay(h.pose, odo, before=index):
            s = past.support
            if (
                past.agreement < opt.hypothesis_agreement
                or s.conflict > opt.max_conflict
                or s.loose > opt.max_loose_conflict
                or s.outside > opt.max_outside
            ):
                break
            credited.append(past)
            if self._search_travel - past.scan.travel >= opt.fix_travel:
                break
        if not credited:
            return
        for past in reversed(credited):
            agreement = self._agreement(past.scan.xy, past.pose, past.agreement)
            h.remember(agreement, past.support, opt.recent_scans)
        h.travel = self._search_travel - credited[-1].scan.travel
        h.scans = index - credited[-1].scan.index
        self.counts["credited"] += 1

    def _propose(self, scan: LaserScan, xy: NDArray, odo: NDArray, index: int) -> None:
        """New hypotheses: on every scan the place index's candidates (corner keypoints,
        ``localise.places``) when the map has an index and no lost track's window is open;
        every ``global_every`` scans the exhaustive correlative search (the whole map, or
        the window after a lost track) when there is no index, or inside a window, or once
        the search has travelled ``places.fallback_travel`` with no hypothesis alive (too few
        corners where the robot is)."""
        opt = self.options
        keypoints = self.window is None and self.places.usable
        due = self._since_search % opt.global_every == 0
        if not (keypoints or due):
            return
        coarse = scan_points(scan, self.mount, opt.min_range, opt.max_range, GLOBAL_SPACING)
        if keypoints:
            found = self.places.propose(coarse.xy)
            self.counts["place_attempts"] += 1
            self._spawn([c.pose for c in found], xy, odo, index)
        fallback = not keypoints or (
            self._search_travel >= opt.places.fallback_travel and not self.hypotheses
        )
        if fallback and due:
            self.counts["searches"] += 1
            start = time.perf_counter()
            if self.window is None:
                found = self.map.global_search(
                    coarse.xy, opt.global_yaw_step, opt.global_candidates
                )
            else:
                found = self.map.window_search(
                    coarse.xy,
                    self.window.pose,
                    *self.window.half_widths,
                    opt.global_yaw_step,
                    opt.global_candidates,
                    (opt.distinct_xy, opt.distinct_yaw),
                )
            self.search_ms.append((time.perf_counter() - start) * 1e3)
            self._spawn([guess for guess, _ in found], xy, odo, index)

    def _spawn(self, guesses: list[NDArray], xy: NDArray, odo: NDArray, index: int) -> None:
        """Hypotheses from the guesses that ICP aligns to agree with the map without
        contradicting its free space; guesses where a hypothesis already is are skipped. Those
        of the global search are credited with the past scans they explain (``_credit``)."""
        opt = self.options
        prior = np.diag(1.0 / np.array([1.0, 1.0, 0.3]) ** 2)
        fresh = []
        for guess in guesses:
            apart = (opt.distinct_xy, opt.distinct_yaw)
            if any(not poses_apart(guess, h.pose, *apart) for h in self.hypotheses):
                continue
            aligned, agreement = self._align(xy, guess, prior)
            if agreement >= opt.hypothesis_agreement and self._fits(aligned.pose, xy):
                h = Hypothesis(aligned.pose, index)
                if self.window is None:
                    self._credit(h, odo, index)
                agreement = self._agreement(xy, h.pose, agreement)
                h.remember(agreement, self._support(h.pose, xy), opt.recent_scans)
                fresh.append(h)
        self.hypotheses = merged(self.hypotheses + fresh, opt)
