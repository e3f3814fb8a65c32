"""The pose graph in gtsam: iSAM2 while running, an optional batch Levenberg-Marquardt at the end.

Keyframe ``k`` is the variable ``X(k)`` (``gtsam.Pose2``, the base pose in the map frame),
landmark ``l`` is ``L(l)`` (``gtsam.Point2``). Loop closures go in under a Cauchy kernel so a
wrong one that passed verification pulls with a bounded force instead of bending the map.

No optimiser error ends a run. When iSAM2 finds the system indeterminate (gtsam's
``RuntimeError``: an under-constrained or too poorly conditioned variable, e.g. a new segment
after a 1 km odometry jump), :meth:`Backend.update` rebuilds iSAM2 from every factor with the
variable the error names re-anchored by a prior at its current estimate (:data:`ANCHOR_SIGMAS`),
up to :data:`RECOVER_ATTEMPTS` times; when that does not help, the factors added since the last
good update are dropped and the new variables anchored where they were guessed. A failed batch
optimisation keeps the iSAM2 estimate. Each is counted (:attr:`Backend.counts`) and named in
:attr:`Backend.warnings`.
"""

from __future__ import annotations

import re

import numpy as np
from numpy.typing import NDArray

from laser_corners.errors import MissingDependencyError

try:
    import gtsam
except ImportError:  # pragma: no cover - the "slam" extra is missing
    gtsam = None

__all__ = ["Backend", "diagonal_noise", "require_gtsam", "robust_noise"]

HUBER_K = 1.345
"""Huber threshold (in standard deviations) of loop-closure factors."""
PRUNE_CHI = 3.0
"""A loop closure whose whitened residual after the batch optimisation exceeds this many
standard deviations contradicts the rest of the graph: it is dropped and the graph re-solved."""
PRUNE_ROUNDS = 3
"""Rounds of pruning and re-solving at most."""
ANCHOR_SIGMAS = (1.0, 1.0, 0.1)
"""Standard deviations (m, m, rad) of the prior that re-anchors a variable iSAM2 found
indeterminate (a landmark's: the first two)."""
RECOVER_ATTEMPTS = 3
"""Rebuilds of iSAM2, each with one more variable re-anchored, before the new factors are
dropped."""
FALLBACK_SIGMAS = (1.0, 1.0, 0.1)
"""Standard deviations of a keyframe covariance gtsam cannot compute (an ill-conditioned graph):
the tracking then trusts its scan alignment less, not more."""
COUNTS = (
    "optimiser_recoveries",
    "optimiser_anchors",
    "optimiser_factors_dropped",
    "optimiser_covariance_failures",
    "final_optimisation_failures",
)
"""Keys of :attr:`Backend.counts`."""
_SYMBOL = re.compile(r"Symbol: ([a-z])(\d+)")


def require_gtsam() -> None:
    """Raise :class:`MissingDependencyError` when gtsam is not installed."""
    if gtsam is None:
        raise MissingDependencyError(
            "laser_corners.slam needs gtsam: pip install 'laser-corners[slam]'"
        )


def X(k: int) -> int:
    """Key of keyframe ``k``."""
    return gtsam.symbol("x", k)


def L(k: int) -> int:
    """Key of landmark ``k``."""
    return gtsam.symbol("l", k)


def diagonal_noise(sx: float, sy: float, syaw: float) -> object:
    """A diagonal gtsam noise model with these standard deviations (x, y, yaw)."""
    return gtsam.noiseModel.Diagonal.Sigmas(np.array([sx, sy, syaw]))


def robust_noise(noise: object) -> object:
    """``noise`` under the Huber kernel of loop closures and landmark observations."""
    return gtsam.noiseModel.Robust.Create(gtsam.noiseModel.mEstimator.Huber.Create(HUBER_K), noise)


