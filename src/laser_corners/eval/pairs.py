"""Scan pairs with a known relative pose, for repeatability (``evaluate real``).

Pairs come from a ground-truth ``.relations`` file matched to scan stamps
(:func:`pairs_from_relations`) or, without one, from the recording's poses
(:func:`pairs_from_poses`); :func:`choose_pairs` applies that rule and describes the source.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from laser_corners.eval.poses import Relation
from laser_corners.scan import LaserScan, Pose2D, compose, invert, relative_pose

__all__ = [
    "Pair",
    "choose_pairs",
    "default_relations",
    "pairs_from_poses",
    "pairs_from_relations",
    "subsample",
]

Pair = tuple[int, int, Pose2D]
"""Scan indices ``(i, j)`` and the sensor pose of scan ``j`` in the sensor frame of scan ``i``."""


def pairs_from_poses(
    poses: Sequence[Pose2D | None],
    min_motion: float = 0.5,
    min_turn_deg: float = 15.0,
    max_pairs: int = 1000,
) -> list[tuple[int, int, Pose2D]]:
    """Scan pairs for repeatability from sensor poses in a common frame.

    Each scan ``i`` with a pose is paired with the first later scan ``j`` whose pose is at
    least ``min_motion`` metres away or turned at least ``min_turn_deg``; the pose of ``j`` in
    the frame of ``i`` is the ground truth. With more than ``max_pairs`` pairs, an evenly
    spaced subset is kept.
    """
    min_turn = math.radians(min_turn_deg)
    idx = [i for i, p in enumerate(poses) if p is not None]
    pairs: list[tuple[int, int, Pose2D]] = []
    for a_pos, i in enumerate(idx):
        pa = poses[i]
        assert pa is not None
        for j in idx[a_pos + 1 :]:
            pb = poses[j]
            assert pb is not None
            rel = relative_pose(pa, pb)
            if math.hypot(rel[0], rel[1]) >= min_motion or abs(rel[2]) >= min_turn:
                pairs.append((i, j, rel))
                break
    return subsample(pairs, max_pairs)


def subsample(pairs: list[Any], max_pairs: int) -> list[Any]:
    """At most ``max_pairs`` of ``pairs``, evenly spaced."""
    if len(pairs) <= max_pairs:
        return pairs
    keep = np.unique(np.linspace(0, len(pairs) - 1, max_pairs).round().astype(int))
    return [pairs[k] for k in keep]


def pairs_from_relations(
    stamps: Sequence[float | None],
    relations: Sequence[Relation],
    mount: Pose2D = (0.0, 0.0, 0.0),
    tolerance: float = 1e-3,
    max_pairs: int = 1000,
) -> list[tuple[int, int, Pose2D]]:
    """Scan pairs for repeatability from ground-truth relations matched to scan stamps.

    Parameters
    ----------
    stamps : sequence of float or None
        Scan stamps, seconds.
    relations : sequence of Relation
        Relative poses between stamps (robot frame).
    mount : (x, y, theta)
        Sensor pose in the robot frame; the relation ``T`` becomes ``mount⁻¹ ⊕ T ⊕ mount``.
    tolerance : float
        Largest stamp difference for a match, seconds.
    max_pairs : int
        At most this many pairs (evenly subsampled).
    """
    known = [(s, i) for i, s in enumerate(stamps) if s is not None]
    if not known:
        return []
    st = np.array([s for s, _ in known])
    order = np.argsort(st)
    st = st[order]
    index = np.array([i for _, i in known])[order]

    def find(t: float) -> int | None:
        k = int(np.searchsorted(st, t))
        best = None
        for c in (k - 1, k):
            if 0 <= c < len(st) and abs(st[c] - t) <= tolerance:
                if best is None or abs(st[c] - t) < abs(st[best] - t):
                    best = c
        return None if best is None else int(index[best])

    inv_mount = invert(mount)
    pairs = []
    for rel in relations:
        i, j = find(rel.t1), find(rel.t2)
        if i is None or j is None or i == j:
            continue
        pairs.append((i, j, compose(compose(inv_mount, rel.pose), mount)))
    return subsample(pairs, max_pairs)


def default_relations(path: Path) -> Path | None:
    """``<name>.relations`` beside a bag ``<name>.bag`` (the Freiburg benchmark layout)."""
    candidate = path.with_suffix(".relations")
    return candidate if path.suffix == ".bag" and candidate.is_file() else None


def choose_pairs(
    scans: Sequence[LaserScan],
    relations: Sequence[Relation] | None,
    mount: Pose2D,
    max_pairs: int,
    min_motion: float,
    min_turn_deg: float,
    pose_source: str = "",
) -> tuple[list[Pair], str, list[str]]:
    """Pairs from ``relations`` when given and matching, else from the scans' poses.

    Returns
    -------
    pairs : list of Pair
    source : str
        How the pairs were made, in words (for the report).
    notes : list of str
        Why the relations were not used, when they were given but matched no scan pair.
    """
    notes: list[str] = []
    if relations is not None:
        stamps = [s.stamp for s in scans]
        matched = pairs_from_relations(stamps, relations, mount, max_pairs=len(relations))
        pairs = subsample(matched, max_pairs)
        if pairs:
            return (
                pairs,
                (
                    f"ground-truth relations: {len(relations)} in the file, {len(matched)} matched "
                    f"to scan stamps, {len(pairs)} used"
                ),
                notes,
            )
        notes.append("no relation matched two scan stamps; pairs taken from the poses")
    found = pairs_from_poses([s.pose for s in scans], min_motion, min_turn_deg, len(scans))
    pairs = subsample(found, max_pairs)
    return (
        pairs,
        (
            f"poses ({pose_source or 'recording'}): each scan with the next one >= "
            f"{min_motion:g} m or {min_turn_deg:g} deg away, {len(found)} pairs, "
            f"{len(pairs)} used"
        ),
        notes,
    )
