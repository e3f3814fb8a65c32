"""Free space of the map (:mod:`laser_corners.localise.freespace`). Issue 20, a later visit: the
far part of a hall that the map saw only from afar.

The mapping robot stayed at one end of a long hall; its long-range scanner saw the far end, so
the rays of the map cross the far part, but only tens of metres from their sensor, where a
keyframe heading error of half a degree moves a ray by more than a cell (and glass, railings
and thin legs are missed at grazing angles). Since then the far part was furnished. A robot of
the later visit drives into it: its right poses put the furniture where the map's far rays
passed. The map is not sure of that space, so the right poses must not be refused as
contradicting the map's free space (aces' later visit: right local poses refused on 0.2-0.3 of
their beams at the map's fringe, the track lost for 25.8 m of travel); near the mapping robot a
new object still contradicts the map.
"""

from __future__ import annotations

import numpy as np
import pytest
from test_localiser import RATE, map_folder, noisy_odometry, scans_along

from laser_corners.localise import Localiser
from laser_corners.localise.freespace import FREE, KNOWN, FreeSpace
from laser_corners.registration.mapfolder import load_map
from laser_corners.registration.points import scan_points
from laser_corners.sim import UST_10LX, World

LENGTH, WIDTH = 36.0, 10.0
LANE = 1.0
"""Half-width (m) of the lane along the hall's middle that the furniture leaves free."""


def hall(furnished: bool) -> World:
    """A 36 x 10 m hall with a few pillars near its start; furnished: boxes in its far part,
    sparse from x = 13 m, dense from x = 19 m, a lane free along the middle."""
    world = World().add_polygon([[0, 0], [LENGTH, 0], [LENGTH, WIDTH], [0, WIDTH]])
    for x, y in ((3.0, 2.0), (5.5, 8.0), (8.5, 1.5)):
        world.add_polygon([[x, y], [x + 0.4, y], [x + 0.4, y + 0.4], [x, y + 0.4]])
    if not furnished:
        return world
    rng = np.random.default_rng(0)
    for x in np.arange(13.0, 33.0, 1.2):
        step = 1.0 if x > 19.0 else 2.5
        for y in np.arange(0.6, WIDTH - 0.6, step):
            if abs(y - WIDTH / 2) < LANE + 0.4:
                continue
            w, h = rng.uniform(0.3, 0.6, 2)
            world.add_polygon([[x, y], [x + w, y], [x + w, y + h], [x, y + h]])
    return world


def along(x0: float, x1: float) -> np.ndarray:
    """Poses along the hall's middle at 0.5 m/s, RATE Hz."""
    x = np.arange(x0, x1, 0.5 / RATE) if x1 > x0 else np.arange(x0, x1, -0.5 / RATE)
    return np.column_stack(
        [x, np.full_like(x, WIDTH / 2), np.full_like(x, 0.0 if x1 > x0 else np.pi)]
    )


@pytest.fixture(scope="module")
def near_end(tmp_path_factory):
    """The empty hall mapped from its first 6 m (there and back)."""
    truth = np.vstack([along(1.0, 6.0), along(6.0, 1.0)])
    return map_folder(tmp_path_factory.mktemp("hall"), hall(False), truth)


def free_share(space: FreeSpace, x0: float, x1: float) -> float:
    """Share of the known cells of the hall between ``x0`` and ``x1`` that are surely free."""
    i0, i1 = ((np.array([x0, x1]) - space.origin[0]) / space.resolution).astype(int)
    j0, j1 = ((np.array([1.0, WIDTH - 1.0]) - space.origin[1]) / space.resolution).astype(int)
    cells = space.state[j0:j1, i0:i1]
    return float(((cells & FREE) != 0).sum() / max(((cells & KNOWN) != 0).sum(), 1))


def test_space_seen_only_from_afar_is_not_surely_free(near_end) -> None:
    space = FreeSpace.build(load_map(near_end))
    assert free_share(space, 1.0, 9.0) > 0.9  # crossed near the mapping robot's sensor
    assert free_share(space, 17.0, 33.0) < 0.02  # crossed only more than 11 m from it
    # right poses among the new furniture: nothing contradicts the map (before: 0.26)
    for x in (12.0, 16.0):
        pose = along(x, x + 1.0)[0]
        scan = short_range_scans(hall(True), pose[None], seed=2)[0]
        xy = scan_points(scan, np.zeros(3), 0.1, 30.0, 0.1).xy
        assert space.support(pose, xy, np.zeros(3)).conflict < 0.05
    # a new box beside the mapping robot's path is still a contradiction
    near = along(3.0, 4.0)[0]
    boxed = hall(False).add_polygon([[4.0, 3.0], [7.0, 3.0], [7.0, 4.3], [4.0, 4.3]])
    boxed.add_polygon([[4.0, 5.7], [7.0, 5.7], [7.0, 7.0], [4.0, 7.0]])
    xy = scan_points(scans_along(boxed, near[None], seed=2)[0], np.zeros(3), 0.1, 30, 0.1).xy
    assert space.support(near, xy, np.zeros(3)).conflict > 0.2


def short_range_scans(world: World, truth: np.ndarray, seed: int) -> list:
    """The later visit's robot has a 10 m scanner (270°): the furniture comes into view as
    it drives on."""
    rng = np.random.default_rng(seed)
    return [
        world.scan(tuple(p), UST_10LX, noise_sigma=0.01, rng=rng, stamp=i / RATE)
        for i, p in enumerate(truth)
    ]


def test_driving_into_the_far_part_furnished_since_keeps_a_true_pose(near_end) -> None:
    drive = along(2.0, 30.0)
    loc = Localiser(near_end)
    loc.set_pose(drive[0])
    scans = short_range_scans(hall(True), drive, seed=4)
    odo = noisy_odometry(drive, seed=4)
    estimates = [loc.add(s, o, i / RATE) for i, (s, o) in enumerate(zip(scans, odo, strict=True))]
    got = [(i, e) for i, e in enumerate(estimates) if e is not None]
    off = np.array([np.hypot(*(e.pose[:2] - drive[i, :2])) for i, e in got])
    assert off.max() < 0.3, f"{(off > 0.3).sum()} estimates > 0.3 m off, max {off.max()}"
    assert len(got) >= 0.95 * len(drive), f"only {len(got)} of {len(drive)} scans have a pose"
    assert loc.counts["lost"] == 0
    assert loc.counts["local"] > 0  # among the furniture the map explains too little