class Backend:
    """Incremental pose graph over keyframes (and landmarks)."""

    def __init__(self) -> None:
        require_gtsam()
        params = gtsam.ISAM2Params()
        params.setRelinearizeThreshold(0.01)
        params.relinearizeSkip = 1
        self._params = params
        self.isam = self._make_isam()
        self.graph = gtsam.NonlinearFactorGraph()  # every factor, for the batch and g2o
        self.initial = gtsam.Values()
        self._new = gtsam.NonlinearFactorGraph()
        self._new_values = gtsam.Values()
        self.n = 0
        self.n_landmarks = 0
        self.loops: list[tuple[int, int, object, object, int]] = []
        self.pruned: list[int] = []  # indices into ``loops`` dropped by :meth:`optimise`
        self.extra_pruned = 0  # extra factors of the last :meth:`optimise` dropped
        self._solved: object | None = None  # the graph the last :meth:`optimise` solved
        self._estimate = np.zeros((0, 3))
        self._values = gtsam.Values()
        self._stale = False
        self.counts = dict.fromkeys(COUNTS, 0)
        self.warnings: list[str] = []  # one line per recovery, for the summary
        self._dropped: set[int] = set()  # indices into ``graph`` of factors dropped
        self._good = 0  # ``graph.size()`` at the last update iSAM2 took

    def _make_isam(self) -> object:
        """A new, empty iSAM2 with this back end's parameters."""
        return gtsam.ISAM2(self._params)

    def _add(self, factor: object) -> None:
        self._solved = None
        self.graph.add(factor)
        self._new.add(factor)

    def add_keyframe(self, guess: NDArray[np.float64], prior: bool = False) -> int:
        """Add the next keyframe variable at ``guess``; the first one (or ``prior``) gets a
        prior (strong for the first, weak for a new odometry segment)."""
        k = self.n
        pose = gtsam.Pose2(*map(float, guess))
        self._new_values.insert(X(k), pose)
        self.initial.insert(X(k), pose)
        if k == 0 or prior:
            sig = (1e-3, 1e-3, 1e-4) if k == 0 else (100.0, 100.0, 3.0)
            self._add(gtsam.PriorFactorPose2(X(k), pose, diagonal_noise(*sig)))
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
            self.loops.append((a, b, rel, diagonal_noise(*sigmas), self.graph.size()))
        self._add(factor)

    def add_landmark(self, guess: NDArray[np.float64]) -> int:
        """Add a landmark variable at ``guess`` (map frame)."""
        k = self.n_landmarks
        point = np.asarray(guess, dtype=np.float64)
        self._new_values.insert(L(k), point)
        self.initial.insert(L(k), point)
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
            graph = self._solved if self._solved is not None else self.graph
            return gtsam.Marginals(graph, self.values)
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
        cost per keyframe does not grow with the map.
        """
        try:
            self.isam.update(self._new, self._new_values)
            for _ in range(extra_iterations):
                self.isam.update()
        except RuntimeError as exc:
            self._recover(exc)
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

    # ------------------------------------------------------------------ recovery
    def _recover(self, exc: RuntimeError) -> None:
        """iSAM2 refused the last update: rebuild it with the variable the error names
        re-anchored, then (if that fails) without the factors of the failed update.

        Raises
        ------
        RuntimeError
            Even the graph of the last good update with the new variables anchored is
            indeterminate (a caller keeps what was mapped, see ``slam.run``).
        """
        self.counts["optimiser_recoveries"] += 1
        what = _first_line(exc)
        anchored: list[int] = []
        for _ in range(RECOVER_ATTEMPTS):
            key = self._culprit(exc)
            if key in anchored:
                break
            self._anchor(key, self._guess())
            anchored.append(key)
            try:
                self._rebuild()
            except RuntimeError as again:
                exc = again
                continue
            names = ", ".join(gtsam.Symbol(k).string() for k in anchored)
            self.warnings.append(f"optimiser: {what}; re-anchored {names} and went on")
            return
        failed = range(self._good, self.graph.size())
        self._dropped.update(failed)
        for f in failed:
            self.graph.remove(f)  # its slot stays (empty): the indices in ``loops`` hold
        guess = self._guess()
        for key in self._new_values.keys():
            self._anchor(key, guess)
        self._rebuild()
        n = len(failed) - len(anchored)
        self.counts["optimiser_factors_dropped"] += n
        self.warnings.append(
            f"optimiser: {what}; dropped the {n} factors of that update and went on"
        )

    def _culprit(self, exc: RuntimeError) -> int:
        """The variable gtsam's message names (``Symbol: x12``), else the newest keyframe."""
        found = _SYMBOL.search(str(exc))
        if found is not None and found.group(1) in "xl":
            return gtsam.symbol(found.group(1), int(found.group(2)))
        return X(max(self.n - 1, 0))

    def _anchor(self, key: int, guess: object) -> None:
        """A prior (:data:`ANCHOR_SIGMAS`) holding ``key`` at ``guess``'s value (counted)."""
        self._solved = None
        if gtsam.Symbol(key).chr() == ord("x"):
            noise = diagonal_noise(*ANCHOR_SIGMAS)
            self.graph.add(gtsam.PriorFactorPose2(key, guess.atPose2(key), noise))
        else:
            noise = gtsam.noiseModel.Isotropic.Sigma(2, ANCHOR_SIGMAS[0])
            self.graph.add(gtsam.PriorFactorPoint2(key, guess.atPoint2(key), noise))
        self.counts["optimiser_anchors"] += 1

    def _guess(self) -> object:
        """Every variable at its latest estimate (the initial guess where there is none)."""
        values = gtsam.Values(self.initial)
        for k in range(min(self._estimate.shape[0], self.n)):
            values.update(X(k), gtsam.Pose2(*map(float, self._estimate[k])))
        for k in range(self.n_landmarks):
            if self._values.exists(L(k)):
                values.update(L(k), self._values.atPoint2(L(k)))
        return values

    def _rebuild(self) -> None:
        """A new iSAM2 over every factor not dropped, from :meth:`_guess`."""
        isam = self._make_isam()
        isam.update(self._active([], set()), self._guess())
        self.isam = isam

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
            self.counts["optimiser_covariance_failures"] += 1
            return np.diag(np.square(FALLBACK_SIGMAS))

    def optimise(
        self,
        extra: list[tuple[int, int, NDArray[np.float64], tuple[float, float, float]]] | None = None,
        start: object | None = None,
    ) -> tuple[object, object]:
        """Batch Levenberg-Marquardt from ``start`` (default: the iSAM2 estimate), then the
        loop closures that the result contradicts (residual > :data:`PRUNE_CHI` sigmas)
        dropped and the graph solved again, up to :data:`PRUNE_ROUNDS` times (a dropped
        closure can have hidden another): (graph, values).

        ``extra``: relative-pose measurements ``(a, b, relative, sigmas)`` for this solve only
        (the refinement pass, :mod:`.refine`), robust and pruned as the loop closures; not
        put into iSAM2. Closures dropped once stay dropped (:attr:`pruned`); the extra ones
        dropped are counted in :attr:`extra_pruned`.
        """
        params = gtsam.LevenbergMarquardtParams()
        params.setMaxIterations(50)
        checked = [(a, b, rel, noise) for a, b, rel, noise, _ in self.loops]
        for a, b, relative, sigmas in extra or []:
            checked.append((a, b, gtsam.Pose2(*map(float, relative)), diagonal_noise(*sigmas)))
        n_loops = len(self.loops)
        dropped = set(self.pruned)
        dropped.update(i for i, loop in enumerate(self.loops) if loop[4] in self._dropped)
        values = start if start is not None else self.isam.calculateEstimate()
        for round_ in range(PRUNE_ROUNDS + 1):
            graph = self._active(checked[n_loops:], dropped)
            try:
                values = self._solve(graph, values, params)
            except RuntimeError as exc:
                self.counts["final_optimisation_failures"] += 1
                self.warnings.append(
                    f"batch optimisation: {_first_line(exc)}; the map keeps the "
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
        self.pruned = sorted(i for i in dropped if i < n_loops)
        self.extra_pruned = sum(1 for i in dropped if i >= n_loops)
        self._solved = graph
        self._values = values
        self._stale = False
        self._estimate = gtsam.utilities.extractPose2(values)
        return graph, values

    @staticmethod
    def _solve(graph: object, values: object, params: object) -> object:
        """Levenberg-Marquardt on ``graph`` from ``values``."""
        return gtsam.LevenbergMarquardtOptimizer(graph, values, params).optimize()

    def _active(self, extra: list[tuple[int, int, object, object]], dropped: set[int]) -> object:
        """Every factor but the dropped loop closures (indices into :attr:`loops`, then into
        ``extra``) and those a recovery dropped, plus the ``extra`` ones not dropped, robust."""
        drop = {self.loops[i][4] for i in dropped if i < len(self.loops)} | self._dropped
        graph = gtsam.NonlinearFactorGraph()
        for f in range(self.graph.size()):
            if f not in drop and self.graph.at(f) is not None:
                graph.add(self.graph.at(f))
        n_loops = len(self.loops)
        for i, (a, b, rel, noise) in enumerate(extra):
            if i + n_loops not in dropped:
                graph.add(gtsam.BetweenFactorPose2(X(a), X(b), rel, robust_noise(noise)))
        return graph

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


def _first_line(exc: BaseException) -> str:
    """gtsam's message in one line (it spans a paragraph)."""
    text = " ".join(str(exc).split())
    head = text.split(".")[0] if text else type(exc).__name__
    return head[:200]
