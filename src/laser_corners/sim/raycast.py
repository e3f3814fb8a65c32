"""Exact ray casting of a 2D laser against line segments (vectorised over beams and segments)."""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ["cast_ranges"]


def cast_ranges(
    segments: ArrayLike, pose: tuple[float, float, float], angles: ArrayLike
) -> NDArray[np.float64]:
    """Distance from ``pose`` along each beam to the nearest segment (``inf``: no hit).

    Parameters
    ----------
    segments : array_like, shape (S, 4)
        Segments ``x1, y1, x2, y2`` in the world frame.
    pose : tuple of float
        Sensor pose ``(x, y, theta)`` in the world frame.
    angles : array_like, shape (N,)
        Beam angles in the sensor frame, radians.
    """
    seg = np.asarray(segments, dtype=np.float64).reshape(-1, 4)
    ang = np.asarray(angles, dtype=np.float64) + pose[2]
    dx = np.cos(ang)[:, None]
    dy = np.sin(ang)[:, None]
    ex = (seg[:, 2] - seg[:, 0])[None, :]
    ey = (seg[:, 3] - seg[:, 1])[None, :]
    wx = (seg[:, 0] - pose[0])[None, :]
    wy = (seg[:, 1] - pose[1])[None, :]
    # ray p + t d meets segment a + u e:  t d - u e = w  (Cramer's rule)
    den = dx * (-ey) - dy * (-ex)
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (wx * (-ey) - wy * (-ex)) / den
        u = (dx * wy - dy * wx) / den
    hit = (np.abs(den) > 1e-15) & (t > 0.0) & (u >= 0.0) & (u <= 1.0)
    t = np.where(hit, t, math.inf)
    return t.min(axis=1) if seg.shape[0] else np.full(ang.shape, math.inf)
