"""The relation metric of Kümmerle et al. (2009), as Cartographer's ``compute_relations_metrics``.

A ``.relations`` file lists pairs of stamps with the relative pose a human-verified alignment
gave between them (``t1 t2 x y z roll pitch yaw``). A trajectory is judged by the error of
its own relative pose between the same stamps: the poses are interpolated at ``t1`` and
``t2`` (x, y linearly, the unwrapped yaw linearly), ``actual = pose1^-1 ∘ pose2`` and
``error = expected^-1 ∘ actual``; the translational error is ``|error.t|`` (m), the rotational
one ``|error.yaw|``. A relation with a stamp outside the trajectory is not covered.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike, NDArray

from laser_corners.io.trajectory import read_numeric_table
from laser_corners.pose import between_many, compose_many, invert_many, wrap_angle
from laser_corners.slam.result import SlamResult

__all__ = [
    "RelationMetrics",
    "closure_consistency",
    "no_coverage",
    "read_relations",
    "relation_metrics",
]


def read_relations(path: str | Path) -> NDArray[np.float64]:
    """Read a Freiburg ``.relations`` file into an ``(R, 5)`` array ``t1, t2, dx, dy, dyaw``.

    Raises
    ------
    InputError
        Missing file, or ``FILE:LINE`` for a line that is not 8 finite numbers
        (``t1 t2 x y z roll pitch yaw``); a file without relations.
    """
    table = read_numeric_table(path, "t1 t2 x y z roll pitch yaw", "relations")
    return table[:, [0, 1, 2, 3, 7]].copy()


def no_coverage(stamps: ArrayLike, relations: ArrayLike) -> str | None:
    """When a trajectory covers no relation at all (relations of another recording, another
    clock): a phrase giving both time spans; None when it covers one."""
    stamps = np.asarray(stamps, dtype=np.float64).reshape(-1)
    rel = np.asarray(relations, dtype=np.float64).reshape(-1, 5)
    if relation_metrics(stamps, np.zeros((stamps.size, 3)), rel).n_covered or not rel.size:
        return None
    span = f"{stamps.min():.3f} to {stamps.max():.3f} s" if stamps.size else "no stamps"
    return (
        f"no relation covered by the trajectory (its stamps {span}; the relations' "
        f"{rel[:, :2].min():.3f} to {rel[:, :2].max():.3f} s): relations of another recording?"
    )


@dataclass
class RelationMetrics:
    """Mean ± std of the relation errors (m, m², degrees, degrees²) over the covered relations."""

    n_total: int
    n_covered: int
    trans_mean: float
    trans_std: float
    trans2_mean: float
    trans2_std: float
    rot_deg_mean: float
    rot_deg_std: float
    rot2_mean: float
    rot2_std: float

    def to_dict(self) -> dict[str, float | int]:
        """The metrics as a plain dict (JSON-ready)."""
        return asdict(self)


def _interpolate(
    stamps: NDArray[np.float64], poses: NDArray[np.float64], at: NDArray[np.float64]
) -> NDArray[np.float64]:
    yaw = np.unwrap(poses[:, 2])
    return np.stack(
        [
            np.interp(at, stamps, poses[:, 0]),
            np.interp(at, stamps, poses[:, 1]),
            np.interp(at, stamps, yaw),
        ],
        axis=1,
    )


def relation_metrics(stamps: ArrayLike, poses: ArrayLike, relations: ArrayLike) -> RelationMetrics:
    """The relation errors of a trajectory.

    Parameters
    ----------
    stamps : array_like, shape (N,)
        Trajectory stamps (s), increasing.
    poses : array_like, shape (N, 3)
        Poses ``(x, y, yaw)``.
    relations : array_like, shape (R, 5)
        ``t1, t2, dx, dy, dyaw`` (:func:`read_relations`).
    """
    stamps = np.asarray(stamps, dtype=np.float64)
    poses = np.asarray(poses, dtype=np.float64).reshape(-1, 3)
    rel = np.asarray(relations, dtype=np.float64).reshape(-1, 5)
    if stamps.size:
        order = np.argsort(stamps, kind="stable")
        stamps, poses = stamps[order], poses[order]
        lo, hi = stamps[0], stamps[-1]
        covered = (rel[:, 0] >= lo) & (rel[:, 0] <= hi) & (rel[:, 1] >= lo) & (rel[:, 1] <= hi)
    else:
        covered = np.zeros(rel.shape[0], dtype=bool)
    rel = rel[covered]
    if rel.shape[0] == 0:
        nan = float("nan")
        return RelationMetrics(int(covered.size), 0, *([nan] * 8))
    p1 = _interpolate(stamps, poses, rel[:, 0])
    p2 = _interpolate(stamps, poses, rel[:, 1])
    actual = between_many(p1, p2)
    error = compose_many(invert_many(rel[:, 2:5]), actual)
    trans = np.hypot(error[:, 0], error[:, 1])
    rot = np.degrees(np.abs(wrap_angle(error[:, 2])))
    return RelationMetrics(
        int(covered.size),
        int(rel.shape[0]),
        float(trans.mean()),
        float(trans.std()),
        float((trans**2).mean()),
        float((trans**2).std()),
        float(rot.mean()),
        float(rot.std()),
        float((rot**2).mean()),
        float((rot**2).std()),
    )


def closure_consistency(
    result: SlamResult, max_translation: float = 0.2, max_rotation_deg: float = 1.0
) -> float:
    """Share of accepted loop closures that the final map contradicts.

    A closure is contradicted when the final keyframe poses put the query keyframe more than
    ``max_translation`` (m) or ``max_rotation_deg`` away from where the closure measured it
    (Cartographer's Table IV). 0.0 without accepted closures.
    """
    accepted = [c for c in result.closures if c.accepted]
    if not accepted:
        return 0.0
    kp = np.asarray(result.keyframe_poses, dtype=np.float64)
    query = kp[[c.query for c in accepted]]
    match = kp[[c.match for c in accepted]]
    measured = np.array([c.relative for c in accepted], dtype=np.float64)
    error = between_many(measured, between_many(match, query))
    bad = (np.hypot(error[:, 0], error[:, 1]) > max_translation) | (
        np.degrees(np.abs(wrap_angle(error[:, 2]))) > max_rotation_deg
    )
    return float(bad.mean())
