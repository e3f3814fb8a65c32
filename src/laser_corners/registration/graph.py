"""The pose graph's vocabulary over gtsam, shared by ``slam`` and ``localise``: variable keys,
noise models and the one robust kernel.

Keyframe ``k`` is the variable ``X(k)`` (``gtsam.Pose2``), landmark ``l`` is ``L(l)``
(``gtsam.Point2``). Loop closures and landmark observations are robust: a Huber kernel with
threshold :data:`HUBER_K` standard deviations (a bounded pull for a wrong closure that slipped
through verification); odometry and scan-matching links are Gaussian.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from laser_corners.errors import InputError, MissingDependencyError, first_line

try:
    import gtsam
except ImportError:  # pragma: no cover - the "slam" extra is missing
    gtsam = None

__all__ = [
    "HUBER_K",
    "L",
    "PoseGraph",
    "X",
    "diagonal_noise",
    "pose_graph_edges",
    "read_g2o_edges",
    "require_gtsam",
    "robust_noise",
]

HUBER_K = 1.345
"""Huber threshold (in standard deviations) of loop-closure factors."""


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


@dataclass(frozen=True)
class PoseGraph:
    """The relative-pose factors between a map's keyframes (its ``graph.g2o``).

    Attributes
    ----------
    pairs : ndarray of int, shape (E, 2)
        Keyframes ``a, b`` of each edge (``X(a)^-1 X(b) = relative``).
    relative : ndarray, shape (E, 3)
        The measured relative poses (x, y, yaw).
    sigmas : ndarray, shape (E, 3)
        Their standard deviations (square roots of the covariance's diagonal).
    """

    pairs: NDArray[np.int64]
    relative: NDArray[np.float64]
    sigmas: NDArray[np.float64]

    def chain(self) -> NDArray[np.bool_]:
        """Which edges link a keyframe to the one before (the first such edge of each
        keyframe: the odometry / scan-matching chain); the others are loop closures."""
        out = np.zeros(len(self.pairs), dtype=bool)
        seen: set[int] = set()
        for i, (a, b) in enumerate(self.pairs):
            if b == a + 1 and b not in seen:
                out[i] = True
                seen.add(int(b))
        return out


def pose_graph_edges(graph: object) -> PoseGraph:
    """The relative-pose factors (``BetweenFactorPose2``) of a gtsam graph (``readG2o``'s) as
    a :class:`PoseGraph`; other factors are left out."""
    pairs, relative, sigmas = [], [], []
    for i in range(graph.size()):
        factor = graph.at(i)
        if not isinstance(factor, gtsam.BetweenFactorPose2):
            continue
        rel = factor.measured()
        cov = np.linalg.inv(factor.noiseModel().R().T @ factor.noiseModel().R())
        pairs.append(list(factor.keys()))
        relative.append((rel.x(), rel.y(), rel.theta()))
        sigmas.append(np.sqrt(np.diag(cov)))
    return PoseGraph(
        np.asarray(pairs, dtype=np.int64).reshape(-1, 2),
        np.asarray(relative, dtype=np.float64).reshape(-1, 3),
        np.asarray(sigmas, dtype=np.float64).reshape(-1, 3),
    )


def read_g2o_edges(path: Path, poses: NDArray[np.float64], tolerance: float) -> PoseGraph:
    """The relative-pose edges of the g2o file ``path`` over the keyframes ``poses`` (K, 3):
    its vertices must be ``0 .. K - 1``, each within ``tolerance`` (m, rad) of its pose.

    Raises
    ------
    InputError
        The file is unreadable, or its vertices are not the keyframes (another count, a
        vertex away from its keyframe's pose: files of two runs), one line.
    """
    require_gtsam()
    try:
        graph, values = gtsam.readG2o(str(path), False)
        found = gtsam.utilities.extractPose2(values).reshape(-1, 3)
    except (RuntimeError, ValueError, IndexError) as exc:
        raise InputError(f"{path}: unreadable ({first_line(exc)})") from None
    keys = np.array(sorted(values.keys()), dtype=np.int64)
    k = len(poses)
    if len(keys) != k or not np.array_equal(keys, np.arange(k)):
        raise InputError(f"{path}: {len(keys)} vertices, the map has {k} keyframes")
    gap = np.abs(found - poses)
    gap[:, 2] = np.abs(np.angle(np.exp(1j * gap[:, 2])))
    if gap.size and gap.max() > tolerance:
        raise InputError(
            f"{path}: vertex {int(gap.max(axis=1).argmax())} is not at its keyframe's pose "
            "in the map (files of two runs?)"
        )
    return pose_graph_edges(graph)
