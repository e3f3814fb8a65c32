"""Repeatability of keypoints between scans with a known relative pose.

For a pair of scans A and B with the pose of B in A's frame known, A's keypoints are moved
into B's sensor frame; those B could have seen (:func:`~laser_corners.eval.visibility.
points_in_view`, with occlusion against scan B itself) are *visible*, and a visible keypoint is
*repeated* when B has a keypoint within ``r`` of it. Repeatability is repeated / visible,
summed over all pairs.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from laser_corners.eval.visibility import points_in_view
from laser_corners.scan import LaserScan, Pose2D

__all__ = ["PairCounts", "RepeatabilityResult", "pair_repeatability", "repeatability"]


@dataclass(frozen=True)
class PairCounts:
    """Counts of one scan pair.

    Attributes
    ----------
    n_a : int
        Keypoints of scan A.
    n_visible : int
        Keypoints of A inside B's view.
    n_repeated : tuple of int
        For each radius, visible keypoints of A with a keypoint of B within the radius.
    """

    n_a: int
    n_visible: int
    n_repeated: tuple[int, ...]


def pair_repeatability(
    keypoints_a: ArrayLike,
    keypoints_b: ArrayLike,
    scan_b: LaserScan,
    pose_b_in_a: Pose2D,
    radii: Sequence[float] = (0.05, 0.1),
    tolerance: float = 0.06,
    occlusion: bool = True,
    max_range: float | None = None,
) -> PairCounts:
    """Count A's keypoints visible in B and those that reappear in B.

    Parameters
    ----------
    keypoints_a, keypoints_b : array_like, shape (M, 2)
        Keypoints of scans A and B, each in its own sensor frame.
    scan_b : LaserScan
        Scan B (its beams define what it could see).
    pose_b_in_a : (x, y, theta)
        Sensor pose of B in the sensor frame of A.
    radii : sequence of float
        Repetition radii r, metres.
    tolerance, occlusion, max_range
        Visibility test, see :func:`~laser_corners.eval.visibility.points_in_view`.

    Returns
    -------
    PairCounts
    """
    kp_a = np.asarray(keypoints_a, dtype=np.float64).reshape(-1, 2)
    kp_b = np.asarray(keypoints_b, dtype=np.float64).reshape(-1, 2)
    # A's keypoints in B's frame: inverse of pose_b_in_a
    c, s = math.cos(pose_b_in_a[2]), math.sin(pose_b_in_a[2])
    shifted = kp_a - np.array([pose_b_in_a[0], pose_b_in_a[1]])
    in_b = shifted @ np.array([[c, -s], [s, c]])
    visible = points_in_view(scan_b, in_b, tolerance, occlusion, max_range)
    vis_pts = in_b[visible]
    if vis_pts.shape[0] and kp_b.shape[0]:
        nearest = np.min(np.linalg.norm(vis_pts[:, None, :] - kp_b[None, :, :], axis=2), axis=1)
    else:
        nearest = np.full(vis_pts.shape[0], np.inf)
    return PairCounts(
        n_a=int(kp_a.shape[0]),
        n_visible=int(vis_pts.shape[0]),
        n_repeated=tuple(int(np.count_nonzero(nearest <= r)) for r in radii),
    )


@dataclass(frozen=True)
class RepeatabilityResult:
    """Repeatability of one detector over many scan pairs.

    Attributes
    ----------
    radii : tuple of float
        Repetition radii.
    n_pairs : int
        Scan pairs evaluated.
    n_visible : int
        Keypoints of the A scans visible in their B scans, summed over pairs.
    n_repeated : tuple of int
        Repeated keypoints per radius, summed over pairs.
    keypoints_per_scan : float
        Mean number of keypoints per scan over the scans the pairs use.
    """

    radii: tuple[float, ...]
    n_pairs: int
    n_visible: int
    n_repeated: tuple[int, ...]
    keypoints_per_scan: float

    @property
    def repeatability(self) -> tuple[float, ...]:
        """Repeated / visible per radius (NaN when nothing was visible)."""
        if self.n_visible == 0:
            return tuple(math.nan for _ in self.radii)
        return tuple(n / self.n_visible for n in self.n_repeated)


def repeatability(
    keypoints: Sequence[ArrayLike],
    scans: Sequence[LaserScan],
    pairs: Sequence[tuple[int, int, Pose2D]],
    radii: Sequence[float] = (0.05, 0.1),
    tolerance: float = 0.06,
    occlusion: bool = True,
    max_range: float | None = None,
) -> RepeatabilityResult:
    """Repeatability over scan pairs with known relative poses.

    Parameters
    ----------
    keypoints : sequence of array_like, shape (M_i, 2)
        Each scan's keypoints in its sensor frame.
    scans : sequence of LaserScan
        The scans (same indexing as ``keypoints``).
    pairs : sequence of (i, j, pose)
        Scan indices of A and B and the sensor pose of B in A's frame.
    radii, tolerance, occlusion, max_range
        See :func:`pair_repeatability`.

    Returns
    -------
    RepeatabilityResult
    """
    radii = tuple(float(r) for r in radii)
    n_visible = 0
    n_repeated = np.zeros(len(radii), dtype=np.int64)
    used: set[int] = set()
    for i, j, pose in pairs:
        counts = pair_repeatability(
            keypoints[i], keypoints[j], scans[j], pose, radii, tolerance, occlusion, max_range
        )
        n_visible += counts.n_visible
        n_repeated += np.asarray(counts.n_repeated, dtype=np.int64)
        used.update((i, j))
    per_scan = (
        float(np.mean([np.asarray(keypoints[k]).reshape(-1, 2).shape[0] for k in sorted(used)]))
        if used
        else math.nan
    )
    return RepeatabilityResult(
        radii=radii,
        n_pairs=len(pairs),
        n_visible=n_visible,
        n_repeated=tuple(int(v) for v in n_repeated),
        keypoints_per_scan=per_scan,
    )
