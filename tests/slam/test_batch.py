"""The batch optimisation and its pruning of contradicted loop closures
(laser_corners.slam.batch)."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("gtsam")

import gtsam

from laser_corners.registration.graph import X, diagonal_noise, robust_noise
from laser_corners.slam.batch import optimise
from laser_corners.slam.counts import SlamCounts
from laser_corners.slam.factors import FactorLog

LOOP = (0.05, 0.05, 0.01)


def _square() -> tuple[FactorLog, gtsam.Values]:
    """Eight keyframes 1 m apart along x, a right closure 0 -> 7 and a wrong one 1 -> 6."""
    log, start = FactorLog(), gtsam.Values()
    log.add(gtsam.PriorFactorPose2(X(0), gtsam.Pose2(), diagonal_noise(1e-3, 1e-3, 1e-4)))
    for k in range(8):
        log.initial.insert(X(k), gtsam.Pose2(float(k), 0.0, 0.0))
        start.insert(X(k), gtsam.Pose2(float(k), 0.0, 0.0))
    for k in range(1, 8):
        rel = gtsam.Pose2(1.0, 0.0, 0.0)
        log.add(gtsam.BetweenFactorPose2(X(k - 1), X(k), rel, diagonal_noise(0.02, 0.02, 0.005)))
    for a, b, dx in ((0, 7, 7.0), (1, 6, 6.0)):  # the second is 1 m off (truth: 5 m)
        rel = gtsam.Pose2(dx, 0.0, 0.0)
        log.add_loop(a, b, rel, diagonal_noise(*LOOP))
        log.add(gtsam.BetweenFactorPose2(X(a), X(b), rel, robust_noise(diagonal_noise(*LOOP))))
    return log, start


def test_a_contradicted_closure_is_pruned_and_the_graph_solved_without_it() -> None:
    log, start = _square()
    counts, warnings = SlamCounts(), []
    found = optimise(log, start, [], counts, warnings)
    assert found.pruned == [1] and found.extra_pruned == 0
    assert found.graph.size() == log.graph.size() - 1
    assert found.values.atPose2(X(7)).x() == pytest.approx(7.0, abs=0.01)
    assert counts.final_optimisation_failures == 0 and warnings == []


def test_a_wrong_extra_measurement_is_dropped_and_counted_apart() -> None:
    log, start = _square()
    extra = [(2, 4, np.array([2.0, 0.0, 0.0]), LOOP), (2, 5, np.array([4.0, 0.0, 0.0]), LOOP)]
    found = optimise(log, start, [1], SlamCounts(), [], extra)
    assert found.pruned == [1] and found.extra_pruned == 1


def test_a_failed_solve_keeps_the_start_and_says_so() -> None:
    log, start = _square()
    counts, warnings = SlamCounts(), []

    def fail(graph, values, params):
        raise RuntimeError("Indeterminate linear system. More text.")

    found = optimise(log, start, [], counts, warnings, solve=fail)
    assert found.values is start and found.pruned == []
    assert counts.final_optimisation_failures == 1
    assert warnings == [
        "batch optimisation: Indeterminate linear system; the map keeps the iSAM2 estimate"
    ]
