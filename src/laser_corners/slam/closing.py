"""Loop closure and relocalisation of the keyframes: :class:`LoopCloser`.

Every ``loop.every``-th keyframe, the older keyframes within the search window
(:func:`~.loops.candidates`) are verified (:func:`~.loops.verify`); a verified closure passes
the :class:`~.loops.ClosureGate` (agreement with another) before it goes into the graph. A
keyframe of a lost segment is searched for in the map built before the segment
(:class:`~.relocalise.Relocaliser`). The closures the final optimisation drops are marked
(:meth:`LoopCloser.prune`).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from laser_corners.slam.backend import Backend
from laser_corners.slam.counts import SlamCounts
from laser_corners.slam.keyframes import KeyframeStore
from laser_corners.slam.loops import (
    MAX_WINDOW_XY,
    MAX_WINDOW_YAW,
    ClosureGate,
    SubmapCache,
    candidates,
    verify,
)
from laser_corners.slam.options import SlamOptions
from laser_corners.slam.relocalise import Relocaliser
from laser_corners.slam.result import LoopClosure

__all__ = ["LoopCloser"]


class LoopCloser:
    """Finds, accepts and prunes the loop closures of a run.

    Parameters
    ----------
    options : SlamOptions
    backend : Backend
        The pose graph accepted closures go into (robust factors).
    counts : SlamCounts
        Counts ``closures_proposed``, ``closures_pruned`` (and, on :meth:`tally`,
        ``closures_accepted`` / ``closures_rejected``).
    relocaliser : Relocaliser
        The search of a lost segment in the older map.

    Attributes
    ----------
    closures : list of LoopClosure
        Every verified closure, accepted or not, in the order verified.
    submaps : SubmapCache
        The verification's submaps of older keyframes (invalidated when estimates move).
    """

    def __init__(
        self,
        options: SlamOptions,
        backend: Backend,
        counts: SlamCounts,
        relocaliser: Relocaliser,
    ) -> None:
        self.options = options
        self.backend = backend
        self.counts = counts
        self.relocaliser = relocaliser
        self.closures: list[LoopClosure] = []
        self._in_graph: list[LoopClosure] = []  # accepted closures, in the back end's order
        self._seeded = len(backend.loops)  # a prior map's closures (:mod:`.grow`) come first
        self.submaps = SubmapCache()
        self.gate = ClosureGate(options.agree_xy, options.agree_yaw, 4 * options.loop.every)
        self._since_closure = 0.0  # distance (m) driven since the last closure
        self._joined = False  # a closure joined the lost segment to the map before it
        self.unplaced: int | None = None  # first keyframe of a segment not yet placed

    def lost_from(self, k: int, unplaced: bool = False) -> None:
        """Keyframe ``k`` starts a new segment, which relocalisation
        (``options.relocalisation``) searches for in the older map. ``unplaced``: the
        segment's frame is unrelated to the map's (a new session on a prior map, no initial
        pose): until relocalised, the ordinary loop closure keeps it to its own keyframes
        (a window around its estimate in the map means nothing)."""
        if self.options.relocalisation:
            self.relocaliser.begin(k)
        if unplaced:
            self.unplaced = k

    def travelled(self, dist: float) -> None:
        """The keyframes moved on by ``dist`` (m): the search window's yaw grows with it."""
        self._since_closure += dist

    def keyframe(
        self, k: int, store: KeyframeStore, pose: NDArray, first: bool = False
    ) -> tuple[bool, bool]:
        """Loop closure (``options.loop.enabled``, not for the ``first`` keyframe) and
        relocalisation for keyframe ``k`` at its tracked ``pose`` (``store``: every keyframe,
        the others at their estimates): whether a closure was accepted, whether a lost
        segment was put back into the map."""
        closed = self._close(k, store, pose) if self.options.loop.enabled and not first else False
        if self._joined:
            self.relocaliser.end()  # an ordinary closure put the segment into the map
            self._joined = False
        relocalised = self._relocalise(k, store, pose) if self.relocaliser.lost else False
        return closed, relocalised

    def _close(self, k: int, store: KeyframeStore, pose: NDArray) -> bool:
        opt = self.options
        if k % opt.loop.every != 0:
            return False
        estimate = np.vstack([store.estimate, pose[None, :]])
        sigma = self.backend.marginal_xy_sigma(k - 1) if k > 0 else 0.0
        window = (
            min(opt.loop.search_xy + 3.0 * sigma, MAX_WINDOW_XY),
            min(opt.loop.search_yaw + opt.loop.drift * self._since_closure, MAX_WINDOW_YAW),
        )
        closed = False
        travelled = store.travelled_array
        for j in candidates(k, estimate, travelled(), window[0], opt):
            if self.unplaced is not None and j < self.unplaced:
                continue
            self.counts.closures_proposed += 1
            closure = verify(k, j, store.points, estimate, travelled(), window, opt, self.submaps)
            self.closures.append(closure)
            if not closure.accepted:
                continue
            for good in self.gate.offer(closure, estimate):
                self.accept(good)
                closed = True
                start = self.relocaliser.start
                # a closure puts a lost segment into the map, unless the segment is unplaced
                # (its frame unrelated to the map's) and the closure within it
                self._joined |= self.unplaced is None or (start is not None and good.match < start)
        if closed:
            self._since_closure = 0.0
        return closed

    def _relocalise(self, k: int, store: KeyframeStore, pose: NDArray) -> bool:
        """A relocalisation attempt for keyframe ``k`` of a lost segment (:mod:`.relocalise`);
        whether it put the segment back into the map (two agreeing closures accepted)."""
        estimate = np.vstack([store.estimate, pose[None, :]])
        found = self.relocaliser.attempt(k, store.points, estimate)
        for closure in found:
            if closure not in self.closures:
                self.closures.append(closure)
            self.accept(closure)
        if found:
            self._since_closure = 0.0
            self.unplaced = None
        return bool(found)

    def accept(self, closure: LoopClosure) -> None:
        """Put a verified closure into the graph (robust factor); the back end's list of
        closures and this part's keep the same order, which :meth:`prune` relies on."""
        opt = self.options
        closure.accepted = True
        if closure.reason == "pending confirmation":
            closure.reason = "confirmed by a later closure"
        self._in_graph.append(closure)
        sig = (opt.loop.sigma_xy, opt.loop.sigma_xy, opt.loop.sigma_yaw)
        self.backend.add_between(
            closure.match, closure.query, np.array(closure.relative), sig, robust=True
        )

    def prune(self, pruned: list[int]) -> None:
        """Mark the accepted closures the final optimisation dropped (``pruned``: indices in
        the order they went into the graph, :attr:`Backend.pruned`) as dropped (counted). A
        prior map's closures, which the back end holds first, are not this run's: skipped."""
        for i in pruned:
            if i < self._seeded:
                continue
            closure = self._in_graph[i - self._seeded]
            if closure.accepted:
                closure.accepted = False
                closure.reason = "dropped: contradicted by the optimised graph"
                self.counts.closures_pruned += 1

    def tally(self) -> None:
        """Count the closures accepted and rejected so far."""
        accepted = sum(c.accepted for c in self.closures)
        self.counts.closures_accepted = accepted
        self.counts.closures_rejected = len(self.closures) - accepted
