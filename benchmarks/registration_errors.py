"""Registration accuracy against ground-truth relative poses (Freiburg relations, corrected logs).

For each scan pair (i, j, T) with T the true pose of scan j's sensor in scan i's sensor frame,
:func:`registration_errors` registers j to i with :func:`laser_corners.matching.register_keypoints`
(keypoints and descriptors computed once per scan) and records the translation error
‖t̂ - t‖ and the rotation error |θ̂ - θ|; when both scans carry poses (the bag's odometry)
the odometry's relative pose is scored the same way, side by side.
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from laser_corners.detector import CornerDetector
from laser_corners.matching import (
    DescriptorParams,
    MatchOptions,
    describe,
    register_keypoints,
)
from laser_corners.scan import LaserScan, Pose2D, pose_error, relative_pose

__all__ = ["RegistrationErrors", "consecutive_pairs", "registration_errors"]


@dataclass(frozen=True)
class RegistrationErrors:
    """Per-pair errors of the registration and of the odometry.

    Attributes
    ----------
    accepted : ndarray of bool
        Registration accepted.
    trans, rot : ndarray
        Registration translation (m) and rotation (rad) errors (NaN when not accepted).
    odom_trans, odom_rot : ndarray
        Same for the odometry's relative pose (NaN when a scan has no pose).
    n_inliers : ndarray of int
    ms_per_pair : float
        Registration time per pair (keypoints and descriptors precomputed), milliseconds.
    """

    accepted: NDArray[np.bool_]
    trans: NDArray[np.float64]
    rot: NDArray[np.float64]
    odom_trans: NDArray[np.float64]
    odom_rot: NDArray[np.float64]
    n_inliers: NDArray[np.int64]
    ms_per_pair: float

    def summary(self) -> dict[str, float]:
        """Acceptance rate, median/p90 errors of the accepted registrations and of odometry
        on all pairs and on the accepted ones, and the rate of gross failures (accepted with
        an error above 0.5 m or 0.2 rad)."""
        acc = self.accepted
        out: dict[str, float] = {
            "pairs": float(acc.size),
            "accepted": float(acc.mean()) if acc.size else math.nan,
        }

        def q(v: NDArray[np.float64], p: float) -> float:
            v = v[np.isfinite(v)]
            return float(np.percentile(v, p)) if v.size else math.nan

        series = (
            ("trans", self.trans[acc]),
            ("rot_deg", np.degrees(self.rot[acc])),
            ("odom_trans", self.odom_trans),
            ("odom_rot_deg", np.degrees(self.odom_rot)),
            ("odom_trans_acc", self.odom_trans[acc]),
            ("odom_rot_deg_acc", np.degrees(self.odom_rot[acc])),
        )
        for name, v in series:
            out[f"{name}_median"] = q(v, 50)
            out[f"{name}_p90"] = q(v, 90)
        gross = acc & ((self.trans > 0.5) | (self.rot > 0.2))
        out["gross"] = float(gross.sum() / max(acc.sum(), 1))
        out["ms_per_pair"] = self.ms_per_pair
        return out


def consecutive_pairs(scans: Sequence[LaserScan], step: int = 1) -> list[tuple[int, int, Pose2D]]:
    """Pairs (i, i + step) of scans that both carry a (ground-truth) pose, with their relative
    pose (e.g. the corrected poses of a CARMEN ``-corrected.clf`` log)."""
    out = []
    for i in range(len(scans) - step):
        a, b = scans[i].pose, scans[i + step].pose
        if a is not None and b is not None:
            out.append((i, i + step, relative_pose(a, b)))
    return out


def registration_errors(
    scans: Sequence[LaserScan],
    pairs: Sequence[tuple[int, int, Pose2D]],
    detector: CornerDetector | None = None,
    descriptor: str | DescriptorParams = "csc",
    options: MatchOptions | None = None,
    odometry: bool = True,
) -> RegistrationErrors:
    """Score :func:`~laser_corners.matching.register_keypoints` on ``pairs`` of ``scans``.

    Parameters
    ----------
    scans : sequence of LaserScan
        The scans; with ``odometry`` their ``pose`` (odometry) is scored too.
    pairs : sequence of (i, j, pose)
        Scan indices and the true pose of scan j's sensor in scan i's sensor frame.
    detector, descriptor, options
        As in :func:`laser_corners.matching.register`.
    odometry : bool
        Also score the relative pose of the scans' own poses.
    """
    det = detector if detector is not None else CornerDetector()
    needed = sorted({i for i, _, _ in pairs} | {j for _, j, _ in pairs})
    kps = {}
    descs = {}
    for i in needed:
        kps[i] = det.detect(scans[i])
        descs[i] = describe(scans[i], kps[i], descriptor)
    n = len(pairs)
    acc = np.zeros(n, dtype=bool)
    trans = np.full(n, np.nan)
    rot = np.full(n, np.nan)
    otrans = np.full(n, np.nan)
    orot = np.full(n, np.nan)
    n_inl = np.zeros(n, dtype=np.int64)
    t0 = time.perf_counter()
    regs = [
        register_keypoints(kps[i], descs[i], kps[j], descs[j], options, scans[i], scans[j])
        for i, j, _ in pairs
    ]
    elapsed = time.perf_counter() - t0
    for k, ((i, j, truth), reg) in enumerate(zip(pairs, regs, strict=True)):
        acc[k] = reg.accepted
        n_inl[k] = reg.n_inliers
        if reg.accepted:
            trans[k], rot[k] = pose_error(reg.pose, truth)
        pa, pb = scans[i].pose, scans[j].pose
        if odometry and pa is not None and pb is not None:
            otrans[k], orot[k] = pose_error(relative_pose(pa, pb), truth)
    return RegistrationErrors(acc, trans, rot, otrans, orot, n_inl, 1e3 * elapsed / max(n, 1))
