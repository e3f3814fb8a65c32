"""The incremental SLAM: :class:`Slam` (``add(scan, odometry, stamp) -> pose, covariance``).

Per scan: the odometry delta predicts the pose, ICP against the implicit surface of the local
map (the points of the recent keyframes at their current estimates, with their line normals)
corrects it, weighted against the prediction by the odometry noise. A scan becomes a keyframe
after ``keyframe_distance`` / ``keyframe_angle`` of motion: it joins the gtsam graph with a
relative-pose factor to the previous keyframe, loop closures are searched for it, iSAM2
updates, and the local map is rebuilt from the new estimates. Other scans keep their pose
relative to the last keyframe, so their final pose follows the keyframe's final estimate.
"""

from __future__ import annotations

import time

import numpy as np
from numpy.typing import ArrayLike, NDArray

from laser_corners.keypoints import Keypoints
from laser_corners.pose import compose, relative_pose, rotate_covariance, wrap_angle
from laser_corners.registration.align import Alignment, PointMap, icp, match_share
from laser_corners.registration.corners import corner_detector, scan_corners
from laser_corners.registration.correlative import ScoreGrid, search
from laser_corners.registration.place_index import PlaceIndex
from laser_corners.registration.points import scan_points
from laser_corners.scan import LaserScan
from laser_corners.slam.backend import Backend
from laser_corners.slam.corners import CornerRegistrar
from laser_corners.slam.keyframes import KeyframeStore
from laser_corners.slam.landmarks import LandmarkTracker
from laser_corners.slam.loops import (
    MAX_WINDOW_XY,
    MAX_WINDOW_YAW,
    ClosureGate,
    SubmapCache,
    candidates,
    verify,
)
from laser_corners.slam.options import SlamOptions
from laser_corners.slam.refine import refine
from laser_corners.slam.relocalise import (
    LOST_CONFLICT,
    Relocaliser,
    occupancy_keys,
    scan_conflict,
)
from laser_corners.slam.rescan import blend_poses, rescan
from laser_corners.slam.result import COUNT_KEYS, Landmarks, LoopClosure, SlamResult

__all__ = ["Slam"]

FULL_ESTIMATE_EVERY = 50
"""Every this many keyframes (and after every loop closure) all keyframe estimates are read
back from iSAM2; in between only the recent ones."""

RESCUE_SHARE = 0.5
"""Share of a scan's points within half the inlier distance of the local map below which the
tracking tries a correlative search (:meth:`Slam._rescue`)."""
RESCUE_DROP = 0.1
"""... and at least this much below the usual share of the recent scans (an average over
about ten): where every scan fits loosely (far walls, glass, crowds) a loose fit is no sign
of wrong odometry, and searching on every scan there is what made the SLAM slow."""
RESCUE_GAIN = 0.15
"""How much larger that share must be after the correlative search to replace ICP's pose."""
RESCUE_WINDOW = (0.3, 0.7)
"""Half-widths (m, rad) of the rescue's correlative search around the odometry prediction."""
RESCUE_RESOLUTION = 0.05
"""Cell (m) of the rescue's likelihood grid."""

SURFACE_SPACINGS = 2.0
"""Kernel width of the local map's implicit surface that tracking aligns to
(:func:`~laser_corners.registration.align.icp`'s ``surface``), in point spacings: each surface point
averages the lines of the map points within two widths (about eight thinned points of a
wall, from every keyframe that saw it)."""

DISTINGUISH_SIGMA = 3.0
"""Standard deviations (of the scan's own information) by which a second ICP start must differ
from the first for the front end to choose between them (:func:`_distinguishable`)."""


