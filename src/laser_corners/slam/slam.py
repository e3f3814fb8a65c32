"""The incremental SLAM: :class:`Slam` (``add(scan, odometry, stamp) -> pose, covariance``).

Per scan: the odometry delta predicts the pose, ICP against the implicit surface of the local
map (the points of the recent keyframes at their current estimates, with their line normals)
corrects it, weighted against the prediction by the odometry noise. A scan becomes a keyframe
after ``keyframe_distance`` / ``keyframe_angle`` of motion: it joins the gtsam graph with a
relative-pose factor to the previous keyframe, loop closures are searched for it, iSAM2
updates, and the local map is rebuilt from the new estimates. Other scans keep their pose
relative to the last keyframe, so their final pose follows the keyframe's final estimate.

:class:`Slam` wires and orchestrates its parts, one job each: :class:`~.tracking.Tracking`
(the front end), :class:`~.keyframer.Keyframer` (keyframes), :class:`~.closing.LoopCloser`
(loop closure, relocalisation), :class:`~.backend.Backend` (the pose graph) and
:mod:`~.finish` (the final graph and trajectory); they count into one
:class:`~.counts.SlamCounts`.
"""

from __future__ import annotations

import time
from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from laser_corners.keypoints import Keypoints
from laser_corners.pose import compose, relative_pose, rotate_covariance
from laser_corners.registration.mapfolder import SavedMap
from laser_corners.registration.points import ScanPoints, scan_points
from laser_corners.scan import LaserScan
from laser_corners.slam.backend import Backend
from laser_corners.slam.closing import LoopCloser
from laser_corners.slam.corners import CornerRegistrar
from laser_corners.slam.finish import ScanLog, slam_result
from laser_corners.slam.grow import grid_occupancy
from laser_corners.slam.keyframer import Keyframer
from laser_corners.slam.landmarks import LandmarkTracker
from laser_corners.slam.options import SlamOptions
from laser_corners.slam.relocalise import Relocaliser
from laser_corners.slam.result import SlamResult
from laser_corners.slam.tracking import Tracking

__all__ = ["Slam"]

FROZEN_REACH = 10.0
"""A run localising in a frozen map (``frozen``) tracks against the map's keyframes within
this distance (m) of its pose, besides its own recent keyframes."""


class _Placement(NamedTuple):
    """What :meth:`Slam.place` asked for the next scan: the placed scan's base ``pose`` (map
    frame), the ``sigmas`` of its prior, and its ``odometry`` when :meth:`Slam.add` did not
    get that scan (None: the last scan given)."""

    pose: NDArray[np.float64]
    sigmas: tuple[float, float, float]
    odometry: NDArray[np.float64] | None


FULL_ESTIMATE_EVERY = 50
"""Every this many keyframes (and after every loop closure) all keyframe estimates are read
back from iSAM2; in between only the recent ones."""


