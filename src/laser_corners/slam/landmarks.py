"""Corner landmarks: keypoints of keyframes associated into landmarks ``L(i)`` of the graph.

Each keyframe's corner keypoints (:class:`~laser_corners.detector.CornerDetector`, sensor
frame) are moved into the base frame (the mount) and, with the keyframe's current estimate,
into the map frame. A keypoint is associated with a landmark track when the Mahalanobis
distance of their positions, under the keypoint's covariance (``Keypoints.cov`` plus
``landmark_sigma_floor``), the keyframe's pose uncertainty (its marginal, propagated to the
point) and the track's own uncertainty, is within ``landmark_gate``, the corner's bisector
points the same way (within :data:`MAX_TURN`) and its opening angle agrees (within
:data:`MAX_OPENING_DEG`). A keypoint within the gate of two tracks is ambiguous and left out;
one within none starts a track. Associations are one-to-one, nearest first.

A track seen by ``landmark_min_observations`` keyframes becomes the landmark variable
``L(i)``; each of its observations (the earlier ones too) is a bearing-range factor from the
keyframe ``X(k)``, whose 2x2 noise is the keypoint covariance moved into (bearing, range)
coordinates (``J C J^T``) under a Huber kernel, so one wrong association pulls with a bounded
force.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray
from scipy.spatial import cKDTree

from laser_corners.detector import CornerDetector
from laser_corners.keypoints import Keypoints
from laser_corners.pose import rotation, wrap_angle
from laser_corners.registration.corners import corner_detector
from laser_corners.scan import LaserScan
from laser_corners.slam.backend import Backend
from laser_corners.slam.options import SlamOptions
from laser_corners.slam.result import Landmarks

__all__ = ["LandmarkTracker", "base_frame_keypoints"]

MAX_TURN = 0.6
"""Largest difference (rad) between a keypoint's bisector and its track's, map frame."""
MAX_OPENING_DEG = 25.0
"""Largest difference (degrees) between a keypoint's opening angle and its track's."""
SEARCH_RADIUS = 2.0
"""Tracks farther than this (m) from a keypoint are not tested for association."""
POSE_SIGMA_CAP = (0.3, 0.05)
"""Cap (m, rad) on the pose uncertainty used in the gate: after a long loop the marginal
grows to metres, and a gate that wide would associate anything."""


def base_frame_keypoints(
    kp: Keypoints, mount: NDArray[np.float64], floor: float
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Keypoints moved into the base frame: positions (M, 2), covariances (M, 2, 2) with
    ``floor**2`` added (NaN covariances: the floor, or 0.05 m when it is 0), bisector
    orientations (M,) and opening angles (M,)."""
    rot = rotation(float(mount[2]))
    xy = kp.xy @ rot.T + mount[:2]
    cov = np.asarray(kp.cov, dtype=np.float64).copy()
    bad = ~np.isfinite(cov).all(axis=(1, 2))
    cov[bad] = np.eye(2) * (0.05**2 if floor == 0.0 else 0.0)
    cov = rot @ cov @ rot.T + np.eye(2) * floor**2
    return xy, cov, kp.orientation + mount[2], np.asarray(kp.opening_angle_deg, dtype=float)


