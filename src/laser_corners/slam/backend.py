"""The pose graph in gtsam: iSAM2 while running, an optional batch Levenberg-Marquardt at the end.

Keyframe ``k`` is the variable ``X(k)`` (``gtsam.Pose2``, the base pose in the map frame),
landmark ``l`` is ``L(l)`` (``gtsam.Point2``). Loop closures go in under a robust kernel so a
wrong one that passed verification pulls with a bounded force instead of bending the map.

:class:`Backend` runs iSAM2 over the factors; its parts: :class:`~.factors.FactorLog` (every
factor, for the batch and g2o), :class:`~.recovery.Recovery` (an update iSAM2 refused) and
:func:`~.batch.optimise` (the batch optimisation and its pruning).

No optimiser error ends a run. When iSAM2 finds the system indeterminate, :meth:`Backend.update`
rebuilds it (:mod:`.recovery`); a failed batch optimisation keeps the iSAM2 estimate. Each is
counted (:attr:`Backend.counts`) and named in :attr:`Backend.warnings`.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray

from laser_corners.registration.graph import L, X, diagonal_noise, require_gtsam, robust_noise
from laser_corners.slam.batch import Extra, levenberg_marquardt, optimise
from laser_corners.slam.counts import SlamCounts
from laser_corners.slam.factors import FactorLog
from laser_corners.slam.recovery import Recovery

try:
    import gtsam
except ImportError:  # pragma: no cover - the "slam" extra is missing
    gtsam = None

__all__ = ["Backend", "new_isam"]

FALLBACK_SIGMAS = (1.0, 1.0, 0.1)
"""Standard deviations of a keyframe covariance gtsam cannot compute (an ill-conditioned graph):
the tracking then trusts its scan alignment less, not more."""


def new_isam() -> object:
    """A new, empty iSAM2 with the back end's parameters (the default ``make_isam``)."""
    params = gtsam.ISAM2Params()
    params.setRelinearizeThreshold(0.01)
    params.relinearizeSkip = 1
    return gtsam.ISAM2(params)


