"""Keyframe making: :class:`Keyframer` (when a scan becomes a keyframe, its link in the pose
graph, its corners).

A scan becomes a keyframe after ``keyframe_distance`` / ``keyframe_angle`` of motion,
``keyframe_max_interval`` seconds, a time jump or a scan that did not align. It joins the
graph with a relative-pose factor to the previous keyframe (its noise: the scan matching's
when every scan since aligned, the odometry's when one did not, none at all - a new
segment, a weak prior - after a cut), and its corners become the corner front end's
reference, landmark observations and entries of the place index.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from laser_corners.detector import CornerDetector
from laser_corners.keypoints import Keypoints
from laser_corners.pose import relative_pose
from laser_corners.registration.corners import corner_detector, scan_corners
from laser_corners.registration.mapfolder import SavedMap
from laser_corners.registration.odometry import odometry_sigmas
from laser_corners.registration.place_index import PlaceIndex, index_arrays, index_from_arrays
from laser_corners.registration.points import ScanPoints
from laser_corners.scan import LaserScan
from laser_corners.slam.backend import Backend
from laser_corners.slam.corners import CornerRegistrar
from laser_corners.slam.counts import SlamCounts
from laser_corners.slam.grow import (
    INITIAL_SIGMAS,
    LOST_SIGMAS,
    PRIOR_SIGMAS,
    prior_points,
    prior_scans,
)
from laser_corners.slam.keyframes import KeyframeStore
from laser_corners.slam.landmarks import LandmarkTracker
from laser_corners.slam.options import SlamOptions

__all__ = ["CUT_SIGMAS", "Keyframer"]

CUT_SIGMAS = (10.0, 10.0, 3.0)
"""Standard deviations (m, m, rad) of the link to a keyframe that starts a new segment."""


class Keyframer:
    """Makes the keyframes of a run.

    Parameters
    ----------
    options : SlamOptions
    mount : ndarray, shape (3,)
        Base -> laser transform.
    backend : Backend
        The pose graph the keyframes join.
    counts : SlamCounts
        Counts ``landmark_observations``.
    corners : CornerRegistrar, optional
        The corner front end, whose reference every keyframe becomes.
    landmarks : LandmarkTracker, optional
        Gets every keyframe's corners as observations.

    Attributes
    ----------
    store : KeyframeStore
        The keyframes.
    places : PlaceIndex
        Every keyframe's corners and descriptors (``options.places``).
    links : list
        Per keyframe, its tracked pose in the previous keyframe's frame; None for the first
        and for one that starts a new segment (a cut).
    """

    def __init__(
        self,
        options: SlamOptions,
        mount: NDArray[np.float64],
        backend: Backend,
        counts: SlamCounts,
        corners: CornerRegistrar | None = None,
        landmarks: LandmarkTracker | None = None,
    ) -> None:
        self.options = options
        self.mount = mount
        self.backend = backend
        self.counts = counts
        self.corners = corners
        self.landmarks = landmarks
        self.store = KeyframeStore()
        self.places = PlaceIndex(options.places)
        self.links: list[NDArray | None] = [None]
        self.start_sigmas: tuple[float, float, float] | None = None
        self._detector: CornerDetector | None = None
        self._place_detector: CornerDetector | None = None

    def seed(self, saved: SavedMap, initial_pose: bool = False, frozen: bool = False) -> None:
        """Start from a prior map (:mod:`.grow`): its keyframes become keyframes ``0 .. K - 1``
        (store, place index, graph); the session's keyframes follow
        (:attr:`KeyframeStore.first`). ``initial_pose``: the session's first keyframe gets a
        prior of :data:`~.grow.INITIAL_SIGMAS` at its pose (else it starts a lost segment,
        ``cut``).

        With the map's pose graph (``saved.graph``, its ``graph.g2o``) the keyframes are
        linked by the map's own factors, its loop closures robust as the back end makes them,
        under the one-run SLAM's priors only (the first keyframe's, which holds the map's
        frame, and a weak one on a keyframe that started a segment): the session's closures
        bend the map as a one-run SLAM would. Without it, each keyframe is held by a prior of
        :data:`~.grow.PRIOR_SIGMAS` and linked to the one before with the scan matching's
        noise (the map stays put), as with ``frozen`` (a localising run: the map is the
        reference, never bent)."""
        points = prior_points(saved)
        scans = prior_scans(points, self.mount, self.options.max_range)
        if saved.graph is not None and not frozen:
            self._seed_graph(saved)
        else:
            self._seed_fixed(saved)
        for k, pose in enumerate(saved.poses):
            self.store.add(scans[k], points[k], -1, saved.stamps[k], pose, pose)
        self.store.first = len(saved)
        self.links = [None] * len(saved)
        self.start_sigmas = INITIAL_SIGMAS if initial_pose else None
        if saved.places is not None and self.options.places.enabled and not len(self.places):
            old = index_from_arrays(index_arrays(saved.places), self.options.places)
            if old is not None:
                self.places.keyframe, self.places.corners = old.keyframe, old.corners
        self.store.estimate = self.backend.update()

    def _seed_graph(self, saved: SavedMap) -> None:
        """The prior map's keyframes and its pose graph's factors (see :meth:`seed`)."""
        graph = saved.graph
        chain = graph.chain()
        linked = set(graph.pairs[chain, 1].tolist())
        for k, pose in enumerate(saved.poses):
            self.backend.add_keyframe(pose, prior=k > 0 and k not in linked)
        for (a, b), rel, sig, link in zip(
            graph.pairs, graph.relative, graph.sigmas, chain, strict=True
        ):
            sigmas = (float(sig[0]), float(sig[1]), float(sig[2]))
            self.backend.add_between(int(a), int(b), rel, sigmas, robust=not link)

    def _seed_fixed(self, saved: SavedMap) -> None:
        """The prior map's keyframes, each under a prior of :data:`~.grow.PRIOR_SIGMAS` and
        linked to the one before by their relative pose in the map, with the scan matching's
        noise (a map folder without ``graph.g2o``)."""
        opt = self.options
        link = (opt.match_sigma_xy, opt.match_sigma_xy, opt.match_sigma_yaw)
        for k, pose in enumerate(saved.poses):
            self.backend.add_keyframe(pose, sigmas=PRIOR_SIGMAS)
            if k:  # the map's shape as it was made
                self.backend.add_between(k - 1, k, relative_pose(saved.poses[k - 1], pose), link)

    def keypoints(self, scan: LaserScan) -> Keypoints:
        """Corner keypoints of ``scan`` (sensor frame), detector made on the first scan."""
        if self._detector is None:
            self._detector = corner_detector(self.options.detector_preset, scan)
        return self._detector.detect(scan)

    def due(self, moved: NDArray, stamp: float, jumped: bool, aligned: bool) -> bool:
        """Whether a scan ``moved`` (x, y, yaw) from the last keyframe, at ``stamp``, becomes
        a keyframe; ``jumped``, ``aligned``: since the last keyframe the stamps jumped, every
        scan aligned (one that did not is new ground: into the map at once)."""
        opt = self.options
        return bool(
            jumped
            or not aligned
            or np.hypot(moved[0], moved[1]) >= opt.keyframe_distance
            or abs(moved[2]) >= opt.keyframe_angle
            or stamp - self.store.stamps[-1] >= opt.keyframe_max_interval
        )

    def add(
        self,
        scan: LaserScan,
        pts: ScanPoints,
        odo: NDArray,
        stamp: float,
        index: int,
        *,
        pose: NDArray,
        anchor: NDArray,
        cut: bool,
        aligned: bool,
        kp: Keypoints | None,
        cov: NDArray,
        placed: tuple[float, float, float] | None = None,
    ) -> tuple[int, float]:
        """Keyframe ``k`` from scan number ``index`` (``scan``, its points ``pts``, odometry
        ``odo``) at its tracked ``pose``; the last keyframe was at ``anchor``. ``cut``: it
        starts a new segment; ``aligned``: every scan since the last keyframe aligned;
        ``kp``: its keypoints, when detected already; ``cov``: the last keyframe's marginal
        (the landmark observations' pose noise); ``placed``: the standard deviations of a
        prior at ``pose`` (a fix given by the caller, :meth:`.Slam.place`: it starts a new
        segment there). Returns ``k`` and the distance (m) from the last keyframe."""
        start = len(self.store) == self.store.first
        sigmas = placed
        cut = cut or placed is not None
        if start and self.store.first and placed is None:  # a session's first on a prior map
            sigmas = LOST_SIGMAS if cut else self.start_sigmas
        k = self.backend.add_keyframe(pose, prior=cut, sigmas=sigmas)
        dist = 0.0
        if not start:
            rel = np.array(relative_pose(anchor, pose))
            self.links.append(None if cut else rel)
            dist = float(np.hypot(rel[0], rel[1]))
            self.backend.add_between(k - 1, k, rel, self._link_sigmas(rel, dist, cut, aligned))
        elif k > 0:  # a session's first keyframe after a prior map: no link to it
            self.links.append(None)
        self.store.add(scan, pts, index, stamp, odo, pose)
        self._corners(k, scan, kp, stamp, pose, cov)
        self._place(k, scan)
        return k, dist

    def _link_sigmas(
        self, rel: NDArray, dist: float, cut: bool, aligned: bool
    ) -> tuple[float, float, float]:
        """Noise of the link ``rel`` (``dist`` long) to the previous keyframe."""
        opt = self.options
        if aligned:
            return (opt.match_sigma_xy, opt.match_sigma_xy, opt.match_sigma_yaw)
        if cut:
            return CUT_SIGMAS
        sig = odometry_sigmas(rel, opt.odometry)
        return (float(sig[0]), float(sig[1]), float(sig[2]))

    def _corners(
        self,
        k: int,
        scan: LaserScan,
        kp: Keypoints | None,
        stamp: float,
        pose: NDArray,
        cov: NDArray,
    ) -> None:
        """Keyframe ``k``'s corners: the corner front end's new reference, and landmark
        observations (associated at the keyframe's tracked ``pose``)."""
        if self.corners is None and self.landmarks is None:
            return
        if kp is None:
            kp = self.keypoints(scan)
        if self.corners is not None:
            self.corners.set_reference(scan, kp)
        if self.landmarks is not None:
            self.landmarks.observe(k, pose, cov, kp, stamp)
            self.counts.landmark_observations = self.landmarks.n_factors

    def _place(self, k: int, scan: LaserScan) -> None:
        """Keyframe ``k``'s corners into the place index (``places``)."""
        if not self.options.places.enabled:
            return
        if self._place_detector is None:
            self._place_detector = corner_detector(self.options.places.detector_preset, scan)
        self.places.add(k, scan_corners(scan, self._place_detector, self.mount))
