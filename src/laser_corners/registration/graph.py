"""The pose graph's vocabulary over gtsam, shared by ``slam`` and ``localise``: variable keys,
noise models and the one robust kernel.

Keyframe ``k`` is the variable ``X(k)`` (``gtsam.Pose2``), landmark ``l`` is ``L(l)``
(``gtsam.Point2``). Loop closures and landmark observations are robust: a Huber kernel with
threshold :data:`HUBER_K` standard deviations (a bounded pull for a wrong closure that slipped
through verification); odometry and scan-matching links are Gaussian.
"""

from __future__ import annotations

import numpy as np

from laser_corners.errors import MissingDependencyError

try:
    import gtsam
except ImportError:  # pragma: no cover - the "slam" extra is missing
    gtsam = None

__all__ = ["HUBER_K", "L", "X", "diagonal_noise", "require_gtsam", "robust_noise"]

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
