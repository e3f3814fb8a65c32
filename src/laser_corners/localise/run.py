"""Localisation over a recording: :func:`run_localise`.

The odometry is read as :func:`~laser_corners.slam.run_slam` reads it (bags: odometry at the
scan stamp composed with the mount from ``/tf_static``, undone to the base; CARMEN logs: the
FLASER/ROBOTLASER1 pose with a zero mount). Scans without a pose are counted and skipped; a
recording without any odometry is one :class:`~laser_corners.errors.InputError` line.

As ``run_slam``, a run that stops early (Ctrl-C, SIGTERM, an error while localising a scan after
the first) still gives what it did, with ``partial_reason``.
"""

from __future__ import annotations

import signal
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike, NDArray

from laser_corners.errors import InputError, LaserCornersError, first_line
from laser_corners.localise.localiser import Fix, Localiser, LocaliserEstimate
from laser_corners.localise.options import LocaliseOptions
from laser_corners.localise.smooth import Smoothed, smooth
from laser_corners.pipeline.interrupt import STOP_REASONS
from laser_corners.pipeline.recording import open_recording
from laser_corners.pose import check_pose
from laser_corners.registration.mapfolder import SavedMap, load_map
from laser_corners.slam.options import map_options
from laser_corners.slam.run import OdometryFeed, odometry_scans, require_odometry
from laser_corners.slam.slam import Slam

__all__ = ["InitialPose", "LocaliseRun", "run_localise"]


@dataclass
class InitialPose:
    """The pose given for the first scan (``initial_pose``) and what became of it.

    Attributes
    ----------
    pose : tuple of float
        Base pose ``(x, y, yaw)`` in the map, as given.
    accepted : bool or None
        True: the localiser tracked from it (an estimate came before any loss); False: it
        lost the track before any estimate (then searched globally); None: neither happened.
    rejected_at_scan : int or None
        The recording's scan index at which the track from it was lost.
    """

    pose: tuple[float, float, float]
    accepted: bool | None = None
    rejected_at_scan: int | None = None

    def follow(self, index: int, estimate: LocaliserEstimate | None, lost: int) -> None:
        """Note the outcome of scan ``index`` (``lost``: the localiser's lost count)."""
        if self.accepted is not None:
            return
        if estimate is not None:
            self.accepted = True
        elif lost:
            self.accepted, self.rejected_at_scan = False, index


@dataclass
class LocaliseRun:
    """What :func:`run_localise` gives.

    Attributes
    ----------
    estimates : list of LocaliserEstimate
        One per scan that got a pose (``scan_index``: the scan's index in the recording).
    fixes : list of Fix
        The first fix and every relocalisation (``scan_index`` in the recording too).
    counts : dict of str to int
        ``scans, estimates, lost, searches, no_agreement, recoveries, refused_free_space,
        skipped_no_odometry, scans_read`` (the recording's scans read, from index 0 on).
    ms_per_scan : ndarray
        Milliseconds of :meth:`Localiser.add` for every scan given (the whole run; the
        localiser itself keeps the last ``TIMINGS_KEPT``).
    odometry_stamps, odometry : ndarray
        Stamp and base odometry of every scan given.
    interrupted : bool
        The run stopped before the end of the recording (see ``partial_reason``).
    partial_reason : str or None
        Why: ``"interrupted (Ctrl-C)"``, ``"terminated (SIGTERM)"`` or the error at a scan.
    positions : ndarray of int
        Index of each estimate's scan among the scans given (into ``odometry_stamps``).
    smoothed : Smoothed or None
        With ``options.smooth.enabled``: every scan (before the first fix too) placed by the
        localiser's anchors on the SLAM's chain (:mod:`.smooth`); ``index`` into
        ``odometry_stamps``.
    slam_ms_per_scan : ndarray
        The SLAM's time per scan (with ``options.smooth.enabled``), apart from ``ms_per_scan``.
    skipped : dict of str to int
        Records the reader skipped (damaged chunks, broken rows), by reason (``ScanSource``).
    initial : InitialPose or None
        The given initial pose and whether the localiser kept it.
    """

    estimates: list[LocaliserEstimate]
    fixes: list[Fix]
    counts: dict[str, int]
    ms_per_scan: NDArray[np.float64]
    odometry_stamps: NDArray[np.float64] = field(default_factory=lambda: np.zeros(0))
    odometry: NDArray[np.float64] = field(default_factory=lambda: np.zeros((0, 3)))
    interrupted: bool = False
    positions: NDArray[np.int64] = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    smoothed: Smoothed | None = None
    slam_ms_per_scan: NDArray[np.float64] = field(default_factory=lambda: np.zeros(0))
    partial_reason: str | None = None
    skipped: dict[str, int] = field(default_factory=dict)
    initial: InitialPose | None = None

    @property
    def stamps(self) -> NDArray[np.float64]:
        """Stamps of the estimates."""
        return np.array([e.stamp for e in self.estimates], dtype=np.float64)

    @property
    def poses(self) -> NDArray[np.float64]:
        """Base poses in the map frame of the estimates, shape (E, 3)."""
        return np.array([e.pose for e in self.estimates], dtype=np.float64).reshape(-1, 3)


