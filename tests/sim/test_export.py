"""Simulated sequences (:mod:`laser_corners.sim.export`) written as NPZ and as a bag read back the
same."""

from __future__ import annotations

import numpy as np
import pytest

from laser_corners.sim import (
    UST_10LX,
    random_world,
    trajectory,
)
from laser_corners.sim.export import simulate_sequence, write_sequence


def test_export_round_trip_npz_and_bag(tmp_path) -> None:
    from laser_corners.io import open_scans

    rng = np.random.default_rng(2)
    world = random_world(rng, "room")
    poses = trajectory(world, 12, rng, rate_hz=UST_10LX.rate_hz)
    seq = simulate_sequence(world, UST_10LX, poses, 0.01, rng)
    paths = write_sequence(seq, tmp_path / "sim")
    truth = np.load(paths["truth"])
    assert truth["visible"].shape == (12, len(world.corners))
    assert truth["corners"] == pytest.approx(world.corners)
    for key in ("scans", "bag"):
        scans = list(open_scans(paths[key]))
        assert len(scans) == 12
        for got, want, pose in zip(scans, seq.scans, poses, strict=True):
            assert got.stamp == pytest.approx(want.stamp)
            assert got.pose == pytest.approx(tuple(pose), abs=1e-9)
            ok = np.isfinite(want.ranges)
            tol = 1e-6 if key == "bag" else 0.0  # float32 in the bag
            assert np.allclose(got.ranges[ok], want.ranges[ok], atol=tol, rtol=tol)
            assert not np.isfinite(got.ranges[~ok]).any() or not got.valid[~ok].any()