def bearing_range(
    xy: NDArray[np.float64], cov: NDArray[np.float64]
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Bearing (rad), range (m) and their 2x2 covariance (``J C J^T``) of base-frame points
    ``xy`` (M, 2) with covariances ``cov`` (M, 2, 2)."""
    x, y = xy[:, 0], xy[:, 1]
    r2 = np.maximum(x * x + y * y, 1e-12)
    r = np.sqrt(r2)
    jac = np.stack([np.stack([-y / r2, x / r2], -1), np.stack([x / r, y / r], -1)], axis=1)
    return np.arctan2(y, x), r, jac @ cov @ jac.transpose(0, 2, 1)


def _pose_jacobians(pose: NDArray[np.float64], xy: NDArray[np.float64]) -> NDArray[np.float64]:
    """Jacobians (M, 2, 3) of map-frame points with respect to a body-frame perturbation
    (dx, dy, dyaw) of ``pose`` (gtsam's ``Pose2`` tangent space)."""
    rot = rotation(float(pose[2]))
    local = np.zeros((xy.shape[0], 2, 3))
    local[:, 0, 0] = local[:, 1, 1] = 1.0
    local[:, 0, 2] = -xy[:, 1]
    local[:, 1, 2] = xy[:, 0]
    return rot @ local


class _Tracks:
    """Growable arrays of landmark tracks (position information, orientation, stamps)."""

    def __init__(self) -> None:
        self.info = np.zeros((0, 2, 2))  # summed information of the map-frame observations
        self.info_xy = np.zeros((0, 2))  # summed information-weighted positions
        self.orientation = np.zeros(0)
        self.opening = np.zeros(0)
        self.n_obs = np.zeros(0, dtype=np.int64)
        self.first = np.zeros(0)
        self.last = np.zeros(0)
        self.last_keyframe = np.zeros(0, dtype=np.int64)
        self.var = np.full(0, -1, dtype=np.int64)  # landmark index in the graph, -1: not yet
        self.pending: list[list[tuple[int, NDArray, NDArray]]] = []

    def __len__(self) -> int:
        return int(self.n_obs.shape[0])

    def xy(self) -> NDArray[np.float64]:
        return np.linalg.solve(self.info, self.info_xy[:, :, None])[:, :, 0]

    def add(
        self, info: NDArray, xy: NDArray, ori: NDArray, opening: NDArray, stamp: float, k: int
    ) -> None:
        n = xy.shape[0]
        self.last_keyframe = np.concatenate([self.last_keyframe, np.full(n, k, dtype=np.int64)])
        self.info = np.concatenate([self.info, info])
        self.info_xy = np.concatenate([self.info_xy, (info @ xy[:, :, None])[:, :, 0]])
        self.orientation = np.concatenate([self.orientation, ori])
        self.opening = np.concatenate([self.opening, opening])
        self.n_obs = np.concatenate([self.n_obs, np.ones(n, dtype=np.int64)])
        self.first = np.concatenate([self.first, np.full(n, stamp)])
        self.last = np.concatenate([self.last, np.full(n, stamp)])
        self.var = np.concatenate([self.var, np.full(n, -1, dtype=np.int64)])
        self.pending.extend([] for _ in range(n))


class LandmarkTracker:
    """Associates keyframe keypoints into landmarks and adds them to a :class:`Backend`.

    Parameters
    ----------
    options : SlamOptions
    mount : ndarray, shape (3,)
        Base -> laser transform.
    backend : Backend
        The graph the landmarks and their observations go into.
    """

    def __init__(self, options: SlamOptions, mount: NDArray[np.float64], backend: Backend):
        self.options = options
        self.mount = mount
        self.backend = backend
        self.tracks = _Tracks()
        self.detector: CornerDetector | None = None
        self.n_factors = 0
        self.ambiguous = 0

    def detect(self, scan: LaserScan) -> Keypoints:
        """The corner keypoints of ``scan`` (sensor frame); the detector is made on the first."""
        if self.detector is None:
            self.detector = corner_detector(self.options.detector_preset, scan)
        return self.detector.detect(scan)

    def observe(
        self,
        k: int,
        pose: NDArray[np.float64],
        pose_cov: NDArray[np.float64],
        kp: Keypoints,
        stamp: float,
    ) -> None:
        """Associate the keypoints ``kp`` of keyframe ``k`` (estimate ``pose``, marginal
        ``pose_cov`` in the body frame) and add the factors of the landmarks they confirm."""
        if len(kp) == 0:
            return
        bxy, bcov, bori, opening = base_frame_keypoints(
            kp, self.mount, self.options.landmark_sigma_floor
        )
        rot = rotation(float(pose[2]))
        mxy = bxy @ rot.T + pose[:2]
        jac = _pose_jacobians(pose, bxy)
        mcov = rot @ bcov @ rot.T + jac @ _capped(pose_cov) @ jac.transpose(0, 2, 1)
        mori = wrap_angle(bori + pose[2])
        pairs, fresh = self._associate(k, mxy, mcov, mori, opening)
        t = self.tracks
        for i, j in pairs:
            t.info[j] += np.linalg.inv(mcov[i])
            t.info_xy[j] += np.linalg.solve(mcov[i], mxy[i])
            t.n_obs[j] += 1
            t.last[j] = stamp
            t.last_keyframe[j] = k
            self._observation(j, k, bxy[i], bcov[i])
        if fresh.size:
            t.add(np.linalg.inv(mcov[fresh]), mxy[fresh], mori[fresh], opening[fresh], stamp, k)
            for i, j in zip(fresh, range(len(t) - fresh.size, len(t)), strict=True):
                t.pending[j].append((k, bxy[i], bcov[i]))

    def _associate(
        self, k: int, mxy: NDArray, mcov: NDArray, mori: NDArray, opening: NDArray
    ) -> tuple[list[tuple[int, int]], NDArray[np.int64]]:
        """One-to-one (keypoint, track) pairs within the gate, nearest first, and the indices
        of the keypoints that start new tracks (within no track's gate). Only tracks seen
        within the last ``landmark_window`` keyframes are candidates (0: every track)."""
        t = self.tracks
        window = self.options.landmark_window
        live = np.flatnonzero(k - t.last_keyframe <= window) if window else np.arange(len(t))
        if live.size == 0:
            return [], np.arange(mxy.shape[0])
        txy = t.xy()[live]
        near = [
            live[np.asarray(c, dtype=np.int64)]
            for c in cKDTree(txy).query_ball_point(mxy, SEARCH_RADIUS)
        ]
        txy = t.xy()
        gate2 = self.options.landmark_gate**2
        scored: list[tuple[float, int, int]] = []
        in_gate = np.zeros(mxy.shape[0], dtype=np.int64)
        for i, cand in enumerate(near):
            if len(cand) == 0:
                continue
            cand = np.asarray(cand)
            d = mxy[i] - txy[cand]
            s = mcov[i] + np.linalg.inv(t.info[cand])
            m2 = np.einsum("ni,ni->n", d, np.linalg.solve(s, d[:, :, None])[:, :, 0])
            ok = (
                (m2 <= gate2)
                & (np.abs(wrap_angle(mori[i] - t.orientation[cand])) <= MAX_TURN)
                & (np.abs(opening[i] - t.opening[cand]) <= MAX_OPENING_DEG)
            )
            in_gate[i] = int(np.count_nonzero(m2 <= gate2))
            if np.count_nonzero(ok) == 1:
                scored.append((float(m2[ok][0]), i, int(cand[ok][0])))
            elif np.count_nonzero(ok) > 1:
                self.ambiguous += 1
        pairs, used_kp, used_tr = [], set(), set()
        for _, i, j in sorted(scored):
            if i not in used_kp and j not in used_tr:
                pairs.append((i, j))
                used_kp.add(i)
                used_tr.add(j)
        fresh = np.flatnonzero(in_gate == 0)
        return pairs, fresh

    def _observation(self, j: int, k: int, bxy: NDArray, bcov: NDArray) -> None:
        """Record observation of track ``j`` from keyframe ``k``: a factor when the track is
        a landmark, else pending; a track reaching the minimum becomes a landmark."""
        t = self.tracks
        t.pending[j].append((k, bxy, bcov))
        if t.var[j] < 0 and t.n_obs[j] < self.options.landmark_min_observations:
            return
        if t.var[j] < 0:
            xy = np.linalg.solve(t.info[j], t.info_xy[j])
            t.var[j] = self.backend.add_landmark(xy)
        for kf, xy, cov in t.pending[j]:
            bearing, rng, brc = bearing_range(xy[None, :], cov[None, :, :])
            self.backend.add_observation(kf, int(t.var[j]), bearing[0], rng[0], brc[0])
            self.n_factors += 1
        t.pending[j] = []

    def refresh(self) -> None:
        """Move the graph landmarks' association positions to the backend's estimates."""
        t = self.tracks
        idx = np.flatnonzero(t.var >= 0)
        if idx.size == 0:
            return
        est = self.backend.landmark_estimates()
        t.info_xy[idx] = (t.info[idx] @ est[t.var[idx]][:, :, None])[:, :, 0]

    def landmarks(self, marginals: object | None) -> Landmarks:
        """The graph landmarks at the backend's estimate, covariances from ``marginals``
        (a ``gtsam.Marginals``; NaN when None)."""
        t = self.tracks
        idx = np.flatnonzero(t.var >= 0)
        idx = idx[np.argsort(t.var[idx])]
        xy = self.backend.landmark_estimates() if idx.size else np.zeros((0, 2))
        cov = np.full((idx.size, 2, 2), np.nan)
        if marginals is not None:
            for n, j in enumerate(idx):
                cov[n] = self.backend.landmark_covariance(marginals, int(t.var[j]))
        return Landmarks(xy, cov, t.n_obs[idx].copy(), t.first[idx].copy(), t.last[idx].copy())


def _capped(cov: NDArray[np.float64]) -> NDArray[np.float64]:
    """``cov`` (3x3, x, y, yaw) scaled down so no standard deviation exceeds
    :data:`POSE_SIGMA_CAP`."""
    sig = np.sqrt(np.maximum(np.diag(cov), 0.0))
    cap = np.array([POSE_SIGMA_CAP[0], POSE_SIGMA_CAP[0], POSE_SIGMA_CAP[1]])
    scale = np.minimum(1.0, cap / np.maximum(sig, 1e-12))
    return cov * np.outer(scale, scale)
