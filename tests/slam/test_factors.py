"""The record of every factor of the pose graph (laser_corners.slam.factors)."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("gtsam")

import gtsam

from laser_corners.registration.graph import L, X, diagonal_noise, robust_noise
from laser_corners.slam.factors import FactorLog


def _between(a: int, b: int, x: float = 1.0) -> object:
    return gtsam.BetweenFactorPose2(X(a), X(b), gtsam.Pose2(x, 0, 0), diagonal_noise(1, 1, 1))


def _chain(n: int = 4) -> FactorLog:
    log = FactorLog()
    log.add(gtsam.PriorFactorPose2(X(0), gtsam.Pose2(), diagonal_noise(1, 1, 1)))
    for k in range(n):
        log.initial.insert(X(k), gtsam.Pose2(float(k), 0.0, 0.0))
    for k in range(1, n):
        log.add(_between(k - 1, k))
    return log


def test_a_loop_is_kept_apart_and_left_out_of_a_solve_that_drops_it() -> None:
    log = _chain()
    log.add_loop(0, 3, gtsam.Pose2(3, 0, 0), diagonal_noise(1, 1, 1))
    log.add(
        gtsam.BetweenFactorPose2(
            X(0), X(3), gtsam.Pose2(3, 0, 0), robust_noise(diagonal_noise(1, 1, 1))
        )
    )
    assert log.loops[0][:2] == (0, 3) and log.loops[0][4] == 4  # its index in the graph
    assert log.active([], set()).size() == 5
    assert log.active([], {0}).size() == 4
    extra = [(1, 3, gtsam.Pose2(2, 0, 0), diagonal_noise(1, 1, 1))]
    assert log.active(extra, set()).size() == 6
    assert log.active(extra, {1}).size() == 5  # the extra one dropped (index after the loops)


def test_dropped_factors_leave_an_empty_slot() -> None:
    log = _chain()
    log.add_loop(0, 3, gtsam.Pose2(3, 0, 0), diagonal_noise(1, 1, 1))
    log.add(_between(0, 3, 3.0))
    log.drop(range(3, 5))
    assert log.graph.size() == 5 and log.graph.at(3) is None and log.graph.at(4) is None
    assert log.dropped == {3, 4} and log.dropped_loops() == {0}
    assert log.active([], set()).size() == 3


def test_an_anchor_holds_a_variable_at_the_guess_and_unsets_solved() -> None:
    log = _chain(2)
    log.solved = log.graph
    guess = log.guess(np.array([[0.0, 0.0, 0.0], [5.0, 1.0, 0.2]]), gtsam.Values(), 0)
    assert guess.atPose2(X(1)).x() == 5.0  # the estimate, not the initial guess 1.0
    log.anchor(X(1), guess, (1.0, 1.0, 0.1))
    assert log.solved is None and log.graph.size() == 3
    prior = log.graph.at(2)
    assert isinstance(prior, gtsam.PriorFactorPose2) and prior.prior().x() == 5.0


def test_a_landmark_guess_comes_from_the_values_that_hold_it() -> None:
    log = FactorLog()
    log.initial.insert(L(0), np.array([1.0, 1.0]))
    log.initial.insert(L(1), np.array([2.0, 2.0]))
    values = gtsam.Values()
    values.insert(L(0), np.array([1.5, 1.0]))
    guess = log.guess(np.zeros((0, 3)), values, 2)
    assert np.allclose(guess.atPoint2(L(0)), [1.5, 1.0])
    assert np.allclose(guess.atPoint2(L(1)), [2.0, 2.0])
    log.anchor(L(1), guess, (1.0, 1.0, 0.1))
    assert isinstance(log.graph.at(0), gtsam.PriorFactorPoint2)
