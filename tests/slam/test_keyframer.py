"""Keyframe making: when a scan becomes a keyframe, its link in the graph, its corners
(laser_corners.slam.keyframer)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("gtsam")

import gtsam

from laser_corners.pose import relative_pose
from laser_corners.registration.graph import PoseGraph
from laser_corners.registration.mapfolder import SavedMap
from laser_corners.registration.points import scan_points
from laser_corners.sim import SICK_LMS_1DEG
from laser_corners.slam.backend import Backend
from laser_corners.slam.grow import INITIAL_SIGMAS, LOST_SIGMAS, PRIOR_SIGMAS
from laser_corners.slam.keyframer import CUT_SIGMAS, Keyframer
from laser_corners.slam.keyframes import SESSION_GAP
from laser_corners.slam.options import SlamOptions
from sim_drives import two_rooms

OPTIONS = SlamOptions()
POSES = np.array([[4.0, 4.0, 0.0], [4.5, 4.0, 0.1], [5.0, 4.1, 0.1]])


def _keyframer(options: SlamOptions = OPTIONS) -> tuple[Keyframer, Backend]:
    backend = Backend()
    return Keyframer(options, np.zeros(3), backend, backend.counts), backend


def _add(keyframer: Keyframer, i: int, cut: bool = False, aligned: bool = True):
    """Keyframe ``i`` of :data:`POSES` (the one before: the anchor): (k, distance)."""
    opt = keyframer.options
    scan = two_rooms().scan(tuple(POSES[i]), SICK_LMS_1DEG, noise_sigma=0.01, stamp=float(i))
    pts = scan_points(scan, np.zeros(3), opt.min_range, opt.max_range, opt.point_spacing)
    anchor = POSES[max(i - 1, 0)]
    cov = np.eye(3) * 1e-4
    return keyframer.add(
        scan,
        pts,
        POSES[i],
        float(i),
        10 * i,
        pose=POSES[i],
        anchor=anchor,
        cut=cut,
        aligned=aligned,
        kp=None,
        cov=cov,
    )


def _sigmas(backend: Backend, index: int) -> np.ndarray:
    return np.asarray(backend.graph.at(index).noiseModel().sigmas())


def test_a_keyframe_is_due_after_distance_turn_time_a_jump_or_a_failed_alignment() -> None:
    keyframer, _ = _keyframer()
    _add(keyframer, 0)
    opt, still = OPTIONS, np.zeros(3)
    assert not keyframer.due(still, 0.1, jumped=False, aligned=True)
    assert keyframer.due(np.array([opt.keyframe_distance, 0, 0]), 0.1, False, True)
    assert keyframer.due(np.array([0, 0, opt.keyframe_angle]), 0.1, False, True)
    assert keyframer.due(still, opt.keyframe_max_interval, False, True)
    assert keyframer.due(still, 0.1, jumped=True, aligned=True)
    assert keyframer.due(still, 0.1, jumped=False, aligned=False)


def test_links_carry_the_matching_or_the_odometry_noise_and_a_cut_none() -> None:
    keyframer, backend = _keyframer()
    assert _add(keyframer, 0) == (0, 0.0)
    assert backend.graph.size() == 1  # the first keyframe's prior, no link
    k, dist = _add(keyframer, 1)
    assert k == 1 and dist == pytest.approx(0.5)
    assert np.allclose(keyframer.links[1], [0.5, 0.0, 0.1])
    opt = OPTIONS
    assert np.allclose(_sigmas(backend, 1), [opt.match_sigma_xy] * 2 + [opt.match_sigma_yaw])
    _add(keyframer, 2, cut=True, aligned=False)
    assert keyframer.links[2] is None and len(keyframer.links) == 3
    assert isinstance(backend.graph.at(2), gtsam.PriorFactorPose2)  # a new segment's prior
    assert np.allclose(_sigmas(backend, 3), CUT_SIGMAS)
    assert keyframer.store.scan_index == [0, 10, 20] and len(keyframer.store) == 3


def test_a_link_after_a_failed_alignment_gets_the_odometry_noise() -> None:
    keyframer, backend = _keyframer()
    _add(keyframer, 0)
    _add(keyframer, 1, aligned=False)
    sxy = OPTIONS.odometry.sigma_xy * (0.5 + 0.1)
    assert np.allclose(_sigmas(backend, 1)[:2], [sxy, sxy])


def test_keyframe_corners_go_into_the_place_index_when_it_is_on() -> None:
    keyframer, _ = _keyframer()
    _add(keyframer, 0)
    assert len(keyframer.places) > 0
    off, _ = _keyframer(OPTIONS.with_overrides(["places.enabled=false"]))
    _add(off, 0)
    assert len(off.places) == 0


def _saved(keyframer: Keyframer) -> SavedMap:
    """The keyframes of ``keyframer`` as a map folder would give them back."""
    store = keyframer.store
    sizes = [len(p.xy) for p in store.points]
    return SavedMap(
        folder=Path("map"),
        poses=POSES.copy(),
        stamps=np.asarray(store.stamps),
        scan_index=np.asarray(store.scan_index),
        offsets=np.concatenate([[0], np.cumsum(sizes)]),
        points=np.concatenate([p.xy for p in store.points]),
        normals=np.concatenate([p.normals for p in store.points]),
        has_normal=np.concatenate([p.has_normal for p in store.points]),
        mount=np.zeros(3),
        places=keyframer.places,
    )


@pytest.mark.parametrize("initial_pose", [False, True])
def test_a_seeded_keyframer_keeps_the_prior_map_and_starts_a_session_after_it(
    initial_pose: bool,
) -> None:
    first, _ = _keyframer()
    for i in range(3):
        _add(first, i)
    saved = _saved(first)
    keyframer, backend = _keyframer()
    keyframer.seed(saved, initial_pose=initial_pose)
    store = keyframer.store
    assert len(store) == 3 and store.first == 3 and keyframer.links == [None] * 3
    np.testing.assert_allclose(store.estimate, POSES, atol=1e-9)
    # three priors, two links with the map's relative poses
    kinds = [type(backend.graph.at(i)).__name__ for i in range(backend.graph.size())]
    prior, link = "PriorFactorPose2", "BetweenFactorPose2"
    assert kinds == [prior, prior, link, prior, link]
    np.testing.assert_allclose(_sigmas(backend, 0), PRIOR_SIGMAS)
    assert len(keyframer.places) == len(first.places) > 0
    # the session's first keyframe: no link to the map's last, a prior of its own
    k, dist = _add(keyframer, 1, cut=not initial_pose)
    assert (k, dist) == (3, 0.0) and keyframer.links[3] is None
    assert backend.graph.size() == 6
    assert type(backend.graph.at(5)).__name__ == "PriorFactorPose2"
    np.testing.assert_allclose(_sigmas(backend, 5), INITIAL_SIGMAS if initial_pose else LOST_SIGMAS)
    assert store.travelled[3] - store.travelled[2] == SESSION_GAP
    store.estimate = backend.update()
    assert store.local_map(20)[1].xy.shape[0] == len(store.points[3].xy)  # the session's only


def _graph(saved: SavedMap, sigmas: tuple[float, float, float]) -> PoseGraph:
    """A pose graph over :data:`POSES`: the chain 0-1-2 and an old closure 0-2."""
    pairs = np.array([[0, 1], [1, 2], [0, 2]])
    relative = np.array([relative_pose(saved.poses[a], saved.poses[b]) for a, b in pairs])
    return PoseGraph(pairs, relative, np.tile(sigmas, (3, 1)))


@pytest.mark.parametrize("with_graph", [True, False])
def test_a_prior_map_with_its_graph_bends_when_a_closure_pulls_it(with_graph: bool) -> None:
    first, _ = _keyframer()
    for i in range(3):
        _add(first, i)
    saved = _saved(first)
    saved.graph = _graph(saved, (0.1, 0.1, 0.02)) if with_graph else None
    keyframer, backend = _keyframer()
    keyframer.seed(saved)
    kinds = [type(backend.graph.at(i)).__name__ for i in range(backend.graph.size())]
    if with_graph:  # one gauge prior, the map's own factors, its closure robust
        assert kinds.count("PriorFactorPose2") == 1 and kinds.count("BetweenFactorPose2") == 3
        assert [(a, b) for a, b, *_ in backend.loops] == [(0, 2)]
    # a new closure says keyframe 2 is 0.15 m further along from keyframe 0
    pulled = relative_pose(POSES[0], POSES[2] + np.array([0.15, 0.0, 0.0]))
    backend.add_between(0, 2, np.asarray(pulled), (0.02, 0.02, 0.005), robust=True)
    moved = np.hypot(*(backend.update(extra_iterations=3)[2, :2] - POSES[2, :2]))
    if with_graph:
        assert moved > 0.1  # the map follows the closure, as a one-run SLAM would
    else:
        assert moved < 0.03  # held in place by the per-keyframe priors
