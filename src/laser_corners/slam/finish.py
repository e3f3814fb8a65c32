"""Finishing a SLAM run: what every scan leaves behind (:class:`ScanLog`), the final graph
(:func:`final_graph`: the batch optimisation, the refinement pass, the pruned closures marked)
and the final pose of every scan (:meth:`ScanLog.poses`: blended between its keyframes, with
``rescan_final`` re-registered against the final map).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from laser_corners.slam.backend import Backend
from laser_corners.slam.closing import LoopCloser
from laser_corners.slam.counts import SlamCounts
from laser_corners.slam.grow import join_warning
from laser_corners.slam.keyframes import KeyframeStore
from laser_corners.slam.options import SlamOptions
from laser_corners.slam.refine import refine
from laser_corners.slam.rescan import blend_poses, rescan
from laser_corners.slam.result import Landmarks, SlamResult
from laser_corners.slam.tracking import SURFACE_SPACINGS

__all__ = ["ScanLog", "final_graph", "slam_result"]


class ScanLog:
    """Every scan added, in order: stamp, odometry, the keyframe before it and its pose
    relative to that keyframe, processing time and, with ``keep_points``, its points (for the
    scan pass of ``rescan_final``).

    Parameters
    ----------
    keep_points : bool
        Keep every scan's points (float32: half the memory; at 30 m, 2 µm).
    """

    def __init__(self, keep_points: bool = False) -> None:
        self.keep_points = keep_points
        self.stamps: list[float] = []
        self.odometry: list[NDArray] = []
        self.ref: list[int] = []
        self.rel: list[NDArray] = []
        self.ms: list[float] = []
        self.points: list[NDArray[np.float32]] = []

    def __len__(self) -> int:
        return len(self.stamps)

    def add(self, stamp: float, odometry: NDArray, ref: int, rel: NDArray, xy: NDArray) -> None:
        """A scan at ``stamp`` with base ``odometry``, its pose ``rel`` relative to keyframe
        ``ref``, its points ``xy`` (base frame)."""
        self.stamps.append(float(stamp))
        self.odometry.append(odometry)
        self.ref.append(ref)
        self.rel.append(rel)
        if self.keep_points:
            self.points.append(xy.astype(np.float32))

    def took(self, ms: float) -> None:
        """The last scan took ``ms`` milliseconds."""
        self.ms.append(ms)

    def poses(
        self,
        links: list[NDArray | None],
        store: KeyframeStore,
        options: SlamOptions,
        counts: SlamCounts,
    ) -> NDArray[np.float64]:
        """Final pose of every scan, shape (N, 3) (:func:`.rescan.blend_poses` between the
        keyframes of ``store`` at their final estimates, ``links`` their tracked steps); with
        ``keep_points`` re-registered against the final map (:func:`.rescan.rescan`,
        counted)."""
        if not self.stamps:
            return np.zeros((0, 3))
        ref = np.asarray(self.ref)
        poses = blend_poses(np.asarray(self.stamps), ref, np.asarray(self.rel), links, store)
        if not self.keep_points:
            return poses
        surface = SURFACE_SPACINGS * options.point_spacing
        poses, rescanned = rescan(self.points, poses, ref, store, options, surface)
        counts.update(rescanned)
        return poses


def final_graph(
    backend: Backend,
    store: KeyframeStore,
    options: SlamOptions,
    counts: SlamCounts,
    closer: LoopCloser,
) -> tuple[object, object]:
    """The final graph and values: with ``final_optimisation`` the batch optimisation, with
    ``refine_final`` the refinement pass after it (:func:`.refine.refine`, counted), and the
    closures it dropped marked (:meth:`LoopCloser.prune`); else iSAM2's full estimate. The
    keyframes of ``store`` get their final estimates. (None, None) without keyframes."""
    if not len(store):
        return None, None
    if options.final_optimisation:
        graph, values = backend.optimise()
        if options.refine_final:
            points, travelled = store.points, store.travelled_array()
            graph, values, refined = refine(backend, values, points, travelled, options)
            counts.update(refined)
        closer.prune(backend.pruned)
    else:
        backend.update(full=True)
        graph, values = backend.graph, backend.values
    store.estimate = backend.estimate
    return graph, values


def slam_result(
    slam: Any, interrupted: bool = False, partial_reason: str | None = None
) -> SlamResult:
    """The result so far of ``slam``, a :class:`~.slam.Slam` (its :meth:`~.slam.Slam.result`;
    not imported here: the module is one of its parts)."""
    opt = slam.options
    graph, values = final_graph(slam.backend, slam.kf, opt, slam.counts, slam.closing)
    poses = slam.log.poses(slam.keyframer.links, slam.kf, opt, slam.counts)
    landmarks = Landmarks()
    if slam.landmarks is not None and slam.backend.n_landmarks:
        landmarks = slam.landmarks.landmarks(slam.backend.marginals())
    slam.counts.landmarks = len(landmarks)
    slam.closing.tally()
    warnings = list(slam.backend.warnings)
    if slam.kf.first:
        joined = join_warning(slam.closing.closures, slam.kf.first, slam.initial_pose is not None)
        slam.counts.grow_unjoined = int(joined is not None)
        warnings += [] if joined is None else [joined]
    keyframes = np.asarray(slam.kf.scan_index, dtype=np.int64)
    starts = [
        k for k in range(slam.kf.first + 1, len(keyframes)) if slam.keyframer.links[k] is None
    ]
    return SlamResult(
        stamps=np.asarray(slam.log.stamps, dtype=np.float64),
        poses=poses,
        odometry=np.asarray(slam.log.odometry, dtype=np.float64).reshape(-1, 3),
        keyframes=keyframes,
        keyframe_poses=np.asarray(slam.kf.estimate, dtype=np.float64).reshape(-1, 3),
        scans=list(slam.kf.scans),
        mount=slam.mount.copy(),
        landmarks=landmarks,
        closures=list(slam.closing.closures),
        ms_per_scan=np.asarray(slam.log.ms, dtype=np.float64),
        options=opt,
        counts=slam.counts.as_dict(),
        interrupted=interrupted or partial_reason is not None,
        partial_reason=partial_reason,
        warnings=warnings,
        graph=graph,
        values=values,
        places=slam.places if opt.places.enabled else None,
        cuts=keyframes[starts],
        prior_keyframes=slam.kf.first,
        prior_map=slam.prior_folder,
        keyframe_stamps=np.asarray(slam.kf.stamps, dtype=np.float64),
        keyframe_points=list(slam.kf.points),
    )
