"""SLAM over a recording: :func:`run_slam`.

Bags (ROS 1/2, MCAP): each scan's ``pose`` is the laser pose in the odometry frame (odometry
interpolated at the scan stamp, composed with the base -> laser mount from ``/tf_static``);
the base pose is that pose composed with the inverse mount, read once from the bag's
transform tree. ``SlamOptions.mount`` overrides the mount. CARMEN logs: the laser pose of
each FLASER/ROBOTLASER1 line is used as odometry with a zero mount (in a raw log it is the
odometry; in a ``*-corrected`` log it is already a map pose, so SLAM on it only refines it).
Scans without a pose are counted (``skipped_no_odometry``) and skipped.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import numpy as np

from laser_corners.errors import InputError
from laser_corners.pipeline.interrupt import stop_requests
from laser_corners.pipeline.recording import open_recording
from laser_corners.pose import compose_many, invert_many
from laser_corners.slam.options import SlamOptions
from laser_corners.slam.result import SlamResult
from laser_corners.slam.slam import Slam

__all__ = ["run_slam"]


def run_slam(
    path: str | Path,
    options: SlamOptions | None = None,
    *,
    topic: str | None = None,
    progress: Callable[[int, int | None, float], None] | None = None,
    stop_scan: int | None = None,
) -> SlamResult:
    """Run SLAM over a recording with odometry.

    Parameters
    ----------
    path : str or Path
        A recording with LaserScan and odometry (see the module notes).
    options : SlamOptions, optional
    topic : str, optional
        The LaserScan topic of a bag (default: the only one).
    progress : callable, optional
        Called after every scan with ``(scans done, scans total or None, scan stamp)``.
    stop_scan : int, optional
        Stop after this many scans.

    Returns
    -------
    SlamResult
        ``interrupted=True`` when Ctrl-C stopped the run (the result holds what was done).

    Raises
    ------
    InputError
        No readable scan, or no scan with odometry.
    """
    options = options or SlamOptions()
    with open_recording(path, topic) as rec:
        mounts = getattr(rec.source, "mounts", {})
        recorded = mounts.get(rec.first.frame_id) or (0.0, 0.0, 0.0)
        mount = np.asarray(options.mount if options.mount is not None else recorded)
        if rec.first.pose is None and getattr(rec.source, "odom_topic", "") is None:
            raise InputError(f"{path}: no odometry (no nav_msgs/Odometry topic, no scan poses)")
        slam = Slam(options, mount)
        # a bag's scan pose was composed with the recorded mount: undo that one
        undo: dict[str, np.ndarray] = {}
        total = rec.source.n_scans
        skipped = 0
        interrupted = False
        try:
            with stop_requests() as stop:
                for i, scan in enumerate(rec.scans()):
                    if stop.is_set():
                        interrupted = True
                        break
                    if stop_scan is not None and i >= stop_scan:
                        break
                    if scan.pose is None or scan.stamp is None:
                        skipped += 1
                        continue
                    if scan.frame_id not in undo:
                        recorded_mount = mounts.get(scan.frame_id) or (0.0, 0.0, 0.0)
                        undo[scan.frame_id] = invert_many(recorded_mount)
                    base = compose_many(np.asarray(scan.pose), undo[scan.frame_id])
                    slam.add(scan, base, float(scan.stamp))
                    if progress is not None:
                        progress(i + 1, total, float(scan.stamp))
        except KeyboardInterrupt:  # a second Ctrl-C, or one before the first scan
            interrupted = True
    slam.counts["skipped_no_odometry"] = skipped
    if slam.counts["scans"] == 0 and not interrupted:
        raise InputError(f"{path}: no scan with odometry ({skipped} scans without a pose)")
    return slam.result(interrupted=interrupted)
