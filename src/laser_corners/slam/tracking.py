"""The SLAM's front end: a scan's pose against the local map (:class:`Tracking`).

ICP against the implicit surface of the local map (the points of the recent keyframes at
their current estimates, with their line normals), weighted against the odometry prediction
by the odometry noise; a second ICP start when the odometry looks wrong, a correlative search
when the scan still does not fit (the rescue), the corner registration's guess
(``front_end`` ``corners``/``both``), and the lost test (the scan sees through the map's
walls). The local map is handed in after every keyframe (:meth:`Tracking.new_local_map`).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from laser_corners.keypoints import Keypoints
from laser_corners.pose import compose, relative_pose, wrap_angle
from laser_corners.registration.align import Alignment, PointMap, icp, match_share
from laser_corners.registration.correlative import ScoreGrid, search
from laser_corners.registration.odometry import JUMP_SIGMAS, odometry_sigmas
from laser_corners.registration.points import ScanPoints
from laser_corners.scan import LaserScan
from laser_corners.slam.corners import CornerRegistrar
from laser_corners.slam.counts import SlamCounts
from laser_corners.slam.options import SlamOptions
from laser_corners.slam.relocalise import LOST_CONFLICT, occupancy_keys, scan_conflict

__all__ = ["SURFACE_SPACINGS", "Tracking", "distinguishable"]

RESCUE_SHARE = 0.5
"""Share of a scan's points within half the inlier distance of the local map below which the
tracking tries a correlative search (:meth:`Tracking._rescue`)."""
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
from the first for the front end to choose between them (:func:`distinguishable`)."""


def distinguishable(first: Alignment, second: Alignment) -> bool:
    """Whether the scan itself tells two alignments apart: their difference, measured with
    the point residuals' information of either (:attr:`Alignment.information`, no prior), is
    more than :data:`DISTINGUISH_SIGMA` standard deviations. Along a corridor it is not: there
    the share of points on the map prefers whichever pose repeats a keyframe's beam pattern,
    which pulls the estimate back towards that keyframe (less motion than driven)."""
    d = second.pose - first.pose  # the information is of the map frame's (x, y, yaw)
    d[2] = wrap_angle(d[2])
    seen = min(float(d @ first.information @ d), float(d @ second.information @ d))
    return seen > DISTINGUISH_SIGMA**2


def disagrees(pose: NDArray, pred: NDArray, sig: NDArray) -> bool:
    """Whether ``pose`` (the alignment's result, or the constant-velocity prediction) is
    more than 3 standard deviations ``sig`` of the odometry from the odometry prediction
    ``pred``: the odometry may be wrong for this scan."""
    off = np.abs(np.array(relative_pose(pred, pose))) / sig
    return bool(off.max() > 3.0)


