"""Registration accuracy evaluation on simulated pairs with known relative poses."""

from __future__ import annotations

import math

import numpy as np

from benchmark_modules import load
from laser_corners.scan import relative_pose
from laser_corners.sim import World

_study = load("registration_errors")  # the study, in benchmarks/
consecutive_pairs, registration_errors = _study.consecutive_pairs, _study.registration_errors


def _room() -> World:
    w = World()
    w.add_polygon(
        [
            [-4, -3],
            [1, -3],
            [1, -2.4],
            [2, -2.4],
            [2, -3],
            [4, -3],
            [4, 0],
            [3.4, 0],
            [3.4, 1],
            [4, 1],
            [4, 3],
            [-1, 3],
            [-1, 2.2],
            [-2.5, 2.2],
            [-2.5, 3],
            [-4, 3],
        ]
    )
    w.add_polygon([[0.5, 0.5], [1.2, 0.5], [1.2, 1.0], [0.5, 1.0]])
    w.add_polygon([[-0.5, -2.0], [0.0, -2.0], [0.0, -1.6], [-0.5, -1.6]])
    return w


def test_registration_errors_on_a_simulated_sequence() -> None:
    room = _room()
    rng = np.random.default_rng(0)
    poses = [(0.1 * k, -0.05 * k, 0.05 * k) for k in range(6)]
    scans = [room.scan(p, noise_sigma=0.01, rng=rng) for p in poses]
    pairs = consecutive_pairs(scans)
    assert len(pairs) == 5
    assert np.allclose(pairs[0][2], relative_pose(poses[0], poses[1]))
    res = registration_errors(scans, pairs)
    assert res.accepted.all()
    assert np.nanmax(res.trans) < 0.02 and np.nanmax(res.rot) < math.radians(1.0)
    # the scans' poses are exact here: the "odometry" has no error
    assert np.nanmax(res.odom_trans) < 1e-9
    s = res.summary()
    assert s["accepted"] == 1.0 and s["gross"] == 0.0 and s["trans_median"] < 0.02
