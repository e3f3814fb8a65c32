"""The batch optimisation at the end of a run: Levenberg-Marquardt over every factor, then
the loop closures the result contradicts dropped and the graph solved again
(:func:`optimise`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from laser_corners.registration.graph import X, diagonal_noise
from laser_corners.slam.counts import SlamCounts
from laser_corners.slam.factors import FactorLog
from laser_corners.slam.recovery import first_line

try:
    import gtsam
except ImportError:  # pragma: no cover - the "slam" extra is missing
    gtsam = None

__all__ = ["PRUNE_CHI", "PRUNE_ROUNDS", "BatchSolution", "Extra", "levenberg_marquardt", "optimise"]

PRUNE_CHI = 3.0
"""A loop closure whose whitened residual after the batch optimisation exceeds this many
standard deviations contradicts the rest of the graph: it is dropped and the graph re-solved."""
PRUNE_ROUNDS = 3
"""Rounds of pruning and re-solving at most."""

Extra = tuple[int, int, NDArray[np.float64], tuple[float, float, float]]
"""A relative-pose measurement for one solve: keyframes ``a``, ``b``, ``relative`` (x, y,
yaw), standard deviations."""


@dataclass
class BatchSolution:
    """What :func:`optimise` found: the graph solved, its ``values``, the loop closures
    dropped (``pruned``: indices into :attr:`FactorLog.loops`) and how many ``extra``
    measurements were dropped."""

    graph: object
    values: object
    pruned: list[int]
    extra_pruned: int


def levenberg_marquardt(graph: object, values: object, params: object) -> object:
    """Levenberg-Marquardt on ``graph`` from ``values`` (the default ``solve``)."""
    return gtsam.LevenbergMarquardtOptimizer(graph, values, params).optimize()


def optimise(
    factors: FactorLog,
    start: object,
    pruned: list[int],
    counts: SlamCounts,
    warnings: list[str],
    extra: list[Extra] | None = None,
    solve: Callable[[object, object, object], object] = levenberg_marquardt,
) -> BatchSolution:
    """Batch Levenberg-Marquardt over ``factors`` from ``start`` (``gtsam.Values``), then the
    loop closures that the result contradicts (residual > :data:`PRUNE_CHI` sigmas) dropped
    and the graph solved again, up to :data:`PRUNE_ROUNDS` times (a dropped closure can have
    hidden another).

    ``pruned``: closures dropped before (they stay dropped). ``extra``: measurements for this
    solve only, robust and pruned as the loop closures. A failed solve keeps the values
    before it (counted in ``final_optimisation_failures``, a line in ``warnings``).
    """
    params = gtsam.LevenbergMarquardtParams()
    params.setMaxIterations(50)
    checked = [(a, b, rel, noise) for a, b, rel, noise, _ in factors.loops]
    for a, b, relative, sigmas in extra or []:
        checked.append((a, b, gtsam.Pose2(*map(float, relative)), diagonal_noise(*sigmas)))
    n_loops = len(factors.loops)
    dropped = set(pruned) | factors.dropped_loops()
    values = start
    for round_ in range(PRUNE_ROUNDS + 1):
        graph = factors.active(checked[n_loops:], dropped)
        try:
            values = solve(graph, values, params)
        except RuntimeError as exc:
            counts.final_optimisation_failures += 1
            warnings.append(
                f"batch optimisation: {first_line(exc)}; the map keeps the "
                + ("iSAM2 estimate" if round_ == 0 else "estimate before that round")
            )
            break
        if round_ == PRUNE_ROUNDS:
            break
        bad = [
            i
            for i, (a, b, rel, noise) in enumerate(checked)
            if i not in dropped
            and np.sqrt(2.0 * gtsam.BetweenFactorPose2(X(a), X(b), rel, noise).error(values))
            > PRUNE_CHI
        ]
        if not bad:
            break
        dropped.update(bad)
    return BatchSolution(
        graph,
        values,
        sorted(i for i in dropped if i < n_loops),
        sum(1 for i in dropped if i >= n_loops),
    )
