"""Exact ray casting of a 2D laser against line segments and circles (vectorised)."""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ["cast_circles", "cast_ranges"]


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

    Returns
    -------
    ndarray, shape (N,)
        Range of the first hit along each beam, ``inf`` when the beam hits nothing.
    """
    seg = np.asarray(segments, dtype=np.float64).reshape(-1, 4)
    ang = np.asarray(angles, dtype=np.float64) + pose[2]
    if seg.shape[0] == 0:
        return np.full(ang.shape, math.inf)
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
    return t.min(axis=1)


def cast_circles(
    circles: ArrayLike, pose: tuple[float, float, float], angles: ArrayLike
) -> NDArray[np.float64]:
    """Distance from ``pose`` along each beam to the nearest circle (``inf``: no hit).

    Parameters
    ----------
    circles : array_like, shape (M, 3)
        Circles ``cx, cy, radius`` in the world frame (the sensor is outside all of them).
    pose : tuple of float
        Sensor pose ``(x, y, theta)`` in the world frame.
    angles : array_like, shape (N,)
        Beam angles in the sensor frame, radians.
    """
    circ = np.asarray(circles, dtype=np.float64).reshape(-1, 3)
    ang = np.asarray(angles, dtype=np.float64) + pose[2]
    if circ.shape[0] == 0:
        return np.full(ang.shape, math.inf)
    dx = np.cos(ang)[:, None]
    dy = np.sin(ang)[:, None]
    wx = (pose[0] - circ[:, 0])[None, :]
    wy = (pose[1] - circ[:, 1])[None, :]
    # |w + t d|^2 = r^2  ->  t^2 + 2 b t + c = 0 with b = d.w, c = |w|^2 - r^2
    b = dx * wx + dy * wy
    c = wx * wx + wy * wy - (circ[:, 2] ** 2)[None, :]
    disc = b * b - c
    with np.errstate(invalid="ignore"):
        t = -b - np.sqrt(disc)
    t = np.where((disc >= 0.0) & (t > 0.0), t, math.inf)
    return t.min(axis=1)
