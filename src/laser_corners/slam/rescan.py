"""The final scan pass: every scan re-registered against the final map.

A scan's pose from the front end is its alignment to the local map *as it was then* (the
recent keyframes at their estimates of that moment), moved with the final estimates of the
keyframes before and after it (:func:`blend_poses`). After the final
optimisation the keyframes around it are known better, and on both sides of it in time. This
pass aligns every scan again by the front end's ICP against the implicit surface of the
keyframes around its own (``local_map_keyframes`` of them, half before and half after, at
their final estimates), starting from its blended pose with a prior of the scan alignment's
noise (``match_sigma_*``: the blended pose is such an alignment). The result replaces the
blended pose when it passes the tracking's and the loop closure's checks: at least
``min_overlap`` of the scan's points on the map, the alignment not degenerate (a corridor),
and a move of less than ``agree_xy`` / ``agree_yaw`` (a larger one is a wrong match:
the map is consistent already). Keyframe estimates are not changed. :class:`~.slam.Slam`
runs it only where its front end runs ICP.

One ICP per scan, one map per keyframe (its scans share it); the scans' thinned points are
kept for it, as float32 (about 1 KB a scan: 120-160 points of 8 bytes on the Freiburg logs).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from laser_corners.pose import between_many, compose_many, wrap_angle
from laser_corners.registration.align import icp
from laser_corners.slam.keyframes import KeyframeStore
from laser_corners.slam.options import SlamOptions

__all__ = ["blend_poses", "rescan"]

MIN_POINTS = 20
"""Scans (and maps) with fewer points are not re-registered."""


def blend_poses(
    stamps: NDArray[np.float64],
    ref: NDArray[np.int64],
    rel: NDArray[np.float64],
    links: list[NDArray | None],
    keyframes: KeyframeStore,
) -> NDArray[np.float64]:
    """Final pose of every scan: its pose ``rel`` relative to the keyframe before it
    (``ref``), moved with that keyframe's and the next keyframe's final estimates, blended by
    time (``stamps``), so the correction a keyframe link absorbed is spread over the scans
    along it (no jumps). ``links[k]``: the tracked pose of keyframe k in k - 1's frame (None
    where the graph was cut: no blending across it)."""
    estimate = keyframes.estimate
    from_a = compose_many(estimate[ref], rel)
    nxt = np.minimum(ref + 1, len(keyframes) - 1)
    has_next = (ref + 1 < len(keyframes)) & np.array(
        [links[j] is not None for j in nxt], dtype=bool
    )
    steps = np.array([link if link is not None else np.zeros(3) for link in links])
    from_b = compose_many(estimate[nxt], between_many(steps[nxt], rel))
    kst = np.asarray(keyframes.stamps)
    span = np.maximum(kst[nxt] - kst[ref], 1e-9)
    w = np.where(has_next, np.clip((stamps - kst[ref]) / span, 0, 1), 0.0)
    out = from_a.copy()
    out[:, :2] += w[:, None] * (from_b[:, :2] - from_a[:, :2])
    out[:, 2] = wrap_angle(from_a[:, 2] + w * wrap_angle(from_b[:, 2] - from_a[:, 2]))
    return out


def rescan(
    points: list[NDArray[np.float64]],
    poses: NDArray[np.float64],
    ref: NDArray[np.int64],
    keyframes: KeyframeStore,
    options: SlamOptions,
    surface: float,
) -> tuple[NDArray[np.float64], dict[str, int]]:
    """Re-register every scan against the keyframes around it (module docstring).

    Parameters
    ----------
    points : list of ndarray, shape (M_i, 2)
        Each scan's thinned points (base frame), in scan order.
    poses : ndarray, shape (N, 3)
        The scans' poses after the final optimisation (the starts).
    ref : ndarray of int, shape (N,)
        The keyframe each scan follows (non-decreasing).
    keyframes : KeyframeStore
        The keyframes, with their final ``estimate``.
    options : SlamOptions
    surface : float
        Kernel width (m) of the implicit surface, as the front end's.

    Returns
    -------
    poses : ndarray, shape (N, 3)
        The re-registered poses (the start where an alignment failed a check).
    counts : dict
        ``rescan_tried`` / ``rescan_kept``.
    """
    out = np.array(poses, dtype=np.float64, copy=True)
    ref = np.asarray(ref, dtype=np.int64)
    half = options.local_map_keyframes // 2
    sig = np.array([options.match_sigma_xy, options.match_sigma_xy, options.match_sigma_yaw])
    prior = np.diag(1.0 / sig**2)
    tried = kept = 0
    for group in np.split(np.arange(ref.shape[0]), np.flatnonzero(np.diff(ref)) + 1):
        if group.size == 0:
            continue
        k = int(ref[group[0]])
        line, every = keyframes.span_map(
            max(keyframes.first, k - half), min(len(keyframes), k + half + 1)
        )
        if len(line) < MIN_POINTS:
            continue
        for i in group.tolist():
            if points[i].shape[0] < MIN_POINTS:
                continue
            tried += 1
            aligned = icp(
                np.asarray(points[i], dtype=np.float64),
                line,
                out[i],
                prior,
                options.icp,
                inlier_distance=options.inlier_distance,
                overlap_map=every,
                surface=surface,
            )
            agree = (options.agree_xy, options.agree_yaw)
            if aligned.confirms(out[i], options.min_overlap, *agree):
                out[i] = aligned.pose
                kept += 1
    return out, {"rescan_tried": tried, "rescan_kept": kept}
