"""Live viewer: stream scans and keypoints of a recording to rerun (``laser-corners view``).

Entities (2D, metres), on the timelines ``scan`` (scan index) and ``stamp`` (the scan stamp,
when the recording has one):

* ``sensor/scan``: the valid scan points in the sensor frame (grey);
* ``sensor/keypoints``: the keypoints (red), with their opening angle as label, and
  ``sensor/keypoints/orientation``: arrows along each keypoint's bisector;
* when the scan has a pose: ``map/scan``, ``map/keypoints`` (the same in the frame of the
  poses) and ``map/sensor`` (the sensor position and heading);
* ``stats/keypoints``: keypoints per scan.

Nothing is logged for a part that is empty (no pose, no keypoints): each scan's entities are
cleared first, so the viewer never shows a stale keypoint.
"""

from __future__ import annotations

import math
import os
import shutil
import sys
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from laser_corners.detector import CornerDetector
from laser_corners.errors import InputError, MissingDependencyError, OutputError, first_line
from laser_corners.io import KeypointWriter
from laser_corners.keypoints import Keypoints
from laser_corners.pipeline import ParamsChoice, Recording, detect_recording, open_recording
from laser_corners.scan import LaserScan, transform_points

__all__ = [
    "APPLICATION_ID",
    "ViewSummary",
    "ViewerUnavailableError",
    "open_recording_stream",
    "stream_scans",
    "view_recording",
]

APPLICATION_ID = "laser-corners"
"""rerun application id of every recording the viewer makes."""
ARROW_LENGTH = 0.3
"""Length (m) of the orientation arrows."""
_SCAN_COLOR = (150, 150, 150)
_KEYPOINT_COLOR = (230, 30, 30)
_SENSOR_COLOR = (40, 110, 230)


class ViewerUnavailableError(InputError):
    """The rerun viewer cannot be started or reached (no display, no viewer, it went away)."""


@dataclass
class ViewSummary:
    """What :func:`stream_scans` sent.

    Attributes
    ----------
    n_scans, n_keypoints, n_with_pose : int
        Scans logged, keypoints logged (sensor frame), scans that had a pose.
    """

    n_scans: int = 0
    n_keypoints: int = 0
    n_with_pose: int = 0


def open_recording_stream(
    name: str, save: str | Path | None = None, connect: str | None = None, spawn: bool = False
) -> Any:
    """A rerun ``RecordingStream`` that saves to ``save``, sends to ``connect`` or a new viewer.

    Parameters
    ----------
    name : str
        Recording name shown in the viewer (the input file name).
    save : str or Path, optional
        Write an ``.rrd`` file (works without a display).
    connect : str, optional
        gRPC address of a running viewer (``rerun+http://127.0.0.1:9876/proxy``).
    spawn : bool
        Start a viewer process and stream to it (the default when neither ``save`` nor
        ``connect`` is given).

    Raises
    ------
    MissingDependencyError
        rerun-sdk is not installed.
    OutputError
        The ``.rrd`` cannot be written.
    ViewerUnavailableError
        No display to spawn a viewer on, or the viewer does not start.
    """
    try:
        import rerun as rr
    except ImportError:
        raise MissingDependencyError(
            "rerun-sdk is needed: pip install 'laser-corners[viewer]'"
        ) from None
    recording = rr.RecordingStream(APPLICATION_ID)
    recording.send_recording_name(name)
    if save is not None:
        path = Path(save)
        if not path.parent.is_dir():
            raise OutputError(f"{path}: cannot write the recording, no folder {path.parent}")
        recording.save(str(path))
    elif connect is not None:
        recording.connect_grpc(connect)
    if spawn or (save is None and connect is None):
        if sys.platform.startswith("linux") and not (
            os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")
        ):
            raise ViewerUnavailableError(
                "no display to open the rerun viewer on (DISPLAY and WAYLAND_DISPLAY are unset);"
                " save to an .rrd file and open it elsewhere, or connect to a running viewer"
            )
        # the viewer ships with rerun-sdk next to this Python, which may not be on PATH
        beside = Path(sys.executable).parent / "rerun"
        executable = shutil.which("rerun") or (str(beside) if beside.exists() else None)
        try:
            rr.spawn(executable_path=executable, recording=recording)
        except RuntimeError as exc:
            raise ViewerUnavailableError(
                f"cannot start the rerun viewer ({first_line(exc)}); save to an .rrd file (no "
                "display needed) or connect to a running viewer"
            ) from None
    return recording


def _log_keypoints(rr: Any, recording: Any, path: str, keypoints: Keypoints) -> None:
    if not len(keypoints):
        return
    recording.log(
        path,
        rr.Points2D(
            keypoints.xy,
            colors=_KEYPOINT_COLOR,
            radii=rr.Radius.ui_points(6.0),
            labels=[f"{a:.0f}°" for a in keypoints.opening_angle_deg],
        ),
    )
    vectors = ARROW_LENGTH * np.column_stack(
        (np.cos(keypoints.orientation), np.sin(keypoints.orientation))
    )
    recording.log(
        f"{path}/orientation",
        rr.Arrows2D(origins=keypoints.xy, vectors=vectors, colors=_KEYPOINT_COLOR),
    )