class Slam:
    """Incremental 2D SLAM over laser scans and odometry.

    Parameters
    ----------
    options : SlamOptions, optional
        Defaults: ``SlamOptions()``.
    mount : tuple of float
        Base -> laser transform ``(x, y, yaw)`` (``options.mount`` overrides it).
    backend : Backend, optional
        The pose graph (default: a new :class:`~.backend.Backend`); the run counts into its
        :attr:`~.backend.Backend.counts`.
    prior_map : SavedMap, optional
        A map folder to grow (:mod:`.grow`, read by :func:`~.grow.load_prior_map`): its
        keyframes come first and stay, the run's follow in its frame.
    initial_pose : array_like, optional
        With ``prior_map``: the base pose ``(x, y, yaw)`` of the first scan in the map's frame
        (default: none, a global search of the map).
    frozen : bool
        With ``prior_map``: localisation, the engine's other mode. The map is a frozen
        reference (held by its priors, never written): the scans are tracked against its
        keyframes near the pose as well as the run's own recent ones, loop closures join the
        run's keyframes to it, and the run's segments are placed by the caller
        (:meth:`place`, a fix of the localiser's global search; :meth:`cut` after a lost
        track), not by the engine's own relocalisation (``relocalisation`` is not used).

    Attributes
    ----------
    counts : SlamCounts
        Every counter of the run (:attr:`SlamResult.counts` is its :meth:`~.SlamCounts.as_dict`).
    kf : KeyframeStore
        The keyframes (``keyframer.store``).
    places : PlaceIndex
        Every keyframe's corners and descriptors: relocalisation candidates, and the map
        folder's index for ``localise``.
    tracking, keyframer, closing, log
        The parts: front end, keyframes, loop closure and relocalisation, every scan's record.
    """

    def __init__(
        self,
        options: SlamOptions | None = None,
        mount: ArrayLike = (0.0, 0.0, 0.0),
        backend: Backend | None = None,
        prior_map: SavedMap | None = None,
        initial_pose: ArrayLike | None = None,
        frozen: bool = False,
    ) -> None:
        opt = options or SlamOptions()
        self.frozen = frozen and prior_map is not None
        if self.frozen and opt.relocalisation:
            opt = opt.model_copy(update={"relocalisation": False})
        self.options = opt
        chosen = opt.mount if opt.mount is not None else mount
        self.mount = np.asarray(chosen, dtype=np.float64).reshape(3)
        self.backend = backend if backend is not None else Backend()
        self.counts = self.backend.counts
        self.landmarks = LandmarkTracker(opt, self.mount, self.backend) if opt.landmarks else None
        corners = CornerRegistrar(self.mount) if opt.front_end != "scan" else None
        self.tracking = Tracking(opt, self.mount, self.counts, corners)
        self.keyframer = Keyframer(
            opt, self.mount, self.backend, self.counts, corners, self.landmarks
        )
        self.kf = self.keyframer.store
        given = None if initial_pose is None else np.asarray(initial_pose, float).reshape(3)
        self.initial_pose = given
        """The first scan's given pose in the prior map (None: a global search)."""
        self.prior_folder = None if prior_map is None else str(prior_map.folder)
        if prior_map is not None:
            self.keyframer.seed(prior_map, self.initial_pose is not None, frozen=self.frozen)
            self.counts.prior_keyframes = len(prior_map)
        self.places = self.keyframer.places
        relocaliser = Relocaliser(opt, self.mount, self.places, counts=self.counts)
        self.closing = LoopCloser(opt, self.backend, self.counts, relocaliser)
        if prior_map is not None and prior_map.grid is not None:
            relocaliser.prior = (len(prior_map), grid_occupancy(prior_map.grid))
        # the scan pass re-runs the front end's ICP: only with it
        self.log = ScanLog(opt.rescan_final and opt.scan_alignment and opt.front_end != "corners")
        self.pose: NDArray[np.float64] | None = None
        self._anchor = np.zeros(3)  # the last keyframe's pose in the tracking frame
        self._last_odom = np.zeros(3)
        self._last_stamp = -np.inf
        self._step = np.zeros(3)  # the last scan-to-scan motion of the estimate
        self._cov = np.diag([1e-6, 1e-6, 1e-8])  # the last keyframe's marginal
        self._place: _Placement | None = None  # place() asked for the next scan
        self._cut = False  # cut() asked for the next scan

    # ------------------------------------------------------------------ placing (frozen)
    def place(
        self,
        pose: ArrayLike,
        sigmas: tuple[float, float, float],
        odometry: ArrayLike | None = None,
    ) -> None:
        """A scan's base pose is ``pose`` (map frame) with these standard deviations (m, m,
        rad): the next scan, placed by the odometry step from it, becomes a keyframe starting
        a new segment there under that prior (a fix of a localiser searching the map; loop
        closures then join the segment to the map). ``odometry``: that scan's odometry pose,
        when it was not given to :meth:`add` (a localiser feeds the engine only while it is
        placed); None: the last scan given (before the first scan: the first scan's pose)."""
        at = None if odometry is None else np.asarray(odometry, dtype=np.float64).reshape(3)
        self._place = _Placement(np.asarray(pose, dtype=np.float64).reshape(3).copy(), sigmas, at)

    def cut(self) -> None:
        """The next scan starts a new segment, not placed in the map (a localiser lost its
        track: until :meth:`place`, loop closure keeps to the segment's own keyframes)."""
        self._cut = True

    @property
    def placed(self) -> bool:
        """Whether the current segment is placed in the map's frame (always, without a prior
        map; with one, after a fix: an initial pose, a relocalisation or :meth:`place`)."""
        return self.closing.unplaced is None

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
        opt, tracking = self.options, self.tracking
        odo = np.asarray(odometry_pose, dtype=np.float64).reshape(3)
        pts = scan_points(scan, self.mount, opt.min_range, opt.max_range, opt.point_spacing)
        kp = self.keyframer.keypoints(scan) if tracking.corners is not None else None
        if self.pose is None or self._place is not None or self._cut:
            first, placed = self.pose is None, self._place
            self._place, self._cut = None, False
            if placed is not None and placed.odometry is not None:  # a scan add() did not get
                step = np.array(relative_pose(placed.odometry, odo))
            else:
                step = np.zeros(3) if first else np.array(relative_pose(self._last_odom, odo))
            if placed is not None:
                self.pose = np.array(compose(placed.pose, step))
            elif first:
                self.pose = odo.copy() if self.initial_pose is None else self.initial_pose.copy()
            else:
                self.pose = np.array(compose(self.pose, step))
            self._step = np.zeros(3)
            self._keyframe(scan, pts, odo, stamp, kp, first=first, placed=placed, cut=not first)
        else:
            jump = abs(stamp - self._last_stamp) > opt.time_jump
            delta = np.array(relative_pose(self._last_odom, odo))
            pred = np.array(compose(self.pose, delta))
            corner = tracking.corner_guess(scan, kp, pred, self._anchor)
            steady = np.array(compose(self.pose, self._step))
            last = self.pose
            self.pose = tracking.track(pts, pred, delta, jump, corner, steady)
            self._step = np.array(relative_pose(last, self.pose))
            moved = relative_pose(self._anchor, self.pose)
            if self.keyframer.due(moved, stamp, tracking.jumped, tracking.aligned):
                self._keyframe(scan, pts, odo, stamp, kp)
            else:  # a lost segment's exhaustive search goes on a slice a scan
                self.closing.relocaliser.advance()
        self._last_odom, self._last_stamp = odo, stamp
        rel = np.array(relative_pose(self._anchor, self.pose))
        self.log.add(stamp, odo, len(self.kf) - 1, rel, pts.xy)
        self.log.took((time.perf_counter() - start) * 1e3)
        self.counts.scans += 1
        return self.pose.copy(), self._covariance()

    def _covariance(self) -> NDArray[np.float64]:
        """The last keyframe's iSAM2 marginal (body frame) plus the scan-alignment noise since
        it, rotated into the map frame."""
        opt = self.options
        cov = (
            self._cov + np.diag([opt.match_sigma_xy, opt.match_sigma_xy, opt.match_sigma_yaw]) ** 2
        )
        assert self.pose is not None
        return rotate_covariance(cov, float(self.pose[2]))

    # ------------------------------------------------------------------ keyframes
    def _keyframe(
        self,
        scan: LaserScan,
        pts: ScanPoints,
        odo: NDArray,
        stamp: float,
        kp: Keypoints | None,
        first: bool = False,
        placed: _Placement | None = None,
        cut: bool = False,
    ) -> None:
        """The scan at the tracked pose becomes keyframe ``k``: into the graph, loop closure
        and relocalisation, an iSAM2 update, the new local map. ``placed``: a pose and its
        prior's sigmas (:meth:`place`); ``cut``: a new segment (:meth:`cut`)."""
        opt, tracking = self.options, self.tracking
        assert self.pose is not None
        # a gap the alignment did not bridge, or a scan that fit nothing: a new segment; on a
        # prior map without an initial pose, the session starts lost
        cut = cut or ((tracking.jumped or tracking.lost) and not tracking.aligned and not first)
        cut = cut or (first and self.kf.first > 0 and self.initial_pose is None)
        k, dist = self.keyframer.add(
            scan,
            pts,
            odo,
            stamp,
            len(self.log),
            pose=self.pose,
            anchor=self._anchor,
            cut=cut,
            aligned=tracking.aligned,
            kp=kp,
            cov=self._cov,
            placed=None if placed is None else placed.sigmas,
        )
        if placed is not None:
            self.closing.unplaced = None
        elif cut:
            self.closing.lost_from(k, unplaced=first or self.frozen)
        self.closing.travelled(dist)
        closed, relocalised = self.closing.keyframe(k, self.kf, self.pose, k == 0)
        full = closed or relocalised or k % FULL_ESTIMATE_EVERY == 0
        if full:
            self.closing.submaps.invalidate()
        estimate = self.backend.update(
            extra_iterations=5 if relocalised else 1 if closed else 0,
            full=full,
            recent=opt.local_map_keyframes + 5,
        )
        self.kf.estimate = estimate
        if full and self.landmarks is not None:
            self.landmarks.refresh()
        self.pose = estimate[k].copy()
        self._anchor = self.pose.copy()
        around = self.pose if self.frozen and self.placed else None
        tracking.new_local_map(*self.kf.local_map(opt.local_map_keyframes, around, FROZEN_REACH))
        self.counts.keyframes = len(self.kf)
        self._cov = self.backend.covariance(k)

    # ------------------------------------------------------------------ result
    def result(self, interrupted: bool = False, partial_reason: str | None = None) -> SlamResult:
        """The current result (:func:`~.finish.slam_result`); with ``final_optimisation``, a
        batch optimisation runs first, and with ``refine_final`` the refinement pass after
        it; ``partial_reason``: why the run stopped early."""
        return slam_result(self, interrupted, partial_reason)