class Tracking:
    """The pose of every scan against the local map.

    Parameters
    ----------
    options : SlamOptions
    mount : ndarray, shape (3,)
        Base -> laser transform.
    counts : SlamCounts
        Counts time jumps, alignment failures, second guesses, rescues, lost scans and the
        corner registrations used.
    corners : CornerRegistrar, optional
        The corner front end (``front_end`` ``corners``/``both``).

    Attributes
    ----------
    aligned, jumped, lost : bool
        Since the last keyframe: every scan aligned; the stamps jumped
        (``options.time_jump``); the last scan contradicted the local map. Reset by
        :meth:`new_local_map`.
    """

    def __init__(
        self,
        options: SlamOptions,
        mount: NDArray[np.float64],
        counts: SlamCounts,
        corners: CornerRegistrar | None = None,
    ) -> None:
        self.options = options
        self.mount = mount
        self.counts = counts
        self.corners = corners
        self.local: PointMap | None = None  # line points with normals, for ICP
        self.local_all: PointMap | None = None  # every point, for the overlap
        self._grid: ScoreGrid | None = None  # likelihood grid of local_all, when needed
        self._occupied: NDArray[np.int64] | None = None  # cells of local_all
        self._usual_share = 1.0  # recent scans' share on the local map (_rescue)
        self.aligned, self.jumped, self.lost = True, False, False
        self.scan_aligned = True
        """Whether the last scan aligned (:attr:`aligned`: every scan since the keyframe)."""

    def new_local_map(self, local: PointMap, local_all: PointMap) -> None:
        """A keyframe was made: track against ``local`` (line points with normals) and
        ``local_all`` (every point) from now on."""
        self.local, self.local_all = local, local_all
        self._grid = self._occupied = None
        self.aligned, self.jumped, self.lost = True, False, False

    def corner_guess(
        self, scan: LaserScan, kp: Keypoints | None, pred: NDArray, anchor: NDArray
    ) -> NDArray | None:
        """The base pose from the corner registration to the last keyframe (at ``anchor``),
        when accepted and within the odometry's reach of ``pred`` (1 m, 0.5 rad: a
        registration farther off is a wrong match); else None."""
        if self.corners is None or kp is None:
            return None
        rel = self.corners.register(scan, kp)
        self.counts.corner_registrations = self.corners.attempts
        if rel is None:
            return None
        guess = np.array(compose(anchor, rel))
        off = relative_pose(pred, guess)
        if np.hypot(off[0], off[1]) > 1.0 or abs(off[2]) > 0.5:
            return None
        self.counts.corner_registrations_used += 1
        return guess

    def track(
        self,
        pts: ScanPoints,
        pred: NDArray,
        delta: NDArray,
        jump: bool,
        corner: NDArray | None,
        steady: NDArray,
    ) -> NDArray:
        """The pose of a scan (points ``pts``, base frame): ICP against the local map from
        the corner registration (``corner``, when there is one) or the odometry prediction
        ``pred`` (odometry motion ``delta``); when it fails (too little overlap), the
        prediction (counted). ``front_end=corners``: the corner registration, no ICP. Unless
        the odometry jumped (``jump``), ICP from ``steady`` (the last motion repeated) when
        the odometry looks wrong (:meth:`_second_guess`), then a correlative search around
        the prediction when the scan still does not fit (:meth:`_rescue`)."""
        opt, xy = self.options, pts.xy
        self.scan_aligned = True
        if jump:
            self.counts.time_jumps += 1
            self.jumped = True
        if opt.front_end == "corners":
            return corner if corner is not None else self._failed(pred)
        if not opt.scan_alignment or self.local is None:
            return pred
        if corner is not None:
            pred = corner
        sig = JUMP_SIGMAS if jump else odometry_sigmas(delta, opt.odometry)
        prior = np.diag(1.0 / sig**2)
        aligned = self._icp(xy, pred, prior)
        if not jump:
            share = self.fit_share(xy, aligned.pose)
            if disagrees(aligned.pose, pred, sig) or disagrees(steady, pred, sig):
                aligned, share = self._second_guess(xy, aligned, share, steady, prior)
            aligned = self._rescue(xy, aligned, share, pred)
        if aligned.overlap >= opt.min_overlap and not (jump and self.lost_at(pts, aligned.pose)):
            return aligned.pose
        if not jump:
            self.lost_at(pts, pred)
        return self._failed(pred)

    def lost_at(self, pts: ScanPoints, pose: NDArray) -> bool:
        """Whether the scan ``pts``, at ``pose``, sees through the local map's walls (more
        than :data:`LOST_CONFLICT` of its beams): lost (kidnapped, an odometry jump, a time
        jump aligned to the wrong place); the keyframe made for it starts a new segment and
        relocalisation (:mod:`.relocalise`). Asked only when the alignment failed, or after
        a time jump."""
        assert self.local_all is not None
        if not self.options.relocalisation or len(self.local_all) < 50:
            return False
        if self._occupied is None:
            self._occupied = occupancy_keys(self.local_all.xy)
        if scan_conflict(self._occupied, pts, pose, self.mount) <= LOST_CONFLICT:
            return False
        self.lost = True
        self.counts.lost += 1
        return True

    def fit_share(self, xy: NDArray, pose: NDArray) -> float:
        """Share of the scan's points ``xy`` within half the inlier distance of the local map
        at ``pose``: how the front end compares its candidate alignments."""
        assert self.local_all is not None
        return match_share(xy, self.local_all, pose, 0.5 * self.options.inlier_distance)

    def _rescue(self, xy: NDArray, aligned: Alignment, share: float, pred: NDArray) -> Alignment:
        """When less than :data:`RESCUE_SHARE` of the scan lies within half the inlier
        distance of the local map after ICP (``share``), and :data:`RESCUE_DROP` less than
        usual, a correlative search (:func:`search`,
        window :data:`RESCUE_WINDOW`) around the prediction, refined by ICP, replaces the
        alignment if it puts :data:`RESCUE_GAIN` more of the scan on the map: odometry wrong by
        more than ICP's reach (intel.bag's scans whose stamps are out of order) is recovered,
        and a match that is not clearly better is not taken."""
        assert self.local_all is not None
        usual, self._usual_share = self._usual_share, 0.9 * self._usual_share + 0.1 * share
        if share >= min(RESCUE_SHARE, usual - RESCUE_DROP) or len(self.local_all) < 20:
            return aligned
        self.counts.rescues += 1
        if self._grid is None:
            self._grid = ScoreGrid.build(
                self.local_all.xy, RESCUE_RESOLUTION, RESCUE_RESOLUTION, RESCUE_WINDOW[0] + 1.0
            )
        thin = xy[:: max(1, xy.shape[0] // 200)]
        _, found = search(self._grid, thin, pred, *RESCUE_WINDOW)
        found = self._icp(xy, found, np.diag(1.0 / np.array([0.1, 0.1, 0.05]) ** 2))
        if self.fit_share(xy, found.pose) > share + RESCUE_GAIN:
            self.counts.rescues_used += 1
            return found
        return aligned

    def _second_guess(
        self, xy: NDArray, first: Alignment, share: float, guess: NDArray, prior: NDArray
    ) -> tuple[Alignment, float]:
        """ICP from a second start, the estimate's own last motion repeated (constant velocity),
        kept when more of the scan lies on the map (:meth:`fit_share`; ``share`` is the
        first alignment's) than from the odometry prediction: the kept alignment and its
        share. Odometry can be wrong in ways a prior cannot absorb: fr079's wheel odometry
        counts a reverse drive as forward motion."""
        self.counts.second_guesses += 1
        second = self._icp(xy, guess, prior)
        second_share = self.fit_share(xy, second.pose)
        if (
            second_share > share + 0.02
            and second.overlap >= first.overlap
            and distinguishable(first, second)
        ):
            self.counts.second_guesses_used += 1
            return second, second_share
        return first, share

    def _failed(self, pred: NDArray) -> NDArray:
        """Count a failed alignment and keep the prediction (the keyframe link gets the
        odometry's noise)."""
        self.counts.alignment_failures += 1
        self.aligned = self.scan_aligned = False
        return pred

    def _icp(self, xy: NDArray, guess: NDArray, prior: NDArray) -> Alignment:
        opt = self.options
        assert self.local is not None
        return icp(
            xy,
            self.local,
            guess,
            prior,
            opt.icp,
            inlier_distance=opt.inlier_distance,
            overlap_map=self.local_all,
            surface=SURFACE_SPACINGS * opt.point_spacing,
        )
