"""Random worlds, poses and trajectories (:mod:`laser_corners.sim.generate`) stay in free space;
unknown kinds are refused."""

from __future__ import annotations

import numpy as np
import pytest

from laser_corners.errors import InvalidParamsError
from laser_corners.sim import (
    WORLD_KINDS,
    random_poses,
    random_world,
    trajectory,
)


@pytest.mark.parametrize("kind", WORLD_KINDS)
def test_random_worlds_poses_and_trajectories_stay_in_free_space(kind: str) -> None:
    rng = np.random.default_rng(4)
    world = random_world(rng, kind)
    assert world.name == kind
    assert len(world.corners) >= 4
    assert np.all((world.corner_angles_deg > 45) & (world.corner_angles_deg < 135))
    poses = random_poses(world, 20, rng, clearance=0.4)
    assert world.is_free(poses[:, :2], clearance=0.4).all()
    drive = trajectory(world, 120, rng, rate_hz=40.0, speed=0.5)
    steps = np.hypot(*np.diff(drive[:, :2], axis=0).T)
    assert steps.max() <= 0.5 / 40.0 + 1e-9
    assert steps.sum() > 0.5  # it moves
    assert world.is_free(drive[:, :2], clearance=0.15).all()


def test_random_world_rejects_unknown_kind() -> None:
    with pytest.raises(InvalidParamsError, match="unknown world kind"):
        random_world(np.random.default_rng(0), "cave")


def test_corridor_doors_stay_inside_the_corridor() -> None:
    # regression: a door loop that overshot the corridor's end never stopped
    for seed in range(300):
        outline = random_world(np.random.default_rng(seed), "corridor").polygons[0]
        length = outline[:, 0].max()
        assert outline[:, 0].min() == 0.0 and 8.0 <= length <= 14.0
        assert len(outline) < 60
