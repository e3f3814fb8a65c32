"""Loop-closure bookkeeping: accepted closures into the graph, the ones the final
optimisation drops marked, relocalisation started for a new segment
(laser_corners.slam.closing)."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("gtsam")

from laser_corners.slam.backend import Backend
from laser_corners.slam.closing import LoopCloser
from laser_corners.slam.keyframes import KeyframeStore
from laser_corners.slam.options import LoopOptions, SlamOptions
from laser_corners.slam.relocalise import Relocaliser
from laser_corners.slam.result import LoopClosure

OPTIONS = SlamOptions()


def _closer(options: SlamOptions = OPTIONS, n: int = 4) -> tuple[LoopCloser, Backend]:
    """A closer over a back end holding a chain of ``n`` keyframes 1 m apart."""
    backend = Backend()
    for k in range(n):
        backend.add_keyframe(np.array([float(k), 0.0, 0.0]))
        if k:
            backend.add_between(k - 1, k, np.array([1.0, 0.0, 0.0]), (0.05, 0.05, 0.01))
    backend.update()
    counts = backend.counts
    relocaliser = Relocaliser(options, np.zeros(3), None, counts=counts)
    return LoopCloser(options, backend, counts, relocaliser), backend


def test_accepted_closures_go_into_the_graph_and_the_dropped_ones_are_marked() -> None:
    closer, backend = _closer()
    first = LoopClosure(3, 0, (3.0, 0.0, 0.0), False, "pending confirmation")
    second = LoopClosure(3, 1, (2.0, 0.0, 0.0), False, "ok")
    rejected = LoopClosure(2, 0, (9.0, 0.0, 0.0), False, "low score 0.3")
    closer.closures += [first, second, rejected]
    closer.accept(first)
    closer.accept(second)
    assert first.accepted and first.reason == "confirmed by a later closure"
    assert [loop[:2] for loop in backend.loops] == [(0, 3), (1, 3)]
    closer.prune([1])  # the back end's second closure
    closer.prune([1])  # already dropped: counted once
    assert first.accepted and not second.accepted
    assert second.reason == "dropped: contradicted by the optimised graph"
    closer.tally()
    counts = backend.counts
    assert (counts.closures_pruned, counts.closures_accepted, counts.closures_rejected) == (1, 1, 2)


def test_no_search_off_the_loop_every_keyframes_or_with_loop_closure_off() -> None:
    store = KeyframeStore()
    store.estimate = np.array([[float(k), 0.0, 0.0] for k in range(3)])
    closer, backend = _closer(SlamOptions(loop=LoopOptions(every=2)))
    assert closer.keyframe(3, store, np.array([3.0, 0.0, 0.0])) == (False, False)
    off, _ = _closer(SlamOptions(loop=LoopOptions(enabled=False, every=1)))
    assert off.keyframe(3, store, np.array([3.0, 0.0, 0.0])) == (False, False)
    assert backend.counts.closures_proposed == 0 and closer.closures == []


def test_a_new_segment_starts_relocalisation_when_it_is_on() -> None:
    closer, _ = _closer()
    closer.lost_from(0)  # nothing older to search in
    assert not closer.relocaliser.lost
    closer.lost_from(2)
    assert closer.relocaliser.lost and closer.relocaliser.start == 2
    off, _ = _closer(SlamOptions(relocalisation=False))
    off.lost_from(2)
    assert not off.relocaliser.lost


def _closing_with(monkeypatch, closer: LoopCloser, olds: list[int], accept: bool) -> list[int]:
    """Every keyframe's loop-closure candidates are ``olds``; each is verified as ``accept``
    and passes the gate at once; no relocalisation finds anything. Returns the keyframes
    verified (appended to as the closer runs)."""
    verified: list[int] = []

    def verify(k, j, *args, **kwargs):
        verified.append(j)
        return LoopClosure(k, j, (0.0, 0.0, 0.0), accept, "ok" if accept else "low score")

    monkeypatch.setattr("laser_corners.slam.closing.candidates", lambda *a, **k: list(olds))
    monkeypatch.setattr("laser_corners.slam.closing.verify", verify)
    monkeypatch.setattr(closer.gate, "offer", lambda closure, estimate: [closure])
    monkeypatch.setattr(closer.relocaliser, "attempt", lambda *a, **k: [])
    return verified


def _store(n: int) -> KeyframeStore:
    store = KeyframeStore()
    store.estimate = np.array([[float(k), 0.0, 0.0] for k in range(n)])
    store.travelled = [float(k) for k in range(n)]
    store.points = [None] * n
    return store


def test_an_unplaced_segment_closes_only_with_its_own_keyframes(monkeypatch) -> None:
    # a new session on a prior map (keyframes 0-3), no initial pose: its frame is not the
    # map's, so a window around its estimate among the map's keyframes means nothing
    closer, backend = _closer(SlamOptions(loop=LoopOptions(every=1)), n=7)
    verified = _closing_with(monkeypatch, closer, [1, 4], accept=False)
    closer.lost_from(4, unplaced=True)
    closer.keyframe(6, _store(6), np.array([6.0, 0.0, 0.0]))
    assert verified == [4] and backend.counts.closures_proposed == 1
    placed, _ = _closer(SlamOptions(loop=LoopOptions(every=1)), n=7)  # an ordinary lost segment
    verified = _closing_with(monkeypatch, placed, [1, 4], accept=False)
    placed.lost_from(4)
    placed.keyframe(6, _store(6), np.array([6.0, 0.0, 0.0]))
    assert verified == [1, 4]


def test_a_closure_within_an_unplaced_segment_does_not_end_its_search(monkeypatch) -> None:
    # an ordinary lost segment: a closure ends the search (the segment's dead-reckoned frame
    # is near the map's); an unplaced one (a new session on a prior map): only relocalisation
    # into the map before it does
    for unplaced, still_lost in ((False, False), (True, True)):
        closer, _ = _closer(SlamOptions(loop=LoopOptions(every=1)), n=7)
        _closing_with(monkeypatch, closer, [4], accept=True)
        closer.lost_from(3, unplaced=unplaced)
        assert closer.keyframe(6, _store(6), np.array([6.0, 0.0, 0.0]))[0]  # closed
        assert closer.relocaliser.lost == still_lost


def test_a_prior_maps_closures_in_the_back_end_do_not_shift_the_pruned_ones() -> None:
    backend = Backend()
    for k in range(4):
        backend.add_keyframe(np.array([float(k), 0.0, 0.0]))
        if k:
            backend.add_between(k - 1, k, np.array([1.0, 0.0, 0.0]), (0.05, 0.05, 0.01))
    backend.add_between(0, 2, np.array([2.0, 0.0, 0.0]), (0.05, 0.05, 0.01), robust=True)
    backend.update()  # a prior map's closure first (slam.grow), then this run's
    closer = LoopCloser(OPTIONS, backend, backend.counts, Relocaliser(OPTIONS, np.zeros(3), None))
    ours = LoopClosure(3, 0, (3.0, 0.0, 0.0), False, "ok")
    closer.closures.append(ours)
    closer.accept(ours)
    assert [loop[:2] for loop in backend.loops] == [(0, 2), (0, 3)]
    closer.prune([0])  # the prior map's: not this run's
    assert ours.accepted and backend.counts.closures_pruned == 0
    closer.prune([1])
    assert not ours.accepted and backend.counts.closures_pruned == 1
