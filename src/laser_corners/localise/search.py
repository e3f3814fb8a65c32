"""Looking for a fix in the saved map: :class:`GlobalSearch` (the ``global`` and ``lost``
states of :class:`~laser_corners.localise.Localiser`).

On every scan the map's place index (corner keypoints of the last metres, :mod:`.places`)
proposes poses; where it has none for ``places.fallback_travel`` (or the map has no index),
at most every ``global_every`` scans (the first as soon as it is needed) the exhaustive
search over the whole map
(:meth:`~laser_corners.localise.mapmodel.MapModel.global_slices`) starts, run in slices of
``SLICE_NODES`` nodes a scan so that no scan waits on it; its answers come best first, each
judged on the scan searched and carried to the current one by the odometry. Each pose becomes a
hypothesis (``localise.hypotheses``), refined by ICP against the map's points and credited with
the search's past scans it explains (``localise.history``). Every scan, every hypothesis is
moved by the odometry step, aligned again and scored by its *agreement* (the share of the
scan the map could have seen, :func:`~laser_corners.localise.hypotheses.seen_share`: a pose
at the map's frontier is judged on the part of its scan the map saw); the winner
(:func:`~laser_corners.localise.hypotheses.choose_winner`) must also not contradict the map's
free space over the search's past scans chained back from it.

After a lost track (not across an odometry or time jump) the search first looks only inside the
*window* of the lost track's dead-reckoned pose (:mod:`.window`), with the exhaustive search
restricted to it; a winner there needs ``reacquire_travel`` and is scored among the points the
map could explain; once the window is wider than ``reacquire_xy`` / ``reacquire_yaw`` the global
search over the whole map takes over (a kidnapped robot).
"""

from __future__ import annotations

import math
import time
from collections import deque

import numpy as np
from numpy.typing import NDArray

from laser_corners.localise.estimate import timing_record
from laser_corners.localise.freespace import Support
from laser_corners.localise.history import SearchHistory
from laser_corners.localise.hypotheses import Hypothesis, choose_winner, merged, seen_share
from laser_corners.localise.local import LocalMap, explained_share
from laser_corners.localise.mapmodel import MapModel
from laser_corners.localise.matcher import MapMatcher
from laser_corners.localise.options import LocaliseOptions
from laser_corners.localise.places import PlaceProposer
from laser_corners.localise.window import Window
from laser_corners.pose import compose_many, poses_apart
from laser_corners.registration.global_search import SLICE_NODES, SlicedSearch, carried
from laser_corners.registration.points import ScanPoints, scan_points, transform
from laser_corners.scan import LaserScan

__all__ = ["GLOBAL_SPACING", "GlobalSearch", "exhaustive_search"]

GLOBAL_SPACING = 0.2
"""Spacing (m) of the scan points given to the global search."""
SPAWN_SIGMA = np.array([1.0, 1.0, 0.3])
"""Standard deviations (m, m, rad) of the prior of a proposed pose's first ICP."""


