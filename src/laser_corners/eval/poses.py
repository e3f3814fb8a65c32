"""Planar poses for evaluation: TUM trajectories, interpolation at scan stamps, relations.

* TUM trajectory files hold one pose per line, ``t x y z qx qy qz qw`` (``#`` comments); only
  x, y and the yaw of the quaternion are used.
* ``.relations`` files (Kuemmerle et al. 2009 SLAM benchmark) hold ground-truth relative poses
  between two scan stamps, ``t1 t2 x y z roll pitch yaw``: the pose at ``t2`` expressed in the
  frame of the pose at ``t1``.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike, NDArray

from laser_corners.io.trajectory import read_numeric_table
from laser_corners.io.trajectory import read_tum as read_planar_tum
from laser_corners.pose import wrap_angle
from laser_corners.scan import LaserScan, Pose2D

__all__ = [
    "Relation",
    "Trajectory",
    "interpolate_poses",
    "read_relations",
    "read_tum",
    "with_poses",
]


@dataclass(frozen=True)
class Trajectory:
    """Timestamped planar poses, sorted by time.

    Attributes
    ----------
    stamps : ndarray, shape (T,)
        Seconds, strictly increasing.
    poses : ndarray, shape (T, 3)
        ``x, y, theta``.
    """

    stamps: NDArray[np.float64]
    poses: NDArray[np.float64]

    def __len__(self) -> int:
        return int(self.stamps.shape[0])


def read_tum(path: str | Path) -> Trajectory:
    """Read a TUM trajectory (``t x y z qx qy qz qw`` per line) as planar poses.

    Raises
    ------
    InputError
        Missing file, a line without 8 numbers, or no poses.
    """
    stamps, poses = read_planar_tum(path)
    order = np.argsort(stamps, kind="stable")
    stamps, poses = stamps[order], poses[order]
    keep = np.r_[True, np.diff(stamps) > 0]  # drop repeated stamps
    return Trajectory(stamps[keep], poses[keep])


def interpolate_poses(
    trajectory: Trajectory, stamps: ArrayLike, max_gap: float = 0.5
) -> NDArray[np.float64]:
    """Poses at ``stamps`` by linear interpolation (yaw along the shorter arc).

    Parameters
    ----------
    trajectory : Trajectory
        The poses.
    stamps : array_like, shape (M,)
        Query times, seconds.
    max_gap : float
        A query is answered only when it lies between two trajectory stamps at most
        ``max_gap`` seconds apart (or within ``max_gap / 2`` of an end point, which is then
        used as is); otherwise its row is NaN.

    Returns
    -------
    ndarray, shape (M, 3)
    """
    t = np.asarray(stamps, dtype=np.float64).reshape(-1)
    ts = trajectory.stamps
    ps = trajectory.poses
    out = np.full((t.shape[0], 3), np.nan)
    if len(ts) == 0:
        return out
    hi = np.searchsorted(ts, t, side="left")
    for i, (ti, h) in enumerate(zip(t, hi, strict=True)):
        if h < len(ts) and ts[h] == ti:
            out[i] = ps[h]
            continue
        if h == 0 or h == len(ts):
            end = 0 if h == 0 else len(ts) - 1
            if abs(ts[end] - ti) <= max_gap / 2:
                out[i] = ps[end]
            continue
        t0, t1 = ts[h - 1], ts[h]
        if t1 - t0 > max_gap:
            continue
        w = (ti - t0) / (t1 - t0)
        p0, p1 = ps[h - 1], ps[h]
        dyaw = wrap_angle(p1[2] - p0[2])
        out[i] = (
            p0[0] + w * (p1[0] - p0[0]),
            p0[1] + w * (p1[1] - p0[1]),
            wrap_angle(p0[2] + w * dyaw),
        )
    return out


def with_poses(scans: Sequence[LaserScan], poses: ArrayLike) -> list[LaserScan]:
    """Copies of ``scans`` carrying ``poses`` (rows of NaN give ``pose=None``)."""
    table = np.asarray(poses, dtype=np.float64).reshape(-1, 3)
    if table.shape[0] != len(scans):
        raise ValueError(f"{len(scans)} scans but {table.shape[0]} poses")
    out = []
    for scan, row in zip(scans, table, strict=True):
        pose = tuple(float(v) for v in row) if np.all(np.isfinite(row)) else None
        out.append(replace(scan, pose=pose))
    return out


@dataclass(frozen=True)
class Relation:
    """A ground-truth relative pose: the sensor at ``t2`` in the frame of the sensor at ``t1``."""

    t1: float
    t2: float
    pose: Pose2D


def read_relations(path: str | Path) -> list[Relation]:
    """Read a ``.relations`` file (``t1 t2 x y z roll pitch yaw`` per line).

    Raises
    ------
    InputError
        Missing file, a line without 8 numbers, or no relations.
    """
    table = read_numeric_table(path, "t1 t2 x y z roll pitch yaw", "relations")
    return [
        Relation(float(r[0]), float(r[1]), (float(r[2]), float(r[3]), float(r[7]))) for r in table
    ]
