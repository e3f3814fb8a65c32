"""The occupancy grid of a simulated square room: walls occupied, inside free, outside unknown."""

from __future__ import annotations

import numpy as np
import pytest

from laser_corners.errors import InvalidParamsError
from laser_corners.scan import compose
from laser_corners.sim import World, get_sensor
from laser_corners.slam.grid import occupancy_grid

MOUNT = (0.2, -0.1, 0.3)


def _room_scans(mount=MOUNT):
    world = World(name="square room")
    world.add_polygon([[-3, -3], [3, -3], [3, 3], [-3, 3]])
    sensor = get_sensor("ust-10lx")
    poses = np.array(
        [
            [0.0, 0.0, 0.0],
            [1.0, 0.5, 1.0],
            [-1.2, 1.0, -2.0],
            [0.5, -1.5, 2.5],
            [-1.5, -1.5, 0.8],
            [1.5, 1.5, -2.4],
            [-0.5, 2.0, -1.2],
            [2.0, -0.5, 3.0],
        ]
    )
    scans = [
        world.scan(compose(tuple(p), mount), sensor, stamp=float(i)) for i, p in enumerate(poses)
    ]
    return poses, scans


def _state(grid, x, y) -> int:
    r, c = grid.cell(x, y)
    return int(grid.occupancy[r, c])


def test_square_room_walls_occupied_inside_free() -> None:
    poses, scans = _room_scans()
    grid = occupancy_grid(poses, scans, MOUNT, resolution=0.05)
    assert grid.resolution == 0.05
    walls = [(x, s * 3.0) for x in np.linspace(-2.8, 2.8, 40) for s in (-1, 1)]
    walls += [(s * 3.0, y) for y in np.linspace(-2.8, 2.8, 40) for s in (-1, 1)]
    # a wall cell sits on a boundary; the beam ends in the cell on or just outside the wall
    occupied = [
        max(_state(grid, x + dx, y + dy) for dx in (-0.02, 0.0, 0.02) for dy in (-0.02, 0.0, 0.02))
        for x, y in walls
    ]
    assert np.mean(np.asarray(occupied) >= 65) > 0.97
    inside = [(x, y) for x in np.linspace(-2.5, 2.5, 21) for y in np.linspace(-2.5, 2.5, 21)]
    free = np.array([_state(grid, x, y) for x, y in inside])
    assert np.all((free >= 0) & (free <= 25)), np.unique(free)
    assert not _known(grid, -3.3, 0.0) and not _known(grid, 0.0, 3.3)  # behind the walls


def test_a_wrong_mount_blurs_the_walls() -> None:
    poses, scans = _room_scans()
    good = occupancy_grid(poses, scans, MOUNT)
    bad = occupancy_grid(poses, scans, (0.0, 0.0, 0.0))
    assert _on_walls(good) > 0.95 and _on_walls(bad) < 0.8


def _on_walls(grid) -> float:
    """Share of the occupied cells whose centre is within 0.1 m of a wall of the room."""
    rows, cols = np.nonzero(grid.occupancy >= 65)
    x = grid.origin[0] + (cols + 0.5) * grid.resolution
    y = grid.origin[1] + (rows + 0.5) * grid.resolution
    distance = np.minimum(np.abs(3.0 - np.abs(x)), np.abs(3.0 - np.abs(y)))
    return float(np.mean(distance < 0.1))


def test_no_return_beams_clear_nothing_by_default() -> None:
    world = World(name="one wall")
    world.add_polygon([[2.0, -1.0], [2.2, -1.0], [2.2, 1.0], [2.0, 1.0]])
    scan = world.scan((0.0, 0.0, 0.0), get_sensor("ust-10lx"), stamp=0.0)
    assert np.count_nonzero(~np.isfinite(scan.ranges)) > 100  # most beams see nothing
    grid = occupancy_grid([[0.0, 0.0, 0.0]], [scan])
    assert 0 <= _state(grid, 1.0, 0.0) < 50  # in front of the wall: crossed once, leaning free
    assert grid.occupancy.shape[0] * 0.05 < 3.0  # the grid spans the hits only
    assert _known(grid, 0.0, 1.0) is False  # to the left nothing was seen: unknown
    cleared = occupancy_grid([[0.0, 0.0, 0.0]], [scan], no_return_clear=1.5)
    assert 0 <= _state(cleared, 0.0, 1.0) < 50  # cleared up to 1.5 m ...
    assert _known(cleared, 0.0, 1.7) is False  # ... and no further


def _known(grid, x, y) -> bool:
    r, c = grid.cell(x, y)
    inside = 0 <= r < grid.shape[0] and 0 <= c < grid.shape[1]
    return bool(inside and grid.occupancy[r, c] >= 0)


def test_bad_arguments_name_the_field() -> None:
    poses, scans = _room_scans()
    with pytest.raises(InvalidParamsError, match="resolution"):
        occupancy_grid(poses, scans, resolution=0.0)
    with pytest.raises(InvalidParamsError, match="8 poses but 3 scans"):
        occupancy_grid(poses, scans[:3])
    with pytest.raises(InvalidParamsError, match="no_return_clear"):
        occupancy_grid(poses, scans, no_return_clear=-1.0)
