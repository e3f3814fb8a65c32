"""Vectorised SE(2) helpers on ``(N, 3)`` arrays of ``(x, y, yaw)`` poses."""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ["between", "between_many", "compose", "compose_many", "invert", "invert_many", "wrap"]


def wrap(angle: ArrayLike) -> NDArray[np.float64]:
    """Angles wrapped to [-pi, pi)."""
    return (np.asarray(angle, dtype=np.float64) + np.pi) % (2 * np.pi) - np.pi


def compose_many(a: ArrayLike, b: ArrayLike) -> NDArray[np.float64]:
    """``a ∘ b`` row by row (either side may be one pose, shape (3,))."""
    a = np.asarray(a, dtype=np.float64)
    b = np.asarray(b, dtype=np.float64)
    c, s = np.cos(a[..., 2]), np.sin(a[..., 2])
    x = a[..., 0] + c * b[..., 0] - s * b[..., 1]
    y = a[..., 1] + s * b[..., 0] + c * b[..., 1]
    return np.stack(np.broadcast_arrays(x, y, wrap(a[..., 2] + b[..., 2])), axis=-1)


def invert_many(a: ArrayLike) -> NDArray[np.float64]:
    """``a^-1`` row by row."""
    a = np.asarray(a, dtype=np.float64)
    c, s = np.cos(a[..., 2]), np.sin(a[..., 2])
    x = -c * a[..., 0] - s * a[..., 1]
    y = s * a[..., 0] - c * a[..., 1]
    return np.stack([x, y, wrap(-a[..., 2])], axis=-1)


def between_many(a: ArrayLike, b: ArrayLike) -> NDArray[np.float64]:
    """``a^-1 ∘ b`` row by row: the pose of ``b`` in the frame of ``a``."""
    return compose_many(invert_many(a), b)


def compose(a: NDArray[np.float64], b: NDArray[np.float64]) -> NDArray[np.float64]:
    """``a ∘ b`` of two single poses (scalar maths: cheaper than :func:`compose_many`)."""
    c, s = math.cos(a[2]), math.sin(a[2])
    yaw = (a[2] + b[2] + math.pi) % (2 * math.pi) - math.pi
    return np.array([a[0] + c * b[0] - s * b[1], a[1] + s * b[0] + c * b[1], yaw])


def between(a: NDArray[np.float64], b: NDArray[np.float64]) -> NDArray[np.float64]:
    """``a^-1 ∘ b`` of two single poses."""
    c, s = math.cos(a[2]), math.sin(a[2])
    dx, dy = b[0] - a[0], b[1] - a[1]
    yaw = (b[2] - a[2] + math.pi) % (2 * math.pi) - math.pi
    return np.array([c * dx + s * dy, -s * dx + c * dy, yaw])


def invert(a: NDArray[np.float64]) -> NDArray[np.float64]:
    """``a^-1`` of a single pose."""
    c, s = math.cos(a[2]), math.sin(a[2])
    return np.array([-c * a[0] - s * a[1], s * a[0] - c * a[1], -a[2]])