def run_localise(
    map_data: str | Path | SavedMap,
    path: str | Path,
    options: LocaliseOptions | None = None,
    *,
    topic: str | None = None,
    odom_topic: str | None = None,
    start_scan: int = 0,
    stop_scan: int | None = None,
    initial_pose: ArrayLike | None = None,
    on_estimate: Callable[[LocaliserEstimate], None] | None = None,
    progress: Callable[[int, int | None, float], None] | None = None,
) -> LocaliseRun:
    """Localise a recording with odometry in a saved map.

    Parameters
    ----------
    map_data : str, Path or SavedMap
        Map folder of ``laser-corners slam``.
    path : str or Path
        Recording with LaserScan and odometry.
    options : LocaliseOptions, optional
    topic : str, optional
        LaserScan topic of a bag (default: the only one).
    odom_topic : str, optional
        Odometry of a bag: a ``nav_msgs/Odometry`` topic or ``"tf"`` (as ``run_slam``).
    start_scan, stop_scan : int
        Use the scans ``start_scan <= i < stop_scan`` of the recording.
    initial_pose : array of 3, optional
        Base pose in the map at the first scan used (skips the global search).
    on_estimate : callable, optional
        Called with every estimate as it comes (incremental output).
    progress : callable, optional
        Called after every scan with ``(scan index, scans total or None, stamp)``.

    Raises
    ------
    InputError
        The map folder is bad, or the recording has no odometry, or it never found itself in
        the map (no estimate within ``options.give_up_travel`` metres of travel).
    ValueError
        ``initial_pose`` is not 3 finite numbers (x, y within ``pose.MAX_COORDINATE``).
    """
    options = options or LocaliseOptions()
    with open_recording(path, topic, odom_topic=odom_topic) as rec:
        require_odometry(rec, path)
        recorded = getattr(rec.source, "mounts", {}).get(rec.first.frame_id)
        saved = map_data if isinstance(map_data, SavedMap) else load_map(map_data)
        loc = Localiser(saved, options, mount=recorded)
        initial = None
        if initial_pose is not None:
            initial = InitialPose(tuple(map(float, check_pose(initial_pose, "initial_pose"))))
            loc.set_pose(initial.pose)
        slam = smoothing_slam(saved, loc.mount) if options.smooth.enabled else None
        watch = _Watch(initial, options.give_up_travel, path, saved.folder)
        run = _loop(loc, slam, rec, (start_scan, stop_scan), (on_estimate, progress), watch)
        run.skipped = dict(rec.source.skipped)
        run.initial = initial
    if loc.counts["scans"] == 0 and not run.interrupted:
        seen = run.counts["scans_read"]
        if start_scan >= seen:
            raise InputError(
                f"{path}: no scan from index {start_scan} on; the recording has {seen} scans"
                + (f" (0 to {seen - 1})" if seen else "")
            )
        skipped = run.counts["skipped_no_odometry"]
        raise InputError(f"{path}: no scan with odometry ({skipped} scans without a pose)")
    broken = run.partial_reason not in (None, *STOP_REASONS.values())
    if slam is not None and slam.counts.scans and not broken:  # (an error: SLAM half-fed)
        try:
            result = slam.result(interrupted=run.interrupted)
            run.slam_ms_per_scan = result.ms_per_scan
            run.smoothed = smooth(run.estimates, run.positions, result, options)
        except KeyboardInterrupt:  # Ctrl-C while smoothing: the online estimates stand
            run.interrupted = True
            run.partial_reason = run.partial_reason or STOP_REASONS[signal.SIGINT]
    return run


