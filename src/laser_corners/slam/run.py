"""SLAM over a recording: :func:`run_slam`.

Bags (ROS 1/2, MCAP): each scan's ``pose`` is the laser pose in the odometry frame (odometry
interpolated at the scan stamp, composed with the base -> laser mount from ``/tf_static``);
the base pose is that pose composed with the inverse mount, read once from the bag's
transform tree. ``SlamOptions.mount`` overrides the mount. CARMEN logs: the laser pose of
each FLASER/ROBOTLASER1 line is used as odometry with a zero mount (in a raw log it is the
odometry; in a ``*-corrected`` log it is already a map pose, so SLAM on it only refines it).
Scans without a pose are counted (``skipped_no_odometry``) and skipped.

A run that stops early still gives what it mapped (``SlamResult.partial_reason`` says why):
Ctrl-C or SIGTERM between two scans, or an error while mapping a scan (a bug, a recording that
breaks off) after the first one; an error before any scan was mapped is raised.
"""

from __future__ import annotations

import signal
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike, NDArray

from laser_corners.errors import InputError, first_line
from laser_corners.pipeline.interrupt import STOP_REASONS, stop_requests
from laser_corners.pipeline.recording import Recording, open_recording
from laser_corners.pose import compose_many, invert_many
from laser_corners.registration.mapfolder import SavedMap
from laser_corners.scan import LaserScan
from laser_corners.slam.grow import load_prior_map
from laser_corners.slam.options import SlamOptions
from laser_corners.slam.result import SlamResult
from laser_corners.slam.slam import Slam

__all__ = ["OdometryFeed", "odometry_scans", "require_odometry", "run_slam", "run_warnings"]

ONE_DIRECTION = 0.05
"""A keyframe whose line normals' scatter (2x2) has its smaller eigenvalue below this share of
the larger sees walls of one direction only (a corridor): the scan alignment cannot measure
the motion along them (:func:`run_warnings`)."""


def run_slam(
    path: str | Path,
    options: SlamOptions | None = None,
    *,
    topic: str | None = None,
    odom_topic: str | None = None,
    progress: Callable[[int, int | None, float], None] | None = None,
    stop_scan: int | None = None,
    start_scan: int = 0,
    prior_map: str | Path | SavedMap | None = None,
    initial_pose: ArrayLike | None = None,
) -> SlamResult:
    """Run SLAM over a recording with odometry.

    Parameters
    ----------
    path : str or Path
        A recording with LaserScan and odometry (see the module notes).
    options : SlamOptions, optional
    topic : str, optional
        The LaserScan topic of a bag (default: the only one).
    odom_topic : str, optional
        The odometry of a bag: a ``nav_msgs/Odometry`` topic or ``"tf"`` (default: the only
        Odometry topic, else ``/tf``; several: an error listing them).
    progress : callable, optional
        Called after every scan with ``(scans done, scans total or None, scan stamp)``.
    stop_scan : int, optional
        Stop before this scan index.
    start_scan : int
        Start at this scan index.
    prior_map : str, Path or SavedMap, optional
        A map folder written by a SLAM run to grow (:mod:`.grow`; ``--map`` of the CLI): the
        run starts in it, keeps its keyframes and adds its own; never modified.
    initial_pose : array_like, optional
        With ``prior_map``: the first scan's base pose in the map's frame (default: a global
        search of the map).

    Returns
    -------
    SlamResult
        ``interrupted=True`` and ``partial_reason`` when Ctrl-C, SIGTERM or an error stopped
        the run (the result holds what was done, see the module notes).

    Raises
    ------
    InputError
        No readable scan, or no scan with odometry; a prior map that cannot be read or is not
        a map folder of this package (one line).
    """
    options = options or SlamOptions()
    prior = load_prior_map(prior_map) if prior_map is not None else None
    if initial_pose is not None and prior is None:
        raise InputError("initial_pose: only with a prior map (--map) to start in")
    with open_recording(path, topic, odom_topic=odom_topic) as rec:
        require_odometry(rec, path)
        recorded = getattr(rec.source, "mounts", {}).get(rec.first.frame_id) or (0.0, 0.0, 0.0)
        mount = np.asarray(options.mount if options.mount is not None else recorded)
        slam = Slam(options, mount, prior_map=prior, initial_pose=initial_pose)
        feed = OdometryFeed()
        try:
            for i, scan, base in odometry_scans(rec, feed, start_scan, stop_scan):
                feed.at = i
                feed.blank += not scan.valid.any()
                slam.add(scan, base, float(scan.stamp))
                if progress is not None:
                    progress(i + 1, rec.source.n_scans, float(scan.stamp))
        except KeyboardInterrupt:  # a second Ctrl-C, or one before the first scan
            feed.stopped(STOP_REASONS[signal.SIGINT], signal.SIGINT)
        except Exception as exc:
            if slam.counts.scans == 0:
                raise
            feed.stopped(f"{type(exc).__name__} at scan {feed.at}: {first_line(exc)}")
    slam.counts.skipped_no_odometry = feed.skipped
    if slam.counts.scans == 0 and not feed.interrupted:
        raise InputError(f"{path}: no scan with odometry ({feed.skipped} scans without a pose)")
    warnings = run_warnings(slam, feed)
    result = slam.result(interrupted=feed.interrupted, partial_reason=feed.reason)
    result.warnings.extend(warnings)
    result.skipped = dict(rec.source.skipped)
    return result