class Backend:
    """Incremental pose graph over keyframes (and landmarks).

    Parameters
    ----------
    counts : SlamCounts, optional
        The run's counters (the ``optimiser_*`` ones and ``final_optimisation_failures`` are
        counted here); default: a record of its own.
    make_isam : callable, optional
        ``make_isam() -> gtsam.ISAM2``: every iSAM2 the back end uses, the first and a
        recovery's (default :func:`new_isam`; a test hands in one that fails).
    solve : callable, optional
        ``solve(graph, values, params) -> values`` of the batch optimisation (default
        :func:`~.batch.levenberg_marquardt`).
    """

    def __init__(
        self,
        counts: SlamCounts | None = None,
        make_isam: Callable[[], object] = new_isam,
        solve: Callable[[object, object, object], object] = levenberg_marquardt,
    ) -> None:
        require_gtsam()
        self.counts = counts if counts is not None else SlamCounts()
        self.warnings: list[str] = []  # one line per recovery, for the summary
        self.factors = FactorLog()
        self.recovery = Recovery(make_isam, self.counts, self.warnings)
        self.solve = solve
        self.isam = make_isam()
        self._new = gtsam.NonlinearFactorGraph()
        self._new_values = gtsam.Values()
        self.n = 0
        self.n_landmarks = 0
        self.pruned: list[int] = []  # indices into ``loops`` dropped by :meth:`optimise`
        self.extra_pruned = 0  # extra factors of the last :meth:`optimise` dropped
        self._estimate = np.zeros((0, 3))
        self._values = gtsam.Values()
        self._stale = False
        self._good = 0  # ``graph.size()`` at the last update iSAM2 took

    @property
    def graph(self) -> object:
        """Every factor (``gtsam.NonlinearFactorGraph``), for the batch and g2o."""
        return self.factors.graph

    @property
    def loops(self) -> list[tuple[int, int, object, object, int]]:
        """The loop closures, in the order added (:attr:`.FactorLog.loops`)."""
        return self.factors.loops

    def _add(self, factor: object) -> None:
        self.factors.add(factor)
        self._new.add(factor)

    def add_keyframe(
        self,
        guess: NDArray[np.float64],
        prior: bool = False,
        sigmas: tuple[float, float, float] | None = None,
    ) -> int:
        """Add the next keyframe variable at ``guess``; the first one (or ``prior``) gets a
        prior (strong for the first, weak for a new odometry segment); ``sigmas``: a prior of
        these standard deviations instead (a prior map's keyframe, an initial pose)."""
        k = self.n
        pose = gtsam.Pose2(*map(float, guess))
        self._new_values.insert(X(k), pose)
        self.factors.initial.insert(X(k), pose)
        if sigmas is None and (k == 0 or prior):
            sigmas = (1e-3, 1e-3, 1e-4) if k == 0 else (100.0, 100.0, 3.0)
        if sigmas is not None:
            self._add(gtsam.PriorFactorPose2(X(k), pose, diagonal_noise(*sigmas)))
        self.n += 1
        return k

    def add_between(
        self,
        a: int,
        b: int,
        relative: NDArray[np.float64],
        sigmas: tuple[float, float, float],
        robust: bool = False,
    ) -> None:
        """A relative-pose factor ``X(a)^-1 X(b) = relative``; ``robust``: a loop closure,
        under a Huber kernel (bounded pull), kept apart so :meth:`optimise` can prune it."""
        noise = robust_noise(diagonal_noise(*sigmas)) if robust else diagonal_noise(*sigmas)
        rel = gtsam.Pose2(*map(float, relative))
        factor = gtsam.BetweenFactorPose2(X(a), X(b), rel, noise)
        if robust:
            self.factors.add_loop(a, b, rel, diagonal_noise(*sigmas))
        self._add(factor)

    def add_landmark(self, guess: NDArray[np.float64]) -> int:
        """Add a landmark variable at ``guess`` (map frame)."""
        k = self.n_landmarks
        point = np.asarray(guess, dtype=np.float64)
        self._new_values.insert(L(k), point)
        self.factors.initial.insert(L(k), point)
        self.n_landmarks += 1
        return k

    def add_observation(
        self,
        keyframe: int,
        landmark: int,
        bearing: float,
        rng: float,
        cov: NDArray[np.float64],
    ) -> None:
        """A bearing-range factor from keyframe ``keyframe`` (base frame) to ``landmark``,
        noise ``cov`` (2x2, bearing rad and range m) under a Huber kernel."""
        noise = robust_noise(
            gtsam.noiseModel.Gaussian.Covariance(np.asarray(cov, dtype=np.float64))
        )
        self._add(
            gtsam.BearingRangeFactor2D(
                X(keyframe), L(landmark), gtsam.Rot2(float(bearing)), float(rng), noise
            )
        )

    def marginals(self) -> object | None:
        """``gtsam.Marginals`` of the current graph at the current estimate (None when the
        graph cannot be factorised, e.g. an under-constrained landmark)."""
        try:
            solved = self.factors.solved
            return gtsam.Marginals(solved if solved is not None else self.graph, self.values)
        except RuntimeError:
            return None

    @staticmethod
    def landmark_covariance(marginals: object, landmark: int) -> NDArray[np.float64]:
        """Marginal covariance (2x2, map frame) of ``landmark`` from ``marginals``."""
        try:
            return np.asarray(marginals.marginalCovariance(L(landmark)))
        except RuntimeError:
            return np.full((2, 2), np.nan)

    def update(
        self, extra_iterations: int = 0, full: bool = True, recent: int = 0
    ) -> NDArray[np.float64]:
        """Run iSAM2 on what was added; the keyframe estimates, shape (K, 3).

        With ``full`` False only the last ``recent`` keyframes are read back from iSAM2 (the
        others keep their last estimate: without a loop closure they barely move), so the
        cost per keyframe does not grow with the map. An update iSAM2 refuses is recovered
        (:class:`~.recovery.Recovery`; it raises ``RuntimeError`` when even that fails).
        """
        try:
            self.isam.update(self._new, self._new_values)
            for _ in range(extra_iterations):
                self.isam.update()
        except RuntimeError as exc:
            guess = self._guess()
            self.isam = self.recovery.recover(
                exc, self.factors, guess, self._new_values.keys(), self._good, self.n - 1
            )
            full = True  # the rebuilt iSAM2 may have moved every estimate
        self._new = gtsam.NonlinearFactorGraph()
        self._new_values = gtsam.Values()
        self._good = self.graph.size()
        old = self._estimate.shape[0]
        if full or old == 0:
            self._values = self.isam.calculateEstimate()
            self._estimate = gtsam.utilities.extractPose2(self._values)
            self._stale = False
            return self._estimate
        estimate = np.empty((self.n, 3))
        estimate[:old] = self._estimate
        for k in range(max(0, self.n - max(recent, 1) - (self.n - old)), self.n):
            pose = self.isam.calculateEstimatePose2(X(k))
            estimate[k] = (pose.x(), pose.y(), pose.theta())
        self._estimate = estimate
        self._stale = True
        return estimate

    def _guess(self) -> object:
        """Every variable at its latest estimate (the initial guess where there is none)."""
        estimate = self._estimate[: min(self._estimate.shape[0], self.n)]
        return self.factors.guess(estimate, self._values, self.n_landmarks)

    def landmark_estimates(self) -> NDArray[np.float64]:
        """Current landmark positions, shape (L, 2)."""
        if self.n_landmarks == 0:
            return np.zeros((0, 2))
        return gtsam.utilities.extractPoint2(self.values)

    def marginal_xy_sigma(self, keyframe: int) -> float:
        """Largest standard deviation (m) of keyframe ``keyframe``'s position (iSAM2 marginal)."""
        cov = self.covariance(keyframe)
        return float(np.sqrt(max(np.linalg.eigvalsh(cov[:2, :2])[-1], 0.0)))

    def covariance(self, keyframe: int) -> NDArray[np.float64]:
        """Marginal covariance (3x3, base frame x, y, yaw) of keyframe ``keyframe``; one of
        :data:`FALLBACK_SIGMAS` (counted) when gtsam cannot compute it."""
        try:
            return np.asarray(self.isam.marginalCovariance(X(keyframe)))
        except RuntimeError:
            self.counts.optimiser_covariance_failures += 1
            return np.diag(np.square(FALLBACK_SIGMAS))

    def optimise(
        self, extra: list[Extra] | None = None, start: object | None = None
    ) -> tuple[object, object]:
        """Batch Levenberg-Marquardt from ``start`` (default: the iSAM2 estimate), pruning
        the loop closures the result contradicts (:func:`~.batch.optimise`): (graph, values).

        ``extra``: relative-pose measurements ``(a, b, relative, sigmas)`` for this solve only
        (the refinement pass, :mod:`.refine`), robust and pruned as the loop closures; not
        put into iSAM2. Closures dropped once stay dropped (:attr:`pruned`); the extra ones
        dropped are counted in :attr:`extra_pruned`.
        """
        values = start if start is not None else self.isam.calculateEstimate()
        found = optimise(
            self.factors, values, self.pruned, self.counts, self.warnings, extra, self.solve
        )
        self.pruned, self.extra_pruned = found.pruned, found.extra_pruned
        self.factors.solved = found.graph
        self._values = found.values
        self._stale = False
        self._estimate = gtsam.utilities.extractPose2(found.values)
        return found.graph, found.values

    @property
    def values(self) -> object:
        """The latest estimate as gtsam ``Values``."""
        if self._stale:
            self._values = self.isam.calculateEstimate()
            self._stale = False
        return self._values

    @property
    def estimate(self) -> NDArray[np.float64]:
        """The latest keyframe estimates, shape (K, 3)."""
        return self._estimate
