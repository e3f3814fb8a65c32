"""Planar poses (SE(2)): composition, inverse, relative pose, errors, and the one angle wrap.

A pose ``(x, y, theta)`` (metres, radians) is the rigid transform taking points of a child
frame (a sensor) into its parent frame: ``p_parent = R(theta)·p_child + (x, y)``.
:func:`wrap_angle` is the package's one angle wrap: Python code and the numba kernels
(:mod:`laser_corners.matching.core`) call the same function.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = [
    "MAX_COORDINATE",
    "Pose2D",
    "between_many",
    "check_pose",
    "compose",
    "compose_many",
    "distinct_poses",
    "invert",
    "invert_many",
    "pose_error",
    "pose_problem",
    "poses_apart",
    "relative_pose",
    "rotate_covariance",
    "rotation",
    "transform_points",
    "wrap_angle",
]

Pose2D = tuple[float, float, float]
"""A planar pose ``(x, y, theta)`` in metres and radians."""

TAU = 2.0 * math.pi

MAX_COORDINATE = 1e7
"""Largest plausible |x| or |y| of a pose, metres (10 000 km): beyond it a pose is a broken
record, and the grids and kernels would turn it into cell indices far outside any array."""


def pose_problem(pose: ArrayLike) -> str | None:
    """What is wrong with ``pose`` as a planar pose (not 3 numbers, not finite, |x| or |y|
    beyond :data:`MAX_COORDINATE`), or None when it is usable. Cheap: three numbers."""
    values = np.asarray(pose, dtype=np.float64).reshape(-1)
    if values.size != 3:
        return f"pose must be 3 numbers x, y, theta, got {values.size}"
    if not np.isfinite(values).all():
        return f"pose must be finite, got {tuple(float(v) for v in values)}"
    if max(abs(values[0]), abs(values[1])) > MAX_COORDINATE:
        return f"pose x, y must be within {MAX_COORDINATE:g} m, got {values[0]:g}, {values[1]:g}"
    return None


def check_pose(pose: ArrayLike, what: str = "pose") -> NDArray[np.float64]:
    """``pose`` as a float array of 3, or a ``ValueError`` naming ``what`` (see
    :func:`pose_problem`): the check at the door of the numba kernels, which would crash on a
    NaN or absurd pose instead of raising."""
    problem = pose_problem(pose)
    if problem is not None:
        raise ValueError(f"{what}: {problem}")
    return np.asarray(pose, dtype=np.float64).reshape(3)


@nb.njit(cache=True, nogil=True)
def wrap_angle(angle: float | NDArray[np.float64]) -> float | NDArray[np.float64]:
    """``angle`` (radians, a number or an array) wrapped to [-π, π]: ``angle - 2π·n`` with
    ``n`` the nearest integer to ``angle / 2π`` (ties to even, as ``math.remainder``).

    Examples
    --------
    >>> round(wrap_angle(3 * math.pi / 2), 12), round(wrap_angle(-0.25), 12)
    (-1.570796326795, -0.25)
    """
    return angle - TAU * np.rint(angle / TAU)


def rotation(theta: float) -> NDArray[np.float64]:
    """The 2x2 rotation matrix of angle ``theta`` (radians)."""
    c, s = math.cos(theta), math.sin(theta)
    return np.array([[c, -s], [s, c]])


def rotate_covariance(cov: ArrayLike, theta: float) -> NDArray[np.float64]:
    """A pose covariance (3, 3; x, y, heading) in a frame turned by ``theta``: ``R cov Rᵀ``
    with ``R`` the rotation of ``theta`` on x, y (a body-frame covariance into the frame of a
    pose of heading ``theta``; ``-theta`` for the way back)."""
    rot = np.eye(3)
    rot[:2, :2] = rotation(theta)
    return rot @ np.asarray(cov, dtype=np.float64) @ rot.T


def transform_points(xy: NDArray[np.float64], pose: Pose2D) -> NDArray[np.float64]:
    """Points ``xy`` (M, 2) moved by the rigid transform ``pose = (x, y, theta)``: sensor-frame
    points to the frame the sensor pose is given in."""
    return xy @ rotation(pose[2]).T + np.array([pose[0], pose[1]])


def compose(a: Pose2D, b: Pose2D) -> Pose2D:
    """``a ⊕ b``: the pose ``b`` (given in the frame of ``a``) in ``a``'s parent frame; the
    angle wrapped to [-π, π]."""
    c, s = math.cos(a[2]), math.sin(a[2])
    return (a[0] + c * b[0] - s * b[1], a[1] + s * b[0] + c * b[1], wrap_angle(a[2] + b[2]))


def invert(a: Pose2D) -> Pose2D:
    """``⊖ a``: the inverse rigid transform."""
    c, s = math.cos(a[2]), math.sin(a[2])
    return (-c * a[0] - s * a[1], s * a[0] - c * a[1], wrap_angle(-a[2]))


def pose_error(est: Pose2D, truth: Pose2D) -> tuple[float, float]:
    """Position error (metres) and absolute angle error (radians, in [0, π]) of ``est``."""
    return math.hypot(est[0] - truth[0], est[1] - truth[1]), abs(wrap_angle(est[2] - truth[2]))


def poses_apart(a: ArrayLike, b: ArrayLike, xy: float, yaw: float) -> bool:
    """Whether poses ``a`` and ``b`` (x, y, theta) differ by at least ``xy`` (m) in position
    or ``yaw`` (rad) in heading: two answers of a search that are not the same place.

    Examples
    --------
    >>> poses_apart((0.0, 0.0, 0.0), (0.5, 0.0, 0.1), 1.0, 0.3)
    False
    """
    dyaw = abs((a[2] - b[2] + math.pi) % (2 * math.pi) - math.pi)
    return bool(math.hypot(a[0] - b[0], a[1] - b[1]) >= xy or dyaw >= yaw)


def distinct_poses(
    poses: ArrayLike, order: ArrayLike, count: int, xy: float, yaw: float
) -> list[int]:
    """The best distinct answers of a search: going through ``poses`` (N, 3) in ``order``
    (best first), the indices of those :func:`poses_apart` from every one taken before, at
    most ``count``.

    Examples
    --------
    >>> distinct_poses([(0, 0, 0), (0.5, 0, 0), (2, 0, 0)], [0, 1, 2], 5, 1.0, 0.3)
    [0, 2]
    """
    poses = np.ascontiguousarray(np.asarray(poses, dtype=np.float64).reshape(-1, 3))
    order = np.ascontiguousarray(np.asarray(order, dtype=np.int64).reshape(-1))
    return _distinct(poses, order, int(count), float(xy), float(yaw)).tolist()


@nb.njit(cache=True, nogil=True)
def _distinct(
    poses: NDArray[np.float64], order: NDArray[np.int64], count: int, xy: float, yaw: float
) -> NDArray[np.int64]:
    """:func:`distinct_poses` compiled: the pairwise test of :func:`poses_apart` against every
    pose taken, O(len(order) * count) without a Python call per pair."""
    chosen = np.empty(min(count, order.shape[0]), dtype=np.int64)
    n = 0
    for i in order:
        if n == count:
            break
        apart = True
        for t in range(n):
            j = chosen[t]
            dyaw = abs((poses[i, 2] - poses[j, 2] + math.pi) % (2 * math.pi) - math.pi)
            if math.hypot(poses[i, 0] - poses[j, 0], poses[i, 1] - poses[j, 1]) < xy and dyaw < yaw:
                apart = False
                break
        if apart:
            chosen[n] = i
            n += 1
    return chosen[:n]


def relative_pose(a: Pose2D, b: Pose2D) -> Pose2D:
    """``⊖ a ⊕ b``: the pose ``b`` expressed in the frame of ``a``.

    Examples
    --------
    >>> [round(v, 6) for v in relative_pose((1.0, 0.0, math.pi / 2), (1.0, 2.0, math.pi / 2))]
    [2.0, 0.0, 0.0]
    """
    return compose(invert(a), b)


def compose_many(a: ArrayLike, b: ArrayLike) -> NDArray[np.float64]:
    """``a ⊕ b`` row by row on ``(N, 3)`` arrays of poses (either side may be one pose,
    shape (3,)): the vectorised :func:`compose`."""
    a = np.asarray(a, dtype=np.float64)
    b = np.asarray(b, dtype=np.float64)
    c, s = np.cos(a[..., 2]), np.sin(a[..., 2])
    x = a[..., 0] + c * b[..., 0] - s * b[..., 1]
    y = a[..., 1] + s * b[..., 0] + c * b[..., 1]
    yaw = wrap_angle(np.asarray(a[..., 2] + b[..., 2], dtype=np.float64))
    return np.stack(np.broadcast_arrays(x, y, yaw), axis=-1)


def invert_many(a: ArrayLike) -> NDArray[np.float64]:
    """``⊖ a`` row by row: the vectorised :func:`invert`."""
    a = np.asarray(a, dtype=np.float64)
    c, s = np.cos(a[..., 2]), np.sin(a[..., 2])
    x = -c * a[..., 0] - s * a[..., 1]
    y = s * a[..., 0] - c * a[..., 1]
    return np.stack([x, y, wrap_angle(np.asarray(-a[..., 2], dtype=np.float64))], axis=-1)


def between_many(a: ArrayLike, b: ArrayLike) -> NDArray[np.float64]:
    """``⊖ a ⊕ b`` row by row: the vectorised :func:`relative_pose` (``b`` in ``a``'s frame)."""
    return compose_many(invert_many(a), b)
