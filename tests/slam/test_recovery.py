"""Recovery of an iSAM2 update gtsam refused (laser_corners.slam.recovery)."""

from __future__ import annotations

import pytest

pytest.importorskip("gtsam")

import gtsam

from laser_corners.registration.graph import X, diagonal_noise
from laser_corners.slam.backend import new_isam
from laser_corners.slam.counts import SlamCounts
from laser_corners.slam.factors import FactorLog
from laser_corners.slam.recovery import Recovery, first_line

MESSAGE = (
    "\nIndeterminate linear system detected while working near variable\n"
    "8646911284551352325 (Symbol: x{k}).\n\nThrown when a linear system is ill-posed."
)


class Refusing:
    """A real iSAM2 whose ``update`` raises when the graph holds the factor ``a -> b``."""

    def __init__(self, a: int, b: int) -> None:
        self.real, self.keys = new_isam(), (X(a), X(b))

    def update(self, graph, values):
        for i in range(graph.size()):
            if tuple(graph.at(i).keys()) == self.keys:
                raise RuntimeError(MESSAGE.format(k=b_of(self.keys)))
        return self.real.update(graph, values)

    def calculateEstimate(self):
        return self.real.calculateEstimate()


def b_of(keys: tuple[int, int]) -> int:
    return gtsam.Symbol(keys[1]).index()


def _chain(n: int) -> tuple[FactorLog, gtsam.Values]:
    log, guess = FactorLog(), gtsam.Values()
    log.add(gtsam.PriorFactorPose2(X(0), gtsam.Pose2(), diagonal_noise(1e-3, 1e-3, 1e-4)))
    for k in range(n):
        log.initial.insert(X(k), gtsam.Pose2(float(k), 0.0, 0.0))
        guess.insert(X(k), gtsam.Pose2(float(k), 0.0, 0.0))
    for k in range(1, n):
        rel = gtsam.Pose2(1.0, 0.0, 0.0)
        log.add(gtsam.BetweenFactorPose2(X(k - 1), X(k), rel, diagonal_noise(0.1, 0.1, 0.01)))
    return log, guess


def test_the_named_variable_is_reanchored_and_the_rebuild_taken() -> None:
    log, guess = _chain(3)
    counts, warnings = SlamCounts(), []
    isam = Recovery(new_isam, counts, warnings).recover(
        RuntimeError(MESSAGE.format(k=2)), log, guess, [X(2)], good=2, newest=2
    )
    assert (counts.optimiser_recoveries, counts.optimiser_anchors) == (1, 1)
    assert counts.optimiser_factors_dropped == 0
    assert warnings == [
        "optimiser: Indeterminate linear system detected while working near variable "
        "8646911284551352325 (Symbol: x2); re-anchored x2 and went on"
    ]
    assert log.graph.size() == 4 and isinstance(log.graph.at(3), gtsam.PriorFactorPose2)
    assert isam.calculateEstimate().atPose2(X(2)).x() == pytest.approx(2.0, abs=1e-6)


def test_a_factor_that_keeps_failing_is_dropped_with_the_rest_of_its_update() -> None:
    log, guess = _chain(4)  # factors: prior, 0-1, 1-2, 2-3; the update that failed: 2-3
    counts, warnings = SlamCounts(), []
    recovery = Recovery(lambda: Refusing(2, 3), counts, warnings)
    isam = recovery.recover(RuntimeError(MESSAGE.format(k=3)), log, guess, [X(3)], good=3, newest=3)
    assert counts.optimiser_recoveries == 1
    assert counts.optimiser_factors_dropped == 1  # the link 2 -> 3, not the anchors
    assert log.graph.at(3) is None and 3 in log.dropped
    assert warnings[-1].endswith("dropped the 1 factors of that update and went on")
    assert isam.calculateEstimate().atPose2(X(3)).x() == pytest.approx(3.0, abs=1e-6)


def test_when_even_the_last_good_graph_fails_the_error_goes_up() -> None:
    log, guess = _chain(3)
    recovery = Recovery(lambda: Refusing(0, 1), SlamCounts(), [])
    with pytest.raises(RuntimeError, match="Indeterminate"):
        recovery.recover(RuntimeError(MESSAGE.format(k=2)), log, guess, [X(2)], good=2, newest=2)


def test_first_line_is_one_line() -> None:
    assert first_line(RuntimeError(MESSAGE.format(k=1))).endswith("(Symbol: x1)")
    assert first_line(RuntimeError("")) == "RuntimeError"