def _distinguishable(first: Alignment, second: Alignment) -> bool:
    """Whether the scan itself tells two alignments apart: their difference, measured with
    the point residuals' information of either (:attr:`Alignment.information`, no prior), is
    more than :data:`DISTINGUISH_SIGMA` standard deviations. Along a corridor it is not: there
    the share of points on the map prefers whichever pose repeats a keyframe's beam pattern,
    which pulls the estimate back towards that keyframe (less motion than driven)."""
    d = second.pose - first.pose  # the information is of the map frame's (x, y, yaw)
    d[2] = wrap_angle(d[2])
    seen = min(float(d @ first.information @ d), float(d @ second.information @ d))
    return seen > DISTINGUISH_SIGMA**2


class Slam:
    """Incremental 2D SLAM over laser scans and odometry.

    Parameters
    ----------
    options : SlamOptions, optional
        Defaults: ``SlamOptions()``.
    mount : tuple of float
        Base -> laser transform ``(x, y, yaw)`` (``options.mount`` overrides it).
    """

    def __init__(
        self, options: SlamOptions | None = None, mount: ArrayLike = (0.0, 0.0, 0.0)
    ) -> None:
        self.options = options or SlamOptions()
        chosen = self.options.mount if self.options.mount is not None else mount
        self.mount = np.asarray(chosen, dtype=np.float64).reshape(3)
        self.backend = Backend()
        self.tracker = (
            LandmarkTracker(self.options, self.mount, self.backend)
            if self.options.landmarks
            else None
        )
        self.corners = CornerRegistrar(self.mount) if self.options.front_end != "scan" else None
        self._detector = None
        self.kf = KeyframeStore()
        self.closures: list[LoopClosure] = []
        self._in_graph: list[LoopClosure] = []  # accepted closures, in the back end's order
        self.counts = dict.fromkeys(COUNT_KEYS, 0)
        self._stamps: list[float] = []
        self._odom: list[NDArray] = []
        self._ref: list[int] = []
        self._rel: list[NDArray] = []
        self._ms: list[float] = []
        opt = self.options  # the scan pass re-runs the front end's ICP: only with it
        self._rescan = opt.rescan_final and opt.scan_alignment and opt.front_end != "corners"
        self._scan_xy: list[NDArray] = []  # every scan's points (float32), for the scan pass
        self.pose: NDArray[np.float64] | None = None
        self._anchor = np.zeros(3)  # the last keyframe's pose in the tracking frame
        self._last_odom = np.zeros(3)
        self._last_stamp = -np.inf
        self._links: list[NDArray | None] = [None]  # tracked pose of keyframe k in k - 1's
        self._local: PointMap | None = None  # line points with normals, for ICP
        self._local_all: PointMap | None = None  # every point, for the overlap
        self._local_grid: ScoreGrid | None = None  # likelihood grid of _local_all, when needed
        self._cov = np.diag([1e-6, 1e-6, 1e-8])
        self._since_closure = 0.0
        self._closed_recently = False
        self.submaps = SubmapCache()
        self.gate = ClosureGate(
            self.options.loop_agree_xy, self.options.loop_agree_yaw, 4 * self.options.loop_every
        )
        self._aligned_since_kf = True
        self._jump = False
        self._step = np.zeros(3)  # the last scan-to-scan motion of the estimate
        self._usual_share = 1.0  # recent scans' share on the local map (_rescue)
        self._lost = False  # the last scan contradicts the local map: cut the graph
        self._pts = None  # the points of the scan being added
        self._local_occupied: NDArray[np.int64] | None = None  # cells of _local_all
        self.places = PlaceIndex(self.options.places)
        """Every keyframe's corners and descriptors: relocalisation candidates, and the map
        folder's index for ``localise``."""
        self._place_detector = None
        self.reloc = Relocaliser(self.options, self.mount, self.places)

    # ------------------------------------------------------------------ per scan
    def add(
        self, scan: LaserScan, odometry_pose: ArrayLike, stamp: float
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Add one scan with the base's odometry pose at its stamp.

        Returns
        -------
        pose : ndarray, shape (3,)
            The base pose in the map frame (current estimate).
        covariance : ndarray, shape (3, 3)
            Its covariance (x, y, yaw in the map frame), from the last keyframe's marginal.
        """
        start = time.perf_counter()
        opt = self.options
        odo = np.asarray(odometry_pose, dtype=np.float64).reshape(3)
        pts = scan_points(scan, self.mount, opt.min_range, opt.max_range, opt.point_spacing)
        self._pts = pts
        kp = self._keypoints(scan) if self.corners is not None else None
        if self.pose is None:
            self.pose = odo.copy()
            self._make_keyframe(scan, pts, odo, stamp, first=True, kp=kp)
        else:
            jump = abs(stamp - self._last_stamp) > opt.time_jump
            if jump:
                self.counts["time_jumps"] += 1
                self._jump = True
            delta = np.array(relative_pose(self._last_odom, odo))
            pred = np.array(compose(self.pose, delta))
            last = self.pose
            self.pose = self._track(pts.xy, pred, delta, jump, self._corner_guess(scan, kp, pred))
            self._step = np.array(relative_pose(last, self.pose))
            moved = relative_pose(self._anchor, self.pose)
            if (
                self._jump
                or not self._aligned_since_kf  # new ground: into the map at once
                or np.hypot(moved[0], moved[1]) >= opt.keyframe_distance
                or abs(moved[2]) >= opt.keyframe_angle
                or stamp - self.kf.stamps[-1] >= opt.keyframe_max_interval
            ):
                self._make_keyframe(scan, pts, odo, stamp, kp=kp)
        self._last_odom, self._last_stamp = odo, stamp
        self._stamps.append(float(stamp))
        self._odom.append(odo)
        self._ref.append(len(self.kf) - 1)
        self._rel.append(np.array(relative_pose(self._anchor, self.pose)))
        if self._rescan:
            self._scan_xy.append(pts.xy.astype(np.float32))  # half the memory; 30 m: 2 µm
        self._ms.append((time.perf_counter() - start) * 1e3)
        self.counts["scans"] += 1
        return self.pose.copy(), self._covariance()

    def _keypoints(self, scan: LaserScan) -> Keypoints:
        """Corner keypoints of ``scan`` (sensor frame), detector made on the first scan."""
        if self._detector is None:
            self._detector = corner_detector(self.options.detector_preset, scan)
        return self._detector.detect(scan)

    def _corner_guess(self, scan: LaserScan, kp: Keypoints | None, pred: NDArray) -> NDArray | None:
        """The base pose from the corner registration to the last keyframe (``front_end``
        ``corners``/``both``), when accepted and within the odometry's reach of ``pred``
        (1 m, 0.5 rad: a registration farther off is a wrong match); else None."""
        if self.corners is None or kp is None:
            return None
        rel = self.corners.register(scan, kp)
        self.counts["corner_registrations"] = self.corners.attempts
        if rel is None:
            return None
        guess = np.array(compose(self._anchor, rel))
        off = relative_pose(pred, guess)
        if np.hypot(off[0], off[1]) > 1.0 or abs(off[2]) > 0.5:
            return None
        self.counts["corner_registrations_used"] += 1
        return guess

    def _track(
        self, xy: NDArray, pred: NDArray, delta: NDArray, jump: bool, corner: NDArray | None
    ) -> NDArray:
        """The pose of a scan: ICP against the local map from the corner registration
        (``corner``, when there is one) or the odometry prediction; when it fails (too little
        overlap), the prediction (counted). ``front_end=corners``: the corner registration,
        no ICP. Unless the odometry jumped, ICP from a second start when the odometry looks
        wrong (:meth:`_second_guess`), then a correlative search around the prediction when
        the scan still does not fit (:meth:`_rescue`)."""
        opt = self.options
        if opt.front_end == "corners":
            return corner if corner is not None else self._failed(pred)
        if not opt.scan_alignment or self._local is None:
            return pred
        if corner is not None:
            pred = corner
        dist = float(np.hypot(delta[0], delta[1]))
        if jump:
            sig = np.array([1.0, 1.0, 0.5])
        else:
            sxy = opt.odometry_sigma_xy * (dist + 0.1)
            syaw = opt.odometry_sigma_yaw * (abs(float(delta[2])) + dist + 0.1)
            sig = np.array([sxy, sxy, syaw])
        prior = np.diag(1.0 / sig**2)
        aligned = self._icp(xy, pred, prior)
        if not jump:
            share = self._fit_share(xy, aligned.pose)
            steady = np.array(compose(self.pose, self._step))
            if self._disagrees(aligned.pose, pred, sig) or self._disagrees(steady, pred, sig):
                aligned, share = self._second_guess(xy, aligned, share, steady, prior)
            aligned = self._rescue(xy, aligned, share, pred)
        if aligned.overlap >= opt.min_overlap and not (jump and self._lost_at(aligned.pose)):
            return aligned.pose
        if not jump:
            self._lost_at(pred)
        return self._failed(pred)

    def _lost_at(self, pose: NDArray) -> bool:
        """Whether the scan, at ``pose``, sees through the local map's walls (more than
        :data:`LOST_CONFLICT` of its beams): lost (kidnapped, an odometry jump, a time jump
        aligned to the wrong place); the keyframe made for it starts a new segment and
        relocalisation (:mod:`.relocalise`). Asked only when the alignment failed, or after
        a time jump."""
        assert self._local_all is not None and self._pts is not None
        if not self.options.relocalisation or len(self._local_all) < 50:
            return False
        if self._local_occupied is None:
            self._local_occupied = occupancy_keys(self._local_all.xy)
        if scan_conflict(self._local_occupied, self._pts, pose, self.mount) <= LOST_CONFLICT:
            return False
        self._lost = True
        self.counts["lost"] += 1
        return True

    def _fit_share(self, xy: NDArray, pose: NDArray) -> float:
        """Share of the scan's points within half the inlier distance of the local map at
        ``pose``: how the front end compares its candidate alignments."""
        assert self._local_all is not None
        return match_share(xy, self._local_all, pose, 0.5 * self.options.loop_inlier_distance)

    def _rescue(self, xy: NDArray, aligned: Alignment, share: float, pred: NDArray) -> Alignment:
        """When less than :data:`RESCUE_SHARE` of the scan lies within half the inlier
        distance of the local map after ICP (``share``), and :data:`RESCUE_DROP` less than
        usual, a correlative search (:func:`search`,
        window :data:`RESCUE_WINDOW`) around the prediction, refined by ICP, replaces the
        alignment if it puts :data:`RESCUE_GAIN` more of the scan on the map: odometry wrong by
        more than ICP's reach (intel.bag's scans whose stamps are out of order) is recovered,
        and a match that is not clearly better is not taken."""
        assert self._local_all is not None
        usual, self._usual_share = self._usual_share, 0.9 * self._usual_share + 0.1 * share
        if share >= min(RESCUE_SHARE, usual - RESCUE_DROP) or len(self._local_all) < 20:
            return aligned
        self.counts["rescues"] += 1
        if self._local_grid is None:
            self._local_grid = ScoreGrid.build(
                self._local_all.xy, RESCUE_RESOLUTION, RESCUE_RESOLUTION, RESCUE_WINDOW[0] + 1.0
            )
        thin = xy[:: max(1, xy.shape[0] // 200)]
        _, found = search(self._local_grid, thin, pred, *RESCUE_WINDOW)
        found = self._icp(xy, found, np.diag(1.0 / np.array([0.1, 0.1, 0.05]) ** 2))
        if self._fit_share(xy, found.pose) > share + RESCUE_GAIN:
            self.counts["rescues_used"] += 1
            return found
        return aligned

    @staticmethod
    def _disagrees(pose: NDArray, pred: NDArray, sig: NDArray) -> bool:
        """Whether ``pose`` (the alignment's result, or the constant-velocity prediction) is
        more than 3 standard deviations of the odometry from the odometry prediction: the
        odometry may be wrong for this scan."""
        off = np.abs(np.array(relative_pose(pred, pose))) / sig
        return bool(off.max() > 3.0)

    def _second_guess(
        self, xy: NDArray, first: Alignment, share: float, guess: NDArray, prior: NDArray
    ) -> tuple[Alignment, float]:
        """ICP from a second start, the estimate's own last motion repeated (constant velocity),
        kept when more of the scan lies on the map (:meth:`_fit_share`; ``share`` is the
        first alignment's) than from the odometry prediction: the kept alignment and its
        share. Odometry can be wrong in ways a prior cannot absorb: fr079's wheel odometry
        counts a reverse drive as forward motion."""
        self.counts["second_guesses"] += 1
        second = self._icp(xy, guess, prior)
        second_share = self._fit_share(xy, second.pose)
        if (
            second_share > share + 0.02
            and second.overlap >= first.overlap
            and _distinguishable(first, second)
        ):
            self.counts["second_guesses_used"] += 1
            return second, second_share
        return first, share

    def _covariance(self) -> NDArray[np.float64]:
        """The last keyframe's iSAM2 marginal (body frame) plus the scan-alignment noise since
        it, rotated into the map frame."""
        opt = self.options
        cov = (
            self._cov + np.diag([opt.match_sigma_xy, opt.match_sigma_xy, opt.match_sigma_yaw]) ** 2
        )
        assert self.pose is not None
        return rotate_covariance(cov, float(self.pose[2]))

    def _failed(self, pred: NDArray) -> NDArray:
        """Count a failed alignment and keep the prediction (the keyframe link gets the
        odometry's noise)."""
        self.counts["alignment_failures"] += 1
        self._aligned_since_kf = False
        return pred

    def _icp(self, xy: NDArray, guess: NDArray, prior: NDArray) -> Alignment:
        opt = self.options
        assert self._local is not None
        return icp(
            xy,
            self._local,
            guess,
            prior,
            max_distance=opt.icp_max_distance,
            inlier_distance=opt.loop_inlier_distance,
            iterations=opt.icp_iterations,
            overlap_map=self._local_all,
            surface=SURFACE_SPACINGS * opt.point_spacing,
        )

    # ------------------------------------------------------------------ keyframes
    def _make_keyframe(
        self,
        scan: LaserScan,
        pts,
        odo: NDArray,
        stamp: float,
        first: bool = False,
        kp: Keypoints | None = None,
    ) -> None:
        opt = self.options
        assert self.pose is not None
        # a gap the alignment did not bridge, or a scan that fit nothing: a new segment
        cut = (self._jump or self._lost) and not self._aligned_since_kf
        k = self.backend.add_keyframe(self.pose, prior=cut and not first)
        if cut and not first and opt.relocalisation:
            self.reloc.begin(k)
        self._lost = False
        if not first:
            rel = np.array(relative_pose(self._anchor, self.pose))
            self._links.append(None if cut else rel)
            dist = float(np.hypot(rel[0], rel[1]))
            if self._aligned_since_kf:
                sig = (opt.match_sigma_xy, opt.match_sigma_xy, opt.match_sigma_yaw)
            elif cut:
                sig = (10.0, 10.0, 3.0)
            else:
                sxy = opt.odometry_sigma_xy * (dist + 0.1)
                sig = (sxy, sxy, opt.odometry_sigma_yaw * (abs(float(rel[2])) + dist + 0.1))
            self.backend.add_between(k - 1, k, rel, sig)
            self._since_closure += dist
        self.kf.add(scan, pts, len(self._stamps), stamp, odo, self.pose)
        self._corner_keyframe(k, scan, kp, stamp)
        self._place_keyframe(k, scan)
        closed = self._close_loops(k) if opt.loop_closure and not first else False
        if closed:
            self.reloc.end()  # an ordinary closure put the segment into the map
        relocalised = self._relocalise(k) if self.reloc.lost else False
        full = closed or relocalised or k % FULL_ESTIMATE_EVERY == 0
        if full:
            self.submaps.invalidate()
        estimate = self.backend.update(
            extra_iterations=5 if relocalised else 1 if closed else 0,
            full=full,
            recent=opt.local_map_keyframes + 5,
        )
        self.kf.estimate = estimate
        if full and self.tracker is not None:
            self.tracker.refresh()
        self.pose = estimate[k].copy()
        self._anchor = self.pose.copy()
        self._aligned_since_kf = True
        self._jump = False
        self._local, self._local_all = self.kf.local_map(opt.local_map_keyframes)
        self._local_grid = self._local_occupied = None
        self.counts["keyframes"] = len(self.kf)
        self._cov = self.backend.covariance(k)

    def _corner_keyframe(self, k: int, scan: LaserScan, kp: Keypoints | None, stamp: float):
        """Keyframe ``k``'s corners: the corner front end's new reference, and landmark
        observations (associated at the keyframe's current estimate)."""
        if self.corners is None and self.tracker is None:
            return
        if kp is None:
            kp = self._keypoints(scan)
        if self.corners is not None:
            self.corners.set_reference(scan, kp)
        if self.tracker is not None:
            assert self.pose is not None
            self.tracker.observe(k, self.pose, self._cov, kp, stamp)
            self.counts["landmark_observations"] = self.tracker.n_factors

    def _place_keyframe(self, k: int, scan: LaserScan) -> None:
        """Keyframe ``k``'s corners into the place index (``places``)."""
        if not self.options.places.enabled:
            return
        if self._place_detector is None:
            self._place_detector = corner_detector(self.options.places.detector_preset, scan)
        self.places.add(k, scan_corners(scan, self._place_detector, self.mount))

    def _close_loops(self, k: int) -> bool:
        opt = self.options
        if k % opt.loop_every != 0:
            return False
        estimate = np.vstack([self.kf.estimate, self.pose[None, :]])
        sigma = self.backend.marginal_xy_sigma(k - 1) if k > 0 else 0.0
        window = (
            min(opt.loop_search_xy + 3.0 * sigma, MAX_WINDOW_XY),
            min(opt.loop_search_yaw + opt.loop_drift * self._since_closure, MAX_WINDOW_YAW),
        )
        closed = False
        for j in candidates(k, estimate, self.kf.travelled_array(), window[0], opt):
            self.counts["closures_proposed"] += 1
            closure = verify(
                k,
                j,
                self.kf.points,
                estimate,
                self.kf.travelled_array(),
                window,
                opt,
                self.submaps,
            )
            self.closures.append(closure)
            if not closure.accepted:
                continue
            for good in self.gate.offer(closure, estimate):
                self._accept(good)
                closed = True
        self._closed_recently = closed
        if closed:
            self._since_closure = 0.0
        return closed

    def _relocalise(self, k: int) -> bool:
        """A relocalisation attempt for keyframe ``k`` of a lost segment (:mod:`.relocalise`);
        whether it put the segment back into the map (two agreeing closures accepted)."""
        estimate = np.vstack([self.kf.estimate, self.pose[None, :]])
        found = self.reloc.attempt(k, self.kf.points, estimate)
        self.counts["relocalisations_attempted"] = self.reloc.counts["attempted"]
        self.counts["relocalisations_accepted"] = self.reloc.counts["accepted"]
        self.counts["relocalisations_exhaustive"] = self.reloc.counts["exhaustive"]
        for closure in found:
            if closure not in self.closures:
                self.closures.append(closure)
            self._accept(closure)
        if found:
            self._since_closure = 0.0
        return bool(found)

    def _accept(self, closure: LoopClosure) -> None:
        """Put a verified closure into the graph (robust factor); the back end's list of
        closures and ``_in_graph`` keep the same order, which :meth:`result` relies on to
        mark the ones the final optimisation drops."""
        opt = self.options
        closure.accepted = True
        if closure.reason == "pending confirmation":
            closure.reason = "confirmed by a later closure"
        self._in_graph.append(closure)
        sig = (opt.loop_sigma_xy, opt.loop_sigma_xy, opt.loop_sigma_yaw)
        self.backend.add_between(
            closure.match, closure.query, np.array(closure.relative), sig, robust=True
        )

    def _scan_poses(self) -> NDArray[np.float64]:
        """Final pose of every scan (:func:`.rescan.blend_poses`), with ``rescan_final``
        re-registered against the final map (:func:`.rescan.rescan`)."""
        ref = np.asarray(self._ref)
        poses = blend_poses(
            np.asarray(self._stamps), ref, np.asarray(self._rel), self._links, self.kf
        )
        if not self._rescan:
            return poses
        surface = SURFACE_SPACINGS * self.options.point_spacing
        poses, counts = rescan(self._scan_xy, poses, ref, self.kf, self.options, surface)
        self.counts.update(counts)
        return poses

    def _prune(self, closure: LoopClosure) -> None:
        """Mark an accepted closure as dropped by the final optimisation."""
        closure.accepted = False
        closure.reason = "dropped: contradicted by the optimised graph"
        self.counts["closures_pruned"] += 1

    # ------------------------------------------------------------------ result
    def result(self, interrupted: bool = False, partial_reason: str | None = None) -> SlamResult:
        """The current result; with ``final_optimisation``, a batch optimisation runs first,
        and with ``refine_final`` the refinement pass after it; ``partial_reason``: why."""
        graph, values, opt = None, None, self.options
        if len(self.kf):
            if self.options.final_optimisation:
                graph, values = self.backend.optimise()
                if self.options.refine_final:
                    points, travelled = self.kf.points, self.kf.travelled_array()
                    graph, values, counts = refine(self.backend, values, points, travelled, opt)
                    self.counts.update(counts)
                for i in self.backend.pruned:  # indices in the order added to the graph
                    if self._in_graph[i].accepted:
                        self._prune(self._in_graph[i])
            else:
                self.backend.update(full=True)
                graph, values = self.backend.graph, self.backend.values
            self.kf.estimate = self.backend.estimate
        n = len(self._stamps)
        if n:
            poses = self._scan_poses()
        else:
            poses = np.zeros((0, 3))
        landmarks = Landmarks()
        if self.tracker is not None and self.backend.n_landmarks:
            landmarks = self.tracker.landmarks(self.backend.marginals())
        self.counts["landmarks"] = len(landmarks)
        accepted = sum(c.accepted for c in self.closures)
        self.counts["closures_accepted"] = accepted
        self.counts["closures_rejected"] = len(self.closures) - accepted
        self.counts.update(self.backend.counts)
        return SlamResult(
            stamps=np.asarray(self._stamps, dtype=np.float64),
            poses=poses,
            odometry=np.asarray(self._odom, dtype=np.float64).reshape(-1, 3),
            keyframes=np.asarray(self.kf.scan_index, dtype=np.int64),
            keyframe_poses=np.asarray(self.kf.estimate, dtype=np.float64).reshape(-1, 3),
            scans=list(self.kf.scans),
            mount=self.mount.copy(),
            landmarks=landmarks,
            closures=list(self.closures),
            ms_per_scan=np.asarray(self._ms, dtype=np.float64),
            options=self.options,
            counts=dict(self.counts),
            interrupted=interrupted or partial_reason is not None,
            partial_reason=partial_reason,
            warnings=list(self.backend.warnings),
            graph=graph,
            values=values,
            places=self.places if self.options.places.enabled else None,
            cuts=np.asarray(self.kf.scan_index, dtype=np.int64)[[x is None for x in self._links]][
                1:
            ],
        )
