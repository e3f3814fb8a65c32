"""The incremental localiser: :class:`Localiser` (``add(scan, odometry, stamp) -> estimate``).

Three states (:attr:`Localiser.status`):

``global``
    No fix yet. On every scan the map's place index (corner keypoints of the last metres,
    :mod:`.places`) proposes poses; where it has none for ``places.fallback_travel`` (or the
    map has no index), at most every ``global_every`` scans the exhaustive search over the
    whole map (:meth:`~laser_corners.localise.mapmodel.MapModel.global_search`) does. Each
    pose becomes a hypothesis, refined by ICP against the map's points. Every scan, every
    hypothesis is moved by the odometry step, aligned again (point-to-line ICP,
    :func:`~laser_corners.registration.align.icp`) and scored by its *agreement*: the share of
    the scan's points within ``inlier_distance`` of a map point. Hypotheses whose recent agreement
    falls below ``hypothesis_agreement`` are dropped; two that meet are merged. The fix is
    declared only when one hypothesis has survived ``fix_travel`` metres and ``fix_scans``
    scans, agrees at least ``fix_agreement`` and every other surviving hypothesis agrees less
    by ``fix_margin``: in a symmetric or ambiguous map several hypotheses keep agreeing and no
    fix is given (no estimate is better than a confident wrong one).
    A hypothesis, and the fix, must also not contradict the map's free space (beams ending
    where the map saw free space, or seeing through its walls: :mod:`.freespace`) on more
    than ``max_conflict`` of the beams (what the map is sure of) nor ``max_loose_conflict``
    (any evidence), nor over the history since the search started (the search's past scans
    chained back from the winner by odometry); a winner whose scans partly end outside the map
    needs ``outside_travel`` times the travel.
``tracking``
    Odometry predicts, ICP against the map corrects (the odometry noise is the prior), the
    covariance is the inverse of the ICP information plus the prior's (with a floor for the
    map's own error). A scan agreeing less than ``track_agreement``, with more than
    ``max_outside`` of its beams outside the map, or whose last ``conflict_scans`` contradict
    the map's free space on more than ``track_conflict`` of the beams on average (the track
    slid to a look-alike place, or the robot left the map), gives no estimate.
    The scan is also aligned to a local submap of the recent scans' points that the map
    does not explain (:mod:`.local`) and the two alignments are fused by their information:
    where the robot drives out of the map the unmapped part of the scan holds the pose (a
    corridor whose far end is unmapped cannot drag it back). A scan with more than
    ``partly_outside`` of its beams outside the map that agrees with map and local submap
    together gets a ``"local"`` estimate (chained to the last anchored pose, covariance
    growing); once the map explains it again the estimate is anchored again.
``lost``
    ``lost_scans`` such scans in a row: the fix is dropped and the search starts again; the
    next fix is reported as ``relocalised``. Unless the loss followed an odometry or time
    jump, the search first looks only inside the *window* of the lost track's dead-reckoned
    pose (:mod:`.window`: 3σ of an uncertainty growing with the travel), where a winner needs
    ``reacquire_travel`` instead of ``fix_travel``, is scored among the points the map could
    explain and is not judged on the scans since the loss; once the window is wider than
    ``reacquire_xy`` / ``reacquire_yaw``, the global search over the whole map takes over (a
    kidnapped robot).

The online poses come from the SLAM engine on the map frozen (:mod:`.engine`, ``engine``):
placed by the fixes, confirmed by the tracker, cut at an odometry or time jump; where the map
gives no estimate, the confirmed engine holds the pose when the scan fits its own keyframes
and does not contradict the map's free space.
"""

from __future__ import annotations

import math
import time
from collections import deque
from enum import Enum
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike, NDArray

from laser_corners.localise.engine import EngineTrack
from laser_corners.localise.estimate import Fix, LocaliserEstimate, timing_record
from laser_corners.localise.hypotheses import Hypothesis
from laser_corners.localise.local import LocalMap
from laser_corners.localise.mapmodel import GLOBAL_SIGMA, MapModel
from laser_corners.localise.matcher import MapMatcher
from laser_corners.localise.options import LocaliseOptions
from laser_corners.localise.places import PlaceProposer
from laser_corners.localise.search import GlobalSearch
from laser_corners.localise.tracker import FIX_COVARIANCE, Tracker
from laser_corners.localise.window import Window
from laser_corners.pose import between_many
from laser_corners.registration.mapfolder import SavedMap, load_map
from laser_corners.registration.points import scan_points
from laser_corners.scan import LaserScan

__all__ = ["Fix", "Hypothesis", "Localiser", "LocaliserEstimate", "State"]

COUNT_KEYS = (
    "scans",
    "estimates",
    "lost",
    "searches",
    "search_slices",
    "no_agreement",
    "recoveries",
    "refused_free_space",
    "refused_history",
    "local",
    "reacquired",
    "place_attempts",
    "credited",
    "engine_replaced",
)
"""The localiser's counters (:attr:`Localiser.counts`)."""


