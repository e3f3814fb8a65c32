"""Range-noise estimate from one scan (:mod:`laser_corners.noise`): recovers the simulated sigma;
clean geometry looks quiet."""

from __future__ import annotations

import numpy as np
import pytest

from laser_corners.noise import estimate_range_noise
from laser_corners.sim import SICK_LMS_1DEG, UST_10LX, random_poses, random_world


@pytest.mark.parametrize("sigma", [0.005, 0.01, 0.03])
def test_noise_estimate_from_the_scan_alone(sigma: float) -> None:
    rng = np.random.default_rng(11)
    estimates = []
    for _ in range(4):
        world = random_world(rng)
        pose = tuple(random_poses(world, 1, rng)[0])
        estimates.append(estimate_range_noise(world.scan(pose, UST_10LX, sigma, rng)))
    assert np.median(estimates) == pytest.approx(sigma, rel=0.15)
    world = random_world(rng)
    clean = world.scan(tuple(random_poses(world, 1, rng)[0]), SICK_LMS_1DEG)
    assert estimate_range_noise(clean) < 0.003  # geometry alone looks like little noise
