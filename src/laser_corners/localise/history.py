"""The search's past scans: :class:`SearchHistory`.

While the localiser searches, it keeps one scan per :data:`HISTORY_STEP` of travel (with its
odometry pose and scan index) for ``history_travel`` metres. Chained back from a pose by the
odometry (:meth:`SearchHistory.replay`), they serve twice:

* a fix must not contradict the map's free space over them (what tracking would have
  required had the winner been followed from the search's start);
* a new hypothesis is *credited* with the past scans it explains: the place index often
  proposes the right pose only after a metre or more (few corners seen yet, or alike ones),
  and the scans before it are evidence for it as much as the scans after it. Its agreement
  (scored as the global search scores a scan: ``hypotheses.seen_share``) and free-space
  shares on them join its recent ones, its travel and scan count grow by theirs, so the fix
  comes ``fix_travel`` after the search started rather than after the proposal, while the
  margin over every rival and ``fix_followed_travel`` of following still apply.

Cost: one ICP per replayed scan, at most ``fix_travel / HISTORY_STEP`` of them per credited
hypothesis (10 by default), stopping at the first scan that does not fit.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from laser_corners.localise.freespace import Support
from laser_corners.localise.matcher import MapMatcher
from laser_corners.pose import between_many, compose_many

__all__ = ["HISTORY_STEP", "PastScan", "Replayed", "SearchHistory"]

HISTORY_STEP = 0.2
"""Odometry travel (m, turns 0.5 m per radian) between two scans kept."""


@dataclass(frozen=True)
class PastScan:
    """One kept scan of the search."""

    travel: float
    """The search's travel (m, turns 0.5 m per radian) when it was kept."""
    index: int
    """Its scan index (``Localiser.counts["scans"]`` before it)."""
    xy: NDArray[np.float64]
    """Its points (base frame)."""
    odometry: NDArray[np.float64]
    """The base's odometry pose at it."""


@dataclass(frozen=True)
class Replayed:
    """A past scan placed by chaining back from a pose."""

    scan: PastScan
    pose: NDArray[np.float64]
    """Its pose: ICP from the chained guess, kept when it agrees (else the guess)."""
    agreement: float
    """Share of its points near a map point after ICP."""
    support: Support
    """Its free-space shares at :attr:`pose`."""


class SearchHistory:
    """The search's past scans, one per ``step`` of travel, for ``keep`` metres.

    Parameters
    ----------
    keep : float
        Travel (m) after which a kept scan is forgotten (``history_travel``).
    step : float
        Travel (m) between two kept scans.
    """

    def __init__(self, keep: float, step: float = HISTORY_STEP) -> None:
        self.keep = keep
        self.step = step
        self._scans: deque[PastScan] = deque()

    def __len__(self) -> int:
        return len(self._scans)

    def clear(self) -> None:
        """Forget every kept scan (a new search, or a jump that breaks the odometry chain)."""
        self._scans.clear()

    def remember(self, travel: float, index: int, xy: NDArray, odometry: NDArray) -> None:
        """Keep this scan when the search moved ``step`` since the last one kept; forget
        those more than ``keep`` back."""
        scans = self._scans
        if scans and travel - scans[-1].travel < self.step:
            return
        scans.append(PastScan(travel, index, xy, odometry))
        while travel - scans[0].travel > self.keep:
            scans.popleft()

    def replay(
        self, matcher: MapMatcher, pose: NDArray, odometry: NDArray, before: int | None = None
    ) -> Iterator[Replayed]:
        """The kept scans, newest first, chained back from ``pose`` (at ``odometry``).

        Each is aligned to the map (``matcher``) from the chained guess under the odometry
        prior of the step; the aligned pose is kept when it agrees at least
        ``hypothesis_agreement``, else the guess (dead reckoning through what the map does not
        show). ``before``: only scans with a smaller index (leaves out the current one).
        """
        accept = matcher.options.hypothesis_agreement
        last = odometry
        for past in reversed(self._scans):
            if before is not None and past.index >= before:
                continue
            delta = between_many(last, past.odometry)
            guess = compose_many(pose, delta)
            aligned, agreement = matcher.align(past.xy, guess, matcher.prior(delta, False))
            pose = aligned.pose if agreement >= accept else guess
            yield Replayed(past, pose, float(agreement), matcher.support(pose, past.xy))
            last = past.odometry

    def fits(self, matcher: MapMatcher, pose: NDArray, odometry: NDArray) -> bool:
        """Whether the kept scans, chained back from ``pose``, never contradict the map's free
        space on more than ``track_conflict`` of the beams over ``conflict_scans`` kept scans:
        what tracking would have required had ``pose`` been followed from the search's start.
        A look-alike of an unmapped place often fits the map only from where the robot is
        now (issue 20, later visit). The check stops at the first past scan that lies
        mostly outside the map (more than ``max_outside``) without contradicting it (at most
        ``max_conflict``): the robot came from unknown space, and before it the chain is dead
        reckoning through it. A past scan both outside and contradicting the map is evidence
        against the pose, not a way out: a look-alike 35 m off at aces' later visit from 40 %
        of the log (the robot 23 m from the mapping robot's path) fitted the last 3.3 m, but
        chained back further its scans lay half outside the map and contradicted it on
        0.5-0.8 of their beams for metres. The threshold is tracking's, not the fix's: a right
        fix of aces' later visit had 2 m of its history at 0.22-0.29 (agreeing 0.84-0.94:
        the building had changed)."""
        opt = matcher.options
        conflicts: list[float] = []
        for past in self.replay(matcher, pose, odometry):
            support = past.support
            if support.outside > opt.max_outside and support.conflict <= opt.max_conflict:
                break  # the robot came from outside the map: further back is dead reckoning
            conflicts.append(support.conflict)
        if not conflicts:
            return True
        n = min(len(conflicts), opt.conflict_scans)  # fewer scans: their mean
        window = np.convolve(conflicts, np.ones(n) / n, "valid")
        return float(window.max()) <= opt.track_conflict

    def explained(
        self, matcher: MapMatcher, pose: NDArray, odometry: NDArray, travel: float, before: int
    ) -> list[Replayed]:
        """The kept scans before scan ``before`` that a hypothesis at ``pose`` explains,
        newest first: up to ``fix_travel`` back from the search's ``travel``, stopping at the
        first that agrees less than ``hypothesis_agreement`` or contradicts the map's free
        space as a hypothesis may not (:meth:`MapMatcher.admits`)."""
        opt = matcher.options
        out: list[Replayed] = []
        for past in self.replay(matcher, pose, odometry, before):
            if past.agreement < opt.hypothesis_agreement or not matcher.admits(past.support):
                break
            out.append(past)
            if travel - past.scan.travel >= opt.fix_travel:
                break
        return out