class GlobalSearch:
    """Hypotheses followed by odometry until one wins (see the module notes).

    Parameters
    ----------
    matcher : MapMatcher
    places : PlaceProposer
        The map's place index.
    local : LocalMap
        Tells the scan points the map does not explain (the window's agreement).
    counts : dict
        The localiser's counters (``searches``, ``search_slices``, ``place_attempts``,
        ``credited``, ``refused_free_space``, ``refused_history``), updated here.
    """

    def __init__(
        self, matcher: MapMatcher, places: PlaceProposer, local: LocalMap, counts: dict[str, int]
    ) -> None:
        self.matcher = matcher
        self.options = matcher.options
        self.places = places
        self.local = local
        self.counts = counts
        self.hypotheses: list[Hypothesis] = []
        self.window: Window | None = None
        """The lost track's dead-reckoned pose, searched around while it is narrow enough."""
        self.history = SearchHistory(self.options.history_travel)
        self.travel = 0.0
        """Odometry travel (m, turns 0.5 m per radian) of the search so far."""
        self.scans = 0
        self.started: int | None = None
        """The search's scan count when the last exhaustive search started (None: none yet)."""
        self.search_ms: deque[float] = timing_record()
        """Milliseconds of the last 10,000 (``TIMINGS_KEPT``) exhaustive search slices, global
        or window: what each cost a scan (how many ran: ``counts["search_slices"]``)."""
        self.slice_nodes = SLICE_NODES
        """Nodes of the running exhaustive search spent per scan (:class:`SlicedSearch`)."""
        self.running: tuple[SlicedSearch, tuple, int] | None = None
        """The exhaustive search under way, the scan it searches (odometry, points, index,
        the search's travel) and how many of its answers are hypotheses already."""

    def restart(self, pose: NDArray | None, index: int, window: Window | None) -> None:
        """A new search: from the lost track's predicted ``pose`` as the first hypothesis (a
        robot that stops agreeing with the map is most often still where the odometry says:
        a look-alike elsewhere must then beat it by ``fix_margin``), inside ``window`` if
        given."""
        self.hypotheses = [] if pose is None else [Hypothesis(np.asarray(pose).copy(), index)]
        self.window = window
        self.running = None
        self.scans = 0
        self.started = None
        self.travel = 0.0
        self.history.clear()

    def stop(self) -> None:
        """The search is over (a fix, or a pose given from outside)."""
        self.hypotheses = []
        self.window = None
        self.running = None

    def step(
        self, scan: LaserScan, pts: ScanPoints, delta: NDArray, jump: bool, odo: NDArray, index: int
    ) -> Hypothesis | None:
        """Follow the hypotheses by one scan, propose new ones; the winner, if one wins."""
        opt = self.options
        if jump:
            self.hypotheses = []
            self.running = None
            self.scans = 0
            self.started = None
            self.history.clear()
            self.places.clear()
        self._move_window(delta, jump)
        step = math.hypot(delta[0], delta[1]) + 0.5 * abs(delta[2])
        self.travel += step
        self.history.remember(self.travel, index, pts.xy, odo)
        self.places.observe(scan, odo)
        self._follow(pts.xy, delta, step)
        self._propose(scan, pts.xy, odo, index)
        self.scans += 1
        needed = opt.fix_travel if self.window is None else opt.reacquire_travel
        winner = choose_winner(self.hypotheses, opt, needed)
        # inside the window the winner continues the lost track by odometry: the scans since
        # the loss are those that did not fit the map (a blocked view, a closed door), and
        # judging it on them would refuse every right fix there
        if winner is not None and self.window is None:
            if not self.history.fits(self.matcher, winner.pose, odo):
                self.hypotheses.remove(winner)
                self.counts["refused_history"] += 1
                return None
        return winner

    def _move_window(self, delta: NDArray, jump: bool) -> None:
        """Move the lost track's window by the odometry step; close it (global search from
        now on) across a jump or once it is wider than ``reacquire_xy`` / ``reacquire_yaw``."""
        if self.window is None:
            return
        opt = self.options
        self.window.move(delta, opt.odometry)
        if jump or not self.window.open(opt.reacquire_xy, opt.reacquire_yaw):
            self.window = None
            self.running = None  # a window search: the global one starts anew
            for h in self.hypotheses:  # scored from now on as the global search scores
                h.recent.clear()

    def _agreement(self, xy: NDArray, pose: NDArray, mapped: float, support: Support) -> float:
        """A hypothesis's agreement from ``mapped`` (the share of the scan's points near a
        map point) and its free-space ``support``: in the global search :func:`seen_share`
        (the share of the scan the map could have seen); inside a lost track's window,
        where the robot often sees space the map does not cover, the share among the points
        the map could explain when more than ``partly_outside`` of them are far from every
        map point, as a tracked scan is judged (``Fit.explained``)."""
        if self.window is None:
            return seen_share(mapped, support, self.options)
        unmapped = float(np.mean(self.local.unexplained(transform(xy, pose)))) if len(xy) else 0.0
        return explained_share(mapped, 0.0, unmapped, self.options.partly_outside)

    def _follow(self, xy: NDArray, delta: NDArray, step: float) -> None:
        """Move every hypothesis by the odometry step, align it, score it, prune, merge."""
        opt = self.options
        prior = self.matcher.prior(delta, False)
        for h in self.hypotheses:
            aligned, agreement = self.matcher.align(xy, compose_many(h.pose, delta), prior)
            h.pose = aligned.pose
            support = self.matcher.support(h.pose, xy)
            h.remember(self._agreement(xy, h.pose, agreement, support), support, opt.recent_scans)
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

    def _propose(self, scan: LaserScan, xy: NDArray, odo: NDArray, index: int) -> None:
        """New hypotheses: on every scan the place index's candidates (corner keypoints,
        ``localise.places``) when the map has an index and no lost track's window is open;
        the exhaustive correlative search (the whole map, or the window after a lost track)
        when there is no index, or inside a window, or once the search has travelled
        ``places.fallback_travel`` with no hypothesis alive (too few corners where the robot
        is): started on the first scan it is needed, then at most every ``global_every``
        scans (a fixed phase of the scan count would delay it by up to ``global_every - 1``
        scans, by when the search began), run :attr:`slice_nodes` nodes a scan
        (:meth:`_slice`)."""
        opt = self.options
        keypoints = self.window is None and self.places.usable
        due = self.started is None or self.scans - self.started >= opt.global_every
        if not (keypoints or due or self.running is not None):
            return
        mount = self.matcher.mount
        coarse = scan_points(scan, mount, opt.min_range, opt.max_range, GLOBAL_SPACING)
        if keypoints:
            found = self.places.propose(coarse.xy)
            self.counts["place_attempts"] += 1
            self._spawn([c.pose for c in found], xy, odo, index)
        fallback = not keypoints or (
            self.travel >= opt.places.fallback_travel and not self.hypotheses
        )
        if (fallback and due) or self.running is not None:
            self._slice(coarse.xy, xy, odo, index)

    def _slice(self, coarse: NDArray, xy: NDArray, odo: NDArray, index: int) -> None:
        """One slice of the exhaustive search (a new one on this scan when none runs). Its
        answers come out best first and final (:class:`SlicedSearch`): each new one becomes
        a hypothesis as it would have on the scan searched (:meth:`_fresh` on that scan),
        carried to this scan by the odometry since
        (:func:`~laser_corners.registration.global_search.carried`)."""
        start = time.perf_counter()
        if self.running is None:
            self.counts["searches"] += 1
            self.started = self.scans
            then = (np.array(odo, dtype=np.float64), xy, index, self.travel)
            model, window = self.matcher.model, self.window
            self.running = (exhaustive_search(model, window, coarse, self.options), then, 0)
        search, (then_odo, then_xy, then_index, then_travel), used = self.running
        search.advance(self.slice_nodes)
        self.counts["search_slices"] += 1
        self.search_ms.append((time.perf_counter() - start) * 1e3)
        guesses = [p for p, _ in search.result()[used:]]
        self.running = None if search.done else (search, self.running[1], used + len(guesses))
        if not guesses:
            return
        back = carried([h.pose for h in self.hypotheses], odo, then_odo)
        fresh = self._fresh(guesses, back, then_xy, then_odo, then_index, then_travel)
        for h, pose in zip(fresh, carried([h.pose for h in fresh], then_odo, odo), strict=True):
            h.pose = pose
            h.travel += self.travel - then_travel
            h.scans += index - then_index
        self.hypotheses = merged(self.hypotheses + fresh, self.options)

    def _spawn(self, guesses: list[NDArray], xy: NDArray, odo: NDArray, index: int) -> None:
        """Hypotheses from the guesses on this scan (:meth:`_fresh`), merged with those alive."""
        poses = [h.pose for h in self.hypotheses]
        fresh = self._fresh(guesses, poses, xy, odo, index, self.travel)
        self.hypotheses = merged(self.hypotheses + fresh, self.options)

    def _fresh(
        self,
        guesses: list[NDArray],
        taken: list[NDArray],
        xy: NDArray,
        odo: NDArray,
        index: int,
        travel: float,
    ) -> list[Hypothesis]:
        """Hypotheses from the guesses of the scan ``index`` (points ``xy``, odometry
        ``odo``, the search's ``travel`` then) that ICP aligns to agree with the map without
        contradicting its free space (counted in ``refused_free_space`` when not); guesses
        near a pose of ``taken`` (the hypotheses alive, at that scan) are skipped. Those of
        the global search are credited with the past scans they explain (:meth:`_credit`)."""
        opt = self.options
        prior = np.diag(1.0 / SPAWN_SIGMA**2)
        apart = (opt.distinct_xy, opt.distinct_yaw)
        fresh = []
        for guess in guesses:
            if any(not poses_apart(guess, pose, *apart) for pose in taken):
                continue
            aligned, agreement = self.matcher.align(xy, guess, prior)
            if agreement < opt.hypothesis_agreement:
                continue
            support = self.matcher.support(aligned.pose, xy)
            if not self.matcher.admits(support):
                self.counts["refused_free_space"] += 1
                continue
            h = Hypothesis(aligned.pose, index)
            if self.window is None:
                self._credit(h, odo, index, travel)
            h.remember(self._agreement(xy, h.pose, agreement, support), support, opt.recent_scans)
            fresh.append(h)
        return fresh

    def _credit(self, h: Hypothesis, odo: NDArray, index: int, travel: float) -> None:
        """Credit a new hypothesis of the global search at scan ``index`` (the search's
        ``travel`` then) with the past scans it explains (``SearchHistory.explained``):
        their agreements (:func:`seen_share`) and shares join its recent ones, their travel
        and scans its own (``localise.history``)."""
        credited = self.history.explained(self.matcher, h.pose, odo, travel, index)
        if not credited:
            return
        opt, keep = self.options, self.options.recent_scans
        for past in reversed(credited):  # scored as the global search scores a scan
            h.remember(seen_share(past.agreement, past.support, opt), past.support, keep)
        h.travel = travel - credited[-1].scan.travel
        h.scans = index - credited[-1].scan.index
        self.counts["credited"] += 1


def exhaustive_search(
    model: MapModel, window: Window | None, xy: NDArray, opt: LocaliseOptions
) -> SlicedSearch:
    """The exhaustive correlative search of the scan points ``xy``, to run in slices: over the
    whole map of ``model``, or inside the lost track's ``window``."""
    if window is None:
        return model.global_slices(xy, opt.global_yaw_step, opt.global_candidates)
    return model.window_slices(
        xy,
        window.pose,
        *window.half_widths,
        opt.global_yaw_step,
        opt.global_candidates,
        (opt.distinct_xy, opt.distinct_yaw),
    )
