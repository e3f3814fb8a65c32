"""Keypoint descriptors of the place-recognition evaluation, computed once per scan.

Each keypoint is described by a shape-context histogram of its scan's points: polar bins
(rings ``RADIAL_EDGES`` x ``SECTORS`` angular sectors) centred on the keypoint, sectors counted
from the keypoint's orientation (so the descriptor is rotation invariant), each point weighted by
the surface length it stands for (range x beam spacing) so near and far walls count alike,
L1-normalised (descriptor distances lie in [0, 2]). See :mod:`laser_corners.eval.loop_match`.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numba as nb
import numpy as np
from numpy.typing import NDArray

from laser_corners.keypoints import Keypoints
from laser_corners.scan import LaserScan

__all__ = ["RADIAL_EDGES", "SECTORS", "KeypointBank", "build_bank"]

RADIAL_EDGES: tuple[float, ...] = (0.0, 0.3, 0.7, 1.2, 2.0)
"""Ring edges of the descriptor, metres (points farther than the last edge are ignored)."""
SECTORS = 12
"""Angular sectors of the descriptor, counted from the keypoint's orientation."""


@dataclass(frozen=True)
class KeypointBank:
    """Keypoints and descriptors of many scans, flattened (scan ``s`` owns rows
    ``offsets[s]:offsets[s + 1]``)."""

    offsets: NDArray[np.int64]
    xy: NDArray[np.float64]
    orientation: NDArray[np.float64]
    opening_deg: NDArray[np.float64]
    descriptors: NDArray[np.float64]

    @property
    def n_scans(self) -> int:
        """Number of scans."""
        return int(self.offsets.shape[0] - 1)

    def counts(self) -> NDArray[np.int64]:
        """Keypoints per scan."""
        return np.diff(self.offsets)


@nb.njit(cache=True, nogil=True)
def _describe_all(
    kp_xy: NDArray[np.float64],
    kp_ori: NDArray[np.float64],
    kp_scan: NDArray[np.int64],
    pts: NDArray[np.float64],
    pt_weight: NDArray[np.float64],
    pt_offsets: NDArray[np.int64],
    edges: NDArray[np.float64],
    sectors: int,
) -> NDArray[np.float64]:
    n_rings = edges.shape[0] - 1
    out = np.zeros((kp_xy.shape[0], n_rings * sectors))
    r_max = edges[n_rings]
    width = 2.0 * math.pi / sectors
    for k in range(kp_xy.shape[0]):
        s = kp_scan[k]
        total = 0.0
        for p in range(pt_offsets[s], pt_offsets[s + 1]):
            dx = pts[p, 0] - kp_xy[k, 0]
            dy = pts[p, 1] - kp_xy[k, 1]
            d = math.sqrt(dx * dx + dy * dy)
            if d >= r_max or d < 1e-9:
                continue
            ring = 0
            while d >= edges[ring + 1]:
                ring += 1
            a = math.atan2(dy, dx) - kp_ori[k]
            a = a - 2.0 * math.pi * math.floor(a / (2.0 * math.pi))
            sector = min(int(a / width), sectors - 1)
            out[k, ring * sectors + sector] += pt_weight[p]
            total += pt_weight[p]
        if total > 0.0:
            for b in range(out.shape[1]):
                out[k, b] /= total
    return out


def build_bank(scans: Sequence[LaserScan], keypoints: Sequence[Keypoints]) -> KeypointBank:
    """Describe every keypoint of every scan once (sensor frames).

    Parameters
    ----------
    scans : sequence of LaserScan
        The scans.
    keypoints : sequence of Keypoints
        The keypoints of each scan, in its sensor frame.

    Returns
    -------
    KeypointBank
    """
    if len(scans) != len(keypoints):
        raise ValueError(f"{len(scans)} scans but {len(keypoints)} keypoint sets")
    counts = np.array([len(k) for k in keypoints], dtype=np.int64)
    offsets = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
    empty = np.zeros((0, 2))
    kp_xy = np.concatenate([k.xy for k in keypoints] or [empty])
    ori = np.concatenate([k.orientation for k in keypoints] or [np.zeros(0)])
    opening = np.concatenate([k.opening_angle_deg for k in keypoints] or [np.zeros(0)])
    pts_list, weights = [], []
    for scan in scans:
        xy, valid = scan.to_cartesian()
        pts_list.append(xy[valid])
        weights.append(scan.ranges[valid] * abs(scan.angle_increment))
    pt_counts = np.array([len(p) for p in pts_list], dtype=np.int64)
    pt_offsets = np.concatenate([[0], np.cumsum(pt_counts)]).astype(np.int64)
    desc = _describe_all(
        np.ascontiguousarray(kp_xy, dtype=np.float64),
        np.ascontiguousarray(ori, dtype=np.float64),
        np.repeat(np.arange(len(scans), dtype=np.int64), counts),
        np.ascontiguousarray(np.concatenate(pts_list or [empty]), dtype=np.float64),
        np.concatenate(weights or [np.zeros(0)]).astype(np.float64),
        pt_offsets,
        np.asarray(RADIAL_EDGES, dtype=np.float64),
        SECTORS,
    )
    return KeypointBank(offsets, kp_xy, ori, opening, desc)