class State(str, Enum):
    """The localiser's states (see the module notes)."""

    GLOBAL = "global"
    """No fix yet: the global search."""
    TRACKING = "tracking"
    """A fix, tracked scan by scan."""
    LOST = "lost"
    """The track was lost: searching again (first inside the lost track's window)."""


class Localiser:
    """Localisation in a saved map with odometry (see the module notes).

    A state machine over two parts: :class:`~laser_corners.localise.search.GlobalSearch`
    (states ``global`` and ``lost``) and :class:`~laser_corners.localise.tracker.Tracker`
    (``tracking``). The search's winner starts the tracker; a lost track restarts the search.

    Parameters
    ----------
    map_data : str, Path or SavedMap
        A map folder written by ``laser-corners slam`` (or one already loaded).
    options : LocaliseOptions, optional
    mount : tuple of float, optional
        Base -> laser transform ``(x, y, yaw)``; default the map's (``options.mount``
        overrides both).

    Raises
    ------
    InputError
        The map folder is missing, incomplete or of another format version.
    """

    def __init__(
        self,
        map_data: str | Path | SavedMap,
        options: LocaliseOptions | None = None,
        mount: ArrayLike | None = None,
    ) -> None:
        self.options = options or LocaliseOptions()
        saved = map_data if isinstance(map_data, SavedMap) else load_map(map_data)
        chosen = self.options.mount if self.options.mount is not None else mount
        self.mount = np.asarray(saved.mount if chosen is None else chosen, float).reshape(3)
        self.map = MapModel(saved, self.options)
        self.counts = dict.fromkeys(COUNT_KEYS, 0)
        self.fixes: list[Fix] = []
        self.ms_per_scan: deque[float] = timing_record()
        """Milliseconds of :meth:`add` for the last 10,000 scans
        (:data:`~laser_corners.localise.estimate.TIMINGS_KEPT`; a whole recording's:
        :func:`~laser_corners.localise.run.run_localise`), oldest first."""
        self.local = LocalMap(self.map.grid, GLOBAL_SIGMA)
        """Recent scans' points the map does not explain (tracking into unmapped space)."""
        matcher = MapMatcher(self.map, self.options, self.mount)
        places = PlaceProposer(
            saved.places, saved.poses, self.map.grid, self.mount, self.options.places
        )
        self.tracker = Tracker(matcher, self.local, self.counts)
        self.search = GlobalSearch(matcher, places, self.local, self.counts)
        self.state = State.GLOBAL
        self.engine: EngineTrack | None = None
        """The engine giving the online poses (``engine``; None for a ``map_server`` map)."""
        if self.options.engine.enabled and saved.virtual_scans is None:
            self.engine = EngineTrack(saved, self.options, self.mount, self.counts)
        self._last_odom: NDArray | None = None
        self._last_stamp = -math.inf

    # ------------------------------------------------------------------ the parts' state
    @property
    def status(self) -> str:
        """``"global"`` (no fix yet), ``"tracking"`` or ``"lost"`` (searching again)."""
        return self.state.value

    @property
    def pose(self) -> NDArray[np.float64] | None:
        """The tracked base pose in the map (None while searching)."""
        return self.tracker.pose

    @property
    def hypotheses(self) -> list[Hypothesis]:
        """The search's hypotheses (empty while tracking)."""
        return self.search.hypotheses

    @property
    def window(self) -> Window | None:
        """The lost track's dead-reckoned pose, searched around while it is narrow enough."""
        return self.search.window

    @property
    def places(self) -> PlaceProposer:
        """The map's place index: global candidates from corner keypoints (``places``)."""
        return self.search.places

    @property
    def search_ms(self) -> deque[float]:
        """Milliseconds of the last 10,000 slices of an exhaustive correlative search (global
        or window; :data:`~laser_corners.localise.estimate.TIMINGS_KEPT`): one a scan while a
        search runs (``registration.global_search.SLICE_NODES`` nodes at most); how many ran:
        ``counts["search_slices"]``."""
        return self.search.search_ms

    def set_pose(self, pose: ArrayLike, covariance: ArrayLike | None = None) -> None:
        """Start tracking from ``pose`` (base in the map frame), e.g. an initial pose."""
        cov = None if covariance is None else np.asarray(covariance, dtype=np.float64)
        self.tracker.start(np.asarray(pose, dtype=np.float64), cov)
        self.search.stop()
        self.state = State.TRACKING
        if self.engine is not None:
            self.engine.place(self.tracker.pose, self.tracker.covariance, self._last_odom)

    # ------------------------------------------------------------------ per scan
    def add(
        self, scan: LaserScan, odometry_pose: ArrayLike, stamp: float
    ) -> LocaliserEstimate | None:
        """Add one scan with the base's odometry pose at its stamp.

        Returns
        -------
        LocaliserEstimate or None
            None while there is no fix, or when this scan does not agree with the map.
        """
        start = time.perf_counter()
        opt = self.options
        odo = np.asarray(odometry_pose, dtype=np.float64).reshape(3)
        delta = np.zeros(3) if self._last_odom is None else between_many(self._last_odom, odo)
        jump = (
            math.hypot(delta[0], delta[1]) > opt.odometry_jump
            or abs(delta[2]) > opt.odometry_jump
            or abs(stamp - self._last_stamp) > opt.time_jump
        ) and self._last_odom is not None
        self._last_odom, self._last_stamp = odo, float(stamp)
        pts = scan_points(scan, self.mount, opt.min_range, opt.max_range, opt.point_spacing)
        index = self.counts["scans"]
        self.counts["scans"] += 1
        if self.engine is not None:
            if jump:  # the odometry or the stamps jumped: the engine's segment ends here
                self.engine.cut()
            self.engine.add(scan, odo, float(stamp))
        if self.state is State.TRACKING:
            estimate = self.tracker.step(pts, delta, jump, odo, index, float(stamp))
            if estimate is None and self._engine_holds(pts.xy):
                assert self.engine is not None
                estimate = self.engine.alone(odo, index, float(stamp))
                self.tracker.follow(self.engine.pose)
            if self.tracker.lost:
                self._lose(index)
        else:
            estimate = self._search(scan, pts, delta, jump, odo, index, float(stamp))
        if self.engine is not None and estimate is not None:
            estimate = self._engine(odo, estimate, pts.xy)
        self.ms_per_scan.append((time.perf_counter() - start) * 1e3)
        if estimate is not None:
            self.counts["estimates"] += 1
        return estimate

    def _engine_holds(self, xy: NDArray) -> bool:
        """Whether the engine holds a scan the map gave no estimate for (:meth:`.EngineTrack.holds`)
        and the scan, at the engine's pose, does not contradict the map's free space (a kidnap
        to a look-alike place inside the map does; driving out of the map does not)."""
        if self.engine is None or not self.engine.holds():
            return False
        support = self.tracker.matcher.support(self.engine.pose, xy)
        return support.conflict <= self.options.track_conflict

    def _engine(self, odo: NDArray, estimate: LocaliserEstimate, xy: NDArray) -> LocaliserEstimate:
        """This scan's estimate with the engine's pose (:mod:`.engine`). Where the tracker,
        anchored in the map, disagrees: at a fix (or with the engine unplaced), the tracker's
        pose, and the engine is placed there from the next scan on; on a tracked scan the map
        settles it (:meth:`.EngineTrack.settle`): the engine stands and the tracker follows
        it, or the tracker's pose (the engine re-placed there after ``engine.gate_scans``)."""
        engine = self.engine
        assert engine is not None
        # a "local" estimate (mostly unmapped) is the engine's own, never a reason to re-place
        if estimate.status == "local" or not engine.disagrees(estimate.pose):
            return engine.estimate(estimate, odo)
        if estimate.status == "tracking" and engine.pose is not None:
            side = engine.settle(estimate.pose, lambda p: self.tracker.matcher.agreement(p, xy))
            if side == "engine":  # the map sided with the engine: the tracker follows it
                self.tracker.follow(engine.pose)
                return engine.estimate(estimate, odo)
            if side == "tracker":
                return estimate
            self.counts["engine_replaced"] += 1
        engine.place(estimate.pose, self.tracker.covariance, odo)
        return estimate

    def _lose(self, index: int) -> None:
        """Drop the fix: back to the search, with the predicted pose as the first hypothesis.
        Unless the loss followed an odometry or time jump, the search stays inside the window
        of the dead-reckoned pose while it is narrow enough (``localise.window``)."""
        covariance = self.tracker.covariance
        recent_jump = self.tracker.since_jump <= self.options.lost_scans
        pose = self.tracker.stop()
        window = None if recent_jump else Window.from_covariance(pose, covariance)
        self.search.restart(pose, index, window)
        self.state = State.LOST
        self.counts["lost"] += 1

    def _search(
        self, scan, pts, delta: NDArray, jump: bool, odo: NDArray, index: int, stamp: float
    ) -> LocaliserEstimate | None:
        """One scan of the search; on a winner, the fix: tracking starts from it."""
        winner = self.search.step(scan, pts, delta, jump, odo, index)
        if winner is None:
            return None
        windowed = self.search.window is not None
        self.counts["reacquired"] += windowed
        pose = tuple(winner.pose.tolist())
        self.fixes.append(Fix(index, stamp, self.search.travel, pose, windowed))
        self.search.stop()
        self.tracker.start(winner.pose, FIX_COVARIANCE, list(winner.recent))
        self.state = State.TRACKING
        return self.tracker.estimate(odo, index, stamp, "relocalised", winner.recent[-1])
