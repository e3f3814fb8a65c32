"""Finishing a run: every scan's record, the final graph with the dropped closures marked,
the final pose of every scan (laser_corners.slam.finish)."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("gtsam")

from laser_corners.pose import between_many
from laser_corners.registration.points import scan_points
from laser_corners.sim import SICK_LMS_1DEG
from laser_corners.slam.backend import Backend
from laser_corners.slam.closing import LoopCloser
from laser_corners.slam.counts import SlamCounts
from laser_corners.slam.finish import ScanLog, final_graph
from laser_corners.slam.keyframes import KeyframeStore
from laser_corners.slam.options import SlamOptions
from laser_corners.slam.relocalise import Relocaliser
from laser_corners.slam.result import LoopClosure
from sim_drives import two_rooms

OPTIONS = SlamOptions()
KEYFRAMES = np.array([[4.0, 4.0, 0.0], [4.6, 4.0, 0.1]])


def _store() -> KeyframeStore:
    """Two keyframes of :func:`two_rooms` at :data:`KEYFRAMES` (stamps 0 and 1)."""
    store, rng = KeyframeStore(), np.random.default_rng(2)
    for i, pose in enumerate(KEYFRAMES):
        scan = two_rooms().scan(tuple(pose), SICK_LMS_1DEG, noise_sigma=0.01, rng=rng)
        pts = scan_points(scan, np.zeros(3), 0.0, 30.0, OPTIONS.point_spacing)
        store.add(scan, pts, 2 * i, float(i), pose, pose)
    store.estimate = KEYFRAMES.copy()
    return store


def _log(keep_points: bool) -> tuple[ScanLog, np.ndarray]:
    """Four scans at stamps 0, 0.5, 1, 1.5 (two per keyframe), 0.3 m a step: log, truth."""
    log, rng = ScanLog(keep_points), np.random.default_rng(3)
    truth = np.array([[4.0, 4.0, 0.0], [4.3, 4.0, 0.05], [4.6, 4.0, 0.1], [4.9, 4.03, 0.1]])
    for i, pose in enumerate(truth):
        ref = i // 2
        scan = two_rooms().scan(tuple(pose), SICK_LMS_1DEG, noise_sigma=0.01, rng=rng)
        pts = scan_points(scan, np.zeros(3), 0.0, 30.0, OPTIONS.point_spacing)
        log.add(0.5 * i, pose, ref, between_many(KEYFRAMES[ref], pose), pts.xy)
        log.took(1.0)
    return log, truth


def _closer(backend: Backend) -> LoopCloser:
    relocaliser = Relocaliser(OPTIONS, np.zeros(3), None, counts=backend.counts)
    return LoopCloser(OPTIONS, backend, backend.counts, relocaliser)


def test_the_log_keeps_every_scan_and_its_points_only_when_asked() -> None:
    log, truth = _log(keep_points=False)
    assert len(log) == 4 and log.ref == [0, 0, 1, 1] and log.ms == [1.0] * 4
    assert log.points == [] and np.allclose(log.odometry, truth)
    kept, _ = _log(keep_points=True)
    assert len(kept.points) == 4 and kept.points[0].dtype == np.float32


def test_scan_poses_follow_their_keyframes_final_estimates() -> None:
    log, truth = _log(keep_points=False)
    store, counts = _store(), SlamCounts()
    links = [None, between_many(KEYFRAMES[0], KEYFRAMES[1])]
    assert np.allclose(log.poses(links, store, OPTIONS, counts), truth)
    shift = np.array([1.0, 2.0, 0.0])
    store.estimate = KEYFRAMES + shift  # the whole map moved: every scan with it
    assert np.allclose(log.poses(links, store, OPTIONS, counts), truth + shift)
    assert counts.rescan_tried == 0
    assert ScanLog().poses(links, store, OPTIONS, counts).shape == (0, 3)


def test_with_points_the_scans_are_registered_again_and_counted() -> None:
    log, truth = _log(keep_points=True)
    store, counts = _store(), SlamCounts()
    links = [None, between_many(KEYFRAMES[0], KEYFRAMES[1])]
    poses = log.poses(links, store, OPTIONS, counts)
    assert counts.rescan_tried == 4 and np.allclose(poses[:, :2], truth[:, :2], atol=0.02)


def _graph(closures: list[LoopClosure]) -> tuple[Backend, LoopCloser, KeyframeStore]:
    """A back end over the two keyframes of :func:`_store` and a third 0.6 m on."""
    backend, store = Backend(), _store()
    poses = np.vstack([KEYFRAMES, [5.2, 4.06, 0.1]])
    for k, pose in enumerate(poses):
        backend.add_keyframe(pose)
        if k:
            backend.add_between(k - 1, k, between_many(poses[k - 1], pose), (0.02, 0.02, 0.005))
    store.add(store.scans[1], store.points[1], 4, 2.0, poses[2], poses[2])
    closer = _closer(backend)
    for closure in closures:
        closer.closures.append(closure)
        closer.accept(closure)
    backend.update()
    return backend, closer, store


def test_the_final_graph_drops_a_contradicted_closure_and_marks_it() -> None:
    wrong = LoopClosure(2, 0, (2.2, 0.1, 0.1), False, "ok")  # 1 m off (truth: 1.2 m)
    backend, closer, store = _graph([wrong])
    graph, values = final_graph(backend, store, OPTIONS, backend.counts, closer)
    assert graph is not None and values is not None
    assert not wrong.accepted and wrong.reason.startswith("dropped")
    assert backend.counts.closures_pruned == 1
    assert np.allclose(store.estimate[2, :2], [5.2, 4.06], atol=0.01)


def test_without_the_batch_the_isam2_graph_is_the_final_one() -> None:
    backend, closer, store = _graph([])
    options = OPTIONS.with_overrides(["final_optimisation=false"])
    graph, _ = final_graph(backend, store, options, backend.counts, closer)
    assert graph is backend.graph and np.array_equal(store.estimate, backend.estimate)
    assert final_graph(Backend(), KeyframeStore(), OPTIONS, SlamCounts(), closer) == (None, None)