class _RerunWriter(KeypointWriter):
    """A keypoint "writer" that logs each scan and its keypoints to a rerun recording."""

    def __init__(self, recording: Any) -> None:
        import rerun as rr

        super().__init__()
        self.rr = rr
        self.recording = recording
        self.n_with_pose = 0

    def write(self, scan_index: int, scan: LaserScan, keypoints: Keypoints) -> None:
        """Log one scan: points, keypoints and, with a pose, the map frame."""
        super().write(scan_index, scan, keypoints)
        rr, recording = self.rr, self.recording
        recording.set_time("scan", sequence=scan_index)
        if scan.stamp is not None:
            recording.set_time("stamp", timestamp=scan.stamp)
        for root in ("sensor", "map"):
            recording.log(root, rr.Clear(recursive=True))
        xy, valid = scan.to_cartesian()
        points = xy[valid]
        radii = rr.Radius.ui_points(2.0)
        recording.log("sensor/scan", rr.Points2D(points, colors=_SCAN_COLOR, radii=radii))
        _log_keypoints(rr, recording, "sensor/keypoints", keypoints)
        if scan.pose is not None:
            self.n_with_pose += 1
            recording.log(
                "map/scan",
                rr.Points2D(transform_points(points, scan.pose), colors=_SCAN_COLOR, radii=radii),
            )
            _log_keypoints(rr, recording, "map/keypoints", keypoints.transformed(scan.pose))
            heading = (ARROW_LENGTH * math.cos(scan.pose[2]), ARROW_LENGTH * math.sin(scan.pose[2]))
            recording.log(
                "map/sensor",
                rr.Arrows2D(origins=[scan.pose[:2]], vectors=[heading], colors=_SENSOR_COLOR),
            )
        recording.log("stats/keypoints", rr.Scalars(len(keypoints)))

    def write_many(
        self, first_index: int, scans: Sequence[LaserScan], keypoints: Sequence[Keypoints]
    ) -> None:
        """Log consecutive scans one by one."""
        for offset, (scan, found) in enumerate(zip(scans, keypoints, strict=True)):
            self.write(first_index + offset, scan, found)


def stream_scans(
    scans: Iterable[LaserScan] | Recording,
    detector: CornerDetector | None,
    recording: Any,
    *,
    every: int = 1,
    max_scans: int | None = None,
) -> ViewSummary:
    """Detect keypoints in each scan and log scan, keypoints (and map frame) to ``recording``.

    Runs the pipeline's detect loop (:func:`laser_corners.pipeline.detect_recording`) with a
    writer that logs to rerun.

    Parameters
    ----------
    scans : iterable of LaserScan or Recording
        The scans (for instance a :func:`laser_corners.io.open_scans` source, or an opened
        :class:`~laser_corners.pipeline.Recording`).
    detector : CornerDetector, optional
        The detector (None: the recording's).
    recording : rerun.RecordingStream
        Where to log (see :func:`open_recording_stream`).
    every : int
        Log every ``every``-th scan (the ``scan`` timeline keeps the scan index).
    max_scans : int, optional
        Stop after logging this many scans.

    Returns
    -------
    ViewSummary
    """
    writer = _RerunWriter(recording)
    summary = detect_recording(
        scans, detector, writer, step=max(1, int(every)), max_scans=max_scans, chunk_scans=16
    )
    try:
        recording.flush()
    except RuntimeError as exc:  # the viewer went away or never answered
        raise ViewerUnavailableError(
            f"could not send the recording to the rerun viewer ({first_line(exc)})"
        ) from None
    if summary.interrupted:
        raise KeyboardInterrupt
    return ViewSummary(summary.n_scans, summary.n_keypoints, writer.n_with_pose)


def view_recording(
    path: str | Path,
    topic: str | None = None,
    params: ParamsChoice | None = None,
    *,
    save: str | Path | None = None,
    connect: str | None = None,
    every: int = 1,
    max_scans: int | None = None,
    odom_topic: str | None = None,
) -> ViewSummary:
    """Open a recording and stream it to rerun (what ``laser-corners view`` runs).

    Parameters
    ----------
    path, topic, params, odom_topic
        As :func:`laser_corners.pipeline.open_recording`.
    save, connect
        As :func:`open_recording_stream` (neither: spawn a viewer).
    every, max_scans
        As :func:`stream_scans`.

    Returns
    -------
    ViewSummary
    """
    opened = open_recording(path, topic, params, odom_topic=odom_topic)
    recording = open_recording_stream(opened.path.name, save=save, connect=connect)
    try:
        return stream_scans(opened, None, recording, every=every, max_scans=max_scans)
    finally:
        recording.disconnect()