def smoothing_slam(saved: SavedMap, mount: NDArray[np.float64]) -> Slam:
    """The SLAM of the smoothed trajectory: the options the map was made with (its
    ``options.yaml``; defaults without one), the localiser's mount."""
    options = map_options(saved.folder).with_overrides({"mount": tuple(map(float, mount))})
    return Slam(options, mount)


@dataclass
class _Watch:
    """What the loop watches besides the scans: the initial pose's fate, and the travel
    without any estimate (a recording of another place: give up after ``give_up`` m)."""

    initial: InitialPose | None
    give_up: float
    path: str | Path
    map_folder: Path
    travel: float = 0.0
    last: NDArray[np.float64] | None = None

    def scan(self, index: int, estimate, base: NDArray, lost: int, found: bool) -> None:
        """Note scan ``index``; :class:`InputError` when the run should give up."""
        if self.initial is not None:
            self.initial.follow(index, estimate, lost)
        if self.last is not None:
            self.travel += float(np.hypot(*(base[:2] - self.last[:2])))
        self.last = base
        if not found and 0 < self.give_up < self.travel:
            raise InputError(
                f"{self.path}: never found itself in the map {self.map_folder}: no fix after "
                f"{self.travel:.0f} m of travel (give_up_travel = {self.give_up:g} m); a "
                "recording of another place?"
            )


def _loop(loc, slam, rec, span, callbacks, watch: _Watch) -> LocaliseRun:
    """Feed the scans (``span``: start and stop scan) to the localiser and the SLAM (when
    smoothing); Ctrl-C stops between two scans. ``callbacks``: ``on_estimate`` and
    ``progress`` (or None)."""
    on_estimate, progress = callbacks
    estimates: list[LocaliserEstimate] = []
    stamps: list[float] = []
    index: list[int] = []
    positions: list[int] = []
    odometry: list[NDArray] = []
    ms: list[float] = []  # every scan's: the localiser keeps the last TIMINGS_KEPT only
    feed = OdometryFeed()
    try:
        for i, scan, base in odometry_scans(rec, feed, *span):
            feed.at = i
            estimate = loc.add(scan, base, float(scan.stamp))
            ms.append(loc.ms_per_scan[-1])
            if slam is not None:
                slam.add(scan, base, float(scan.stamp))
            index.append(i)
            stamps.append(float(scan.stamp))
            odometry.append(base)
            if estimate is not None:
                positions.append(estimate.scan_index)
                estimate.scan_index = i  # the recording's index, not the localiser's
                estimates.append(estimate)
                if on_estimate is not None:
                    on_estimate(estimate)
            watch.scan(i, estimate, base, loc.counts["lost"], bool(estimates))
            if progress is not None:
                progress(i + 1, rec.source.n_scans, float(scan.stamp))
    except KeyboardInterrupt:
        feed.stopped(STOP_REASONS[signal.SIGINT], signal.SIGINT)
    except Exception as exc:
        if not stamps or (not estimates and isinstance(exc, LaserCornersError)):
            raise  # nothing done (or found) yet: the error is the run's, one line
        feed.stopped(f"{type(exc).__name__} at scan {feed.at}: {first_line(exc)}")
    counts = dict(loc.counts, skipped_no_odometry=feed.skipped, scans_read=feed.seen)
    return LocaliseRun(
        estimates,
        [
            replace(f, scan_index=index[f.scan_index])
            for f in loc.fixes
            if f.scan_index < len(index)
        ],
        counts,
        np.asarray(ms, dtype=np.float64),
        np.asarray(stamps, dtype=np.float64),
        np.asarray(odometry, dtype=np.float64).reshape(-1, 3),
        feed.interrupted,
        np.asarray(positions, dtype=np.int64),
        partial_reason=feed.reason,
    )
