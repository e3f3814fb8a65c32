"""The smoothed trajectory (``localise.smooth``): the localiser's anchors on the SLAM's chain.

A drive around a 10 m x 6 m block at 2 cm a scan. The chain is the drive seen by a SLAM in
a frame of its own (turned, shifted) with a drift of 0.5 % in length and 0.05° a metre in
heading; the anchors are the true poses with 1 cm noise, as the localiser's estimates.
"""

from __future__ import annotations

import itertools
import math
from types import SimpleNamespace

import numpy as np
import pytest

from laser_corners.localise import LocaliseOptions, LocaliserEstimate
from laser_corners.localise.smooth import smooth
from laser_corners.pose import between_many, compose_many
from laser_corners.slam import SlamOptions
from laser_corners.slam.result import LoopClosure

pytest.importorskip("gtsam")

STEP = 0.02


def block_drive() -> np.ndarray:
    """Poses (N, 3) around the block, counter-clockwise, heading along the path."""
    corners = np.array([[0, 0], [10, 0], [10, 6], [0, 6], [0, 0]], dtype=float)
    poses = []
    for a, b in itertools.pairwise(corners):
        n = round(np.hypot(*(b - a)) / STEP)
        t = np.arange(n)[:, None] / n
        heading = math.atan2(*(b - a)[::-1])
        poses.append(np.c_[a + t * (b - a), np.full(n, heading)])
    return np.vstack(poses)


def drifted_chain(truth: np.ndarray) -> np.ndarray:
    """``truth`` integrated with a 0.5 % length error and 0.05° per metre of heading drift,
    in a frame turned by 0.7 rad and shifted by (3, -2)."""
    steps = between_many(truth[:-1], truth[1:])
    steps[:, :2] *= 1.005
    steps[:, 2] += math.radians(0.05) * STEP
    chain = [np.array([3.0, -2.0, 0.7])]
    for s in steps:
        chain.append(compose_many(chain[-1], s))
    return np.array(chain)


def estimates_at(truth: np.ndarray, scans, seed: int = 0, status: str = "tracking") -> list:
    rng = np.random.default_rng(seed)
    cov = np.diag([0.02, 0.02, 0.01]) ** 2
    out = []
    for i in scans:
        pose = truth[i] + rng.normal(0.0, [0.01, 0.01, 0.003])
        out.append(LocaliserEstimate(pose, cov, status, np.zeros(3), int(i), float(i)))
    return out


def fake_slam(chain: np.ndarray, cuts=(), closures=(), keyframes=()) -> SimpleNamespace:
    return SimpleNamespace(
        poses=chain,
        stamps=np.arange(len(chain), dtype=float),
        cuts=np.asarray(cuts, dtype=np.int64),
        keyframes=np.asarray(keyframes, dtype=np.int64),
        closures=list(closures),
        options=SlamOptions(),
    )


def run(estimates, chain, **slam) -> object:
    index = np.array([e.scan_index for e in estimates], dtype=np.int64)
    return smooth(estimates, index, fake_slam(chain, **slam), LocaliseOptions())


def position_error(got: np.ndarray, truth: np.ndarray) -> np.ndarray:
    return np.hypot(*(got[:, :2] - truth[:, :2]).T)


def test_a_gap_round_a_corner_is_bridged_by_the_chain() -> None:
    truth = block_drive()
    gap = np.arange(400, 900)  # 10 m without an estimate, round the corner at (10, 0)
    scans = np.setdiff1d(np.arange(len(truth)), gap)
    sm = run(estimates_at(truth, scans), drifted_chain(truth))
    assert sm.index.tolist() == list(range(len(truth))) and sm.anchors > 0
    err = position_error(sm.poses, truth)
    assert err[gap].max() < 0.06 and err.mean() < 0.02
    # the same gap interpolated between its two ends (what a trajectory with a hole gives)
    t = np.arange(len(truth))
    held = np.c_[np.interp(t, scans, truth[scans, 0]), np.interp(t, scans, truth[scans, 1])]
    assert np.hypot(*(held[gap] - truth[gap, :2]).T).max() > 1.0


def test_local_estimates_are_not_anchors_and_the_scans_before_the_fix_are_placed() -> None:
    truth = block_drive()
    wrong = estimates_at(truth, range(100, 150), status="local")
    for e in wrong:  # chained estimates a metre off: the smoother must not follow them
        e.pose = e.pose + np.array([1.0, 0.0, 0.0])
    sm = run(wrong + estimates_at(truth, range(150, len(truth))), drifted_chain(truth))
    assert sm.index.tolist() == list(range(len(truth)))  # before the first anchor too
    assert position_error(sm.poses, truth).max() < 0.05


def test_a_segment_without_anchors_is_left_out() -> None:
    truth = block_drive()
    sm = run(estimates_at(truth, range(0, 900)), drifted_chain(truth), cuts=[1000])
    assert sm.index.max() == 999 and sm.segments_dropped == 1
    assert position_error(sm.poses, truth[:1000]).max() < 0.06


def test_a_wrong_step_of_the_chain_is_outvoted_by_the_anchors() -> None:
    """The SLAM tracked a kidnap through: its chain jumps 3 m at scan 1000; the anchors on
    both sides are right."""
    truth = block_drive()
    chain = drifted_chain(truth)
    chain[1000:] = compose_many(np.array([3.0, 0.0, 0.2]), chain[1000:])
    sm = run(estimates_at(truth, range(len(truth))), chain)
    err = position_error(sm.poses, truth)
    assert err[:990].max() < 0.05 and err[1010:].max() < 0.05


def test_loop_closures_between_anchored_scans_are_used() -> None:
    truth = block_drive()
    closure = LoopClosure(1, 0, tuple(between_many(truth[0], truth[-1])), True, "ok")
    rejected = LoopClosure(1, 0, (5.0, 0.0, 0.0), False, "low score")
    slam = {"closures": [closure, rejected], "keyframes": [0, len(truth) - 1]}
    sm = run(estimates_at(truth, range(0, len(truth), 5)), drifted_chain(truth), **slam)
    assert sm.closures == 1


def test_no_anchor_gives_an_empty_result() -> None:
    truth = block_drive()
    sm = run(estimates_at(truth, range(50), status="local"), drifted_chain(truth))
    assert len(sm.index) == 0 and sm.poses.shape == (0, 3) and sm.anchors == 0
