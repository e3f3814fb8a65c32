"""Every factor of the pose graph, kept for the batch optimisation, a rebuild and g2o:
:class:`FactorLog` (the back end's record; iSAM2 holds its own copy of the factors it took).

Keyframe ``k`` is the variable ``X(k)`` (``gtsam.Pose2``), landmark ``l`` is ``L(l)``
(``gtsam.Point2``). Loop closures are kept apart (:attr:`FactorLog.loops`) so a batch
optimisation can leave out the ones the rest of the graph contradicts; factors a recovery
dropped (:mod:`.recovery`) leave an empty slot, so the indices of the others hold.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from laser_corners.registration.graph import L, X, diagonal_noise, require_gtsam, robust_noise

try:
    import gtsam
except ImportError:  # pragma: no cover - the "slam" extra is missing
    gtsam = None

__all__ = ["FactorLog"]

Loop = tuple[int, int, object, object, int]
"""A loop closure: keyframes ``a``, ``b``, the measured ``gtsam.Pose2``, its (not robust)
noise model and the index of its factor in :attr:`FactorLog.graph`."""


class FactorLog:
    """Every factor added (:attr:`graph`) and every variable's initial guess (:attr:`initial`).

    Attributes
    ----------
    graph : gtsam.NonlinearFactorGraph
        Every factor, in the order added (a dropped one's slot is empty).
    initial : gtsam.Values
        Every variable at the guess it was added with.
    loops : list of tuple
        The loop closures (:data:`Loop`), in the order added.
    dropped : set of int
        Indices into :attr:`graph` of the factors a recovery dropped.
    solved : object or None
        The graph the last batch optimisation solved (None once a factor was added since).
    """

    def __init__(self) -> None:
        require_gtsam()
        self.graph = gtsam.NonlinearFactorGraph()
        self.initial = gtsam.Values()
        self.loops: list[Loop] = []
        self.dropped: set[int] = set()
        self.solved: object | None = None

    def add(self, factor: object) -> None:
        """Keep ``factor``."""
        self.solved = None
        self.graph.add(factor)

    def add_loop(self, a: int, b: int, relative: object, noise: object) -> None:
        """Note that the next factor added is the loop closure ``a -> b`` (``relative``, a
        ``gtsam.Pose2``; ``noise`` its model without the robust kernel)."""
        self.loops.append((a, b, relative, noise, self.graph.size()))

    def anchor(self, key: int, guess: object, sigmas: tuple[float, float, float]) -> None:
        """A prior holding variable ``key`` at its value in ``guess`` (``gtsam.Values``),
        standard deviations ``sigmas`` (a landmark's: the first two)."""
        self.solved = None
        if gtsam.Symbol(key).chr() == ord("x"):
            noise = diagonal_noise(*sigmas)
            self.graph.add(gtsam.PriorFactorPose2(key, guess.atPose2(key), noise))
        else:
            noise = gtsam.noiseModel.Isotropic.Sigma(2, sigmas[0])
            self.graph.add(gtsam.PriorFactorPoint2(key, guess.atPoint2(key), noise))

    def drop(self, factors: range) -> None:
        """Remove the factors at these indices (their slots stay, empty)."""
        self.dropped.update(factors)
        for f in factors:
            self.graph.remove(f)

    def dropped_loops(self) -> set[int]:
        """Indices into :attr:`loops` of the closures whose factor was dropped."""
        return {i for i, loop in enumerate(self.loops) if loop[4] in self.dropped}

    def active(self, extra: list[tuple[int, int, object, object]], dropped: set[int]) -> object:
        """Every factor but the dropped loop closures (indices into :attr:`loops`, then into
        ``extra``) and those a recovery dropped, plus the ``extra`` ones not dropped, robust."""
        drop = {self.loops[i][4] for i in dropped if i < len(self.loops)} | self.dropped
        graph = gtsam.NonlinearFactorGraph()
        for f in range(self.graph.size()):
            if f not in drop and self.graph.at(f) is not None:
                graph.add(self.graph.at(f))
        n_loops = len(self.loops)
        for i, (a, b, rel, noise) in enumerate(extra):
            if i + n_loops not in dropped:
                graph.add(gtsam.BetweenFactorPose2(X(a), X(b), rel, robust_noise(noise)))
        return graph

    def guess(self, estimate: NDArray[np.float64], values: object, n_landmarks: int) -> object:
        """Every variable at its latest estimate: keyframes from ``estimate`` (K, 3), landmarks
        from ``values`` where it holds them, the initial guess for the rest."""
        out = gtsam.Values(self.initial)
        for k in range(estimate.shape[0]):
            out.update(X(k), gtsam.Pose2(*map(float, estimate[k])))
        for k in range(n_landmarks):
            if values.exists(L(k)):
                out.update(L(k), values.atPoint2(L(k)))
        return out
