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
from laser_corners.slam.options import SlamOptions
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
    closer, backend = _closer(SlamOptions(loop_every=2))
    assert closer.keyframe(3, store, np.array([3.0, 0.0, 0.0])) == (False, False)
    off, _ = _closer(SlamOptions(loop_closure=False, loop_every=1))
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