def run_warnings(slam: Slam, feed: OdometryFeed) -> list[str]:
    """What a user should know about a run that went through (counted in ``slam.counts``):
    scans without any valid return, and keyframes that see walls of one direction only
    (:data:`ONE_DIRECTION`; more than half of them: a degenerate corridor)."""
    warnings = []
    slam.counts.scans_without_returns = feed.blank
    if feed.blank:
        warnings.append(
            f"{feed.blank} scans without any valid return: placed by the odometry alone"
        )
    flat = sum(_one_direction(p.normals[p.has_normal]) for p in slam.kf.points)
    slam.counts.keyframes_one_direction = flat
    if flat and 2 * flat > len(slam.kf):
        warnings.append(
            f"{flat} of {len(slam.kf)} keyframes see walls of one direction only (a corridor?): "
            "the motion along them comes from the odometry"
        )
    return warnings


def _one_direction(normals: NDArray[np.float64]) -> bool:
    """Whether line normals (M, 2) all point one way (see :data:`ONE_DIRECTION`)."""
    if len(normals) < 10:
        return False
    low, high = np.linalg.eigvalsh(normals.T @ normals / len(normals))
    return bool(low < ONE_DIRECTION * high)


def require_odometry(rec: Recording, path: str | Path) -> None:
    """One line when the recording has no odometry at all (no topic, no scan poses)."""
    if rec.first.pose is None and getattr(rec.source, "odom_topic", "") is None:
        raise InputError(f"{path}: no odometry (no nav_msgs/Odometry topic, no scan poses)")


@dataclass
class OdometryFeed:
    """What :func:`odometry_scans` counted: scans without a pose, scans read (``seen``, from
    index 0, those before ``start_scan`` too), and a stop by Ctrl-C or SIGTERM (``reason``,
    ``signum``); ``at``: the index of the scan being processed; ``blank``: scans without any
    valid return."""

    skipped: int = 0
    interrupted: bool = False
    seen: int = 0
    reason: str | None = None
    signum: int | None = None
    at: int = -1
    blank: int = 0

    def stopped(self, reason: str, signum: int | None = None) -> None:
        """The run stops early for ``reason`` (the first reason stands)."""
        self.interrupted = True
        if self.reason is None:
            self.reason, self.signum = reason, signum


def odometry_scans(
    rec: Recording, feed: OdometryFeed, start_scan: int = 0, stop_scan: int | None = None
) -> Iterator[tuple[int, LaserScan, NDArray[np.float64]]]:
    """``(index, scan, base odometry pose)`` for the scans ``start_scan`` to ``stop_scan``.

    A bag's scan pose was composed with the recorded mount: that one is undone, per laser
    frame. Scans without a pose or stamp are counted in ``feed.skipped``; Ctrl-C or SIGTERM
    (checked between two scans) ends the iteration with ``feed.interrupted`` set.
    """
    mounts = getattr(rec.source, "mounts", {})
    undo: dict[str, NDArray[np.float64]] = {}
    with stop_requests(terminate=True) as stop:
        for i, scan in enumerate(rec.scans()):
            if stop.is_set():
                signum = stop.signum or signal.SIGINT
                feed.stopped(STOP_REASONS[signum], signum)
                return
            if stop_scan is not None and i >= stop_scan:
                return
            feed.seen = i + 1
            if i < start_scan:
                continue
            if scan.pose is None or scan.stamp is None:
                feed.skipped += 1
                continue
            if scan.frame_id not in undo:
                undo[scan.frame_id] = invert_many(mounts.get(scan.frame_id) or (0.0, 0.0, 0.0))
            yield i, scan, compose_many(np.asarray(scan.pose), undo[scan.frame_id])
