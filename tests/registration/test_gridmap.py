"""Maps made by other packages (a map_server YAML + PGM): virtual keyframes, localisation."""

from __future__ import annotations

import itertools
import math
from pathlib import Path

import numpy as np
import pytest
import yaml

from conftest import real_file
from laser_corners.errors import InputError
from laser_corners.io.occupancy import OccupancyGrid, read_map, write_map
from laser_corners.localise import LocaliseOptions, Localiser, SmoothOptions, run_localise
from laser_corners.pose import between_many, compose_many
from laser_corners.registration.gridmap import (
    BEAMS,
    CLEARANCE,
    RANGE_MAX,
    SPACING,
    PointSettings,
    cast_grid,
    virtual_keyframes,
)
from laser_corners.registration.mapfolder import load_map
from laser_corners.registration.points import scan_points
from laser_corners.sim import SICK_LMS_1DEG, World, cast_circles, cast_ranges
from laser_corners.slam import SlamOptions
from laser_corners.slam.grid import result_grid
from laser_corners.slam.run import run_slam

RATE = 10.0
RES = 0.05
ORIGIN = (-1.0, -1.0)
"""The image's lower-left corner: 1 m of unknown space around the building."""


def building() -> World:
    """Four rooms on both sides of a 20 m corridor (y 5.1..6.9), a door into each, furniture."""
    world = World().add_polygon([[0, 0], [20, 0], [20, 12], [0, 12]])
    for x0, x1 in ((0, 3), (4, 14), (15, 20)):  # corridor's lower wall, doors at x 3, 14
        world.add_polygon([[x0, 5.0], [x1, 5.0], [x1, 5.1], [x0, 5.1]])
    for x0, x1 in ((0, 5), (6, 16), (17, 20)):  # upper wall, doors at x 5, 16
        world.add_polygon([[x0, 6.9], [x1, 6.9], [x1, 7.0], [x0, 7.0]])
    world.add_polygon([[11, 0], [11.1, 0], [11.1, 5.0], [11, 5.0]])
    world.add_polygon([[8, 7.0], [8.1, 7.0], [8.1, 12], [8, 12]])
    world.add_polygon([[2, 1.5], [2.8, 1.5], [2.8, 2.2], [2, 2.2]])  # a pillar
    world.add_polygon([[14, 9], [15, 9], [14.5, 10]])  # a triangle
    world.add_polygon([[2, 9.5], [3.5, 9.5], [3.5, 10.2], [2, 10.2]])  # a cupboard
    world.add_polygon([[6, 2.5], [7.5, 2.5], [7.5, 3.0], [6, 3.0]])  # a desk
    world.add_circle((16.0, 2.5), 0.2)
    return world


def rasterise(world: World) -> np.ndarray:
    """The world as a map_server image (top row first): walls black, inside white, outside
    grey; cells a wall segment passes within 0.7 of a cell of are black too."""
    cols, rows = round(22 / RES), round(14 / RES)
    cx = ORIGIN[0] + (np.arange(cols) + 0.5) * RES
    cy = ORIGIN[1] + (np.arange(rows) + 0.5) * RES
    gx, gy = np.meshgrid(cx, cy)
    centres = np.column_stack([gx.ravel(), gy.ravel()])
    inside = (gx >= 0) & (gx <= 20) & (gy >= 0) & (gy <= 12)
    free = world.is_free(centres).reshape(gx.shape)
    occupancy = np.where(inside, np.where(free, 0, 100), -1)
    for x1, y1, x2, y2 in world.segments:
        t = np.linspace(0.0, 1.0, int(math.hypot(x2 - x1, y2 - y1) / (0.2 * RES)) + 2)
        px, py = x1 + t * (x2 - x1), y1 + t * (y2 - y1)
        occupancy[((py - ORIGIN[1]) / RES).astype(int), ((px - ORIGIN[0]) / RES).astype(int)] = 100
    image = np.select([occupancy == 100, occupancy == 0], [0, 254], 205).astype(np.uint8)
    return image[::-1]


def write_foreign(folder: Path, image: np.ndarray, **fields) -> Path:
    """``map.pgm`` + ``map.yaml`` as ROS map_saver writes them (205: unknown)."""
    folder.mkdir(parents=True, exist_ok=True)
    rows, cols = image.shape
    header = f"P5\n# CREATOR: map_saver.cpp {RES:.3f} m/pix\n{cols} {rows}\n255\n"
    (folder / "map.pgm").write_bytes(header.encode() + image.tobytes())
    meta = {
        "image": "map.pgm",
        "mode": "trinary",
        "resolution": RES,
        "origin": [ORIGIN[0], ORIGIN[1], 0.0],
        "negate": 0,
        "occupied_thresh": 0.65,
        "free_thresh": 0.196,
        **fields,
    }
    (folder / "map.yaml").write_text(yaml.safe_dump(meta, sort_keys=False))
    return folder / "map.yaml"


@pytest.fixture(scope="module")
def foreign(tmp_path_factory) -> Path:
    return write_foreign(tmp_path_factory.mktemp("foreign"), rasterise(building()))


@pytest.fixture(scope="module")
def saved(foreign):
    return load_map(foreign)


def test_virtual_keyframes_cover_every_room_clear_of_the_walls(saved) -> None:
    world = building()
    poses = saved.poses
    assert saved.virtual_scans is not None and len(saved.virtual_scans) == len(poses) > 100
    assert np.all(world.is_free(poses[:, :2], clearance=CLEARANCE - RES))
    assert np.all(poses[:, 2] == 0.0)  # the grid's heading: the scanner sees all around
    rooms = {  # x0, x1, y0, y1 of the four rooms and the corridor
        "C": (0, 3, 0, 5),
        "D": (11.1, 20, 0, 5),
        "corridor": (0, 20, 5.1, 6.9),
        "A": (0, 8, 7, 12),
        "B": (8.1, 20, 7, 12),
    }
    for name, (x0, x1, y0, y1) in rooms.items():
        inside = (poses[:, 0] > x0) & (poses[:, 0] < x1) & (poses[:, 1] > y0) & (poses[:, 1] < y1)
        assert inside.sum() >= 3, name
    # every free place clear of the walls has a keyframe within a block's diagonal
    rng = np.random.default_rng(0)
    probe = rng.uniform([0, 0], [20, 12], (400, 2))
    probe = probe[world.is_free(probe, clearance=0.5)]
    gaps = np.hypot(*(probe[:, None, :] - poses[None, :, :2]).transpose(2, 0, 1)).min(axis=1)
    assert gaps.max() < SPACING * math.sqrt(2)
    assert saved.mount.tolist() == [0.0, 0.0, 0.0] and np.all(saved.stamps == 0)


def wall_distance(world: World, xy: np.ndarray) -> np.ndarray:
    """Distance of each point (N, 2) to the nearest wall segment or circle of ``world``."""
    seg = world.segments
    a, e = seg[None, :, :2], (seg[:, 2:] - seg[:, :2])[None]
    u = np.clip(np.sum((xy[:, None] - a) * e, axis=2) / np.sum(e * e, axis=2), 0.0, 1.0)
    d = np.hypot(*(xy[:, None] - a - u[..., None] * e).transpose(2, 0, 1)).min(axis=1)
    c = world.circles
    to_circle = np.abs(np.hypot(*(xy[:, None] - c[None, :, :2]).transpose(2, 0, 1)) - c[:, 2])
    return np.minimum(d, to_circle.min(axis=1))


def test_virtual_scans_end_on_the_walls(saved) -> None:
    world = building()
    scan = saved.virtual_scans[0]
    assert scan.n_beams == BEAMS and scan.range_max == RANGE_MAX
    assert math.isclose(scan.angle_increment * BEAMS, 2 * math.pi)
    angles = scan.angle_min + scan.angle_increment * np.arange(BEAMS)
    off = []
    for pose, scan in zip(saved.poses[::7], saved.virtual_scans[::7], strict=True):
        exact = np.minimum(
            cast_ranges(world.segments, tuple(pose), angles),
            cast_circles(world.circles, tuple(pose), angles),
        )
        got = np.asarray(scan.ranges)
        assert np.all(np.isfinite(got) == (exact < RANGE_MAX))  # a closed building: all hit
        hit = np.isfinite(got)
        a = angles[hit] + pose[2]
        ends = pose[:2] + got[hit, None] * np.column_stack([np.cos(a), np.sin(a)])
        off.append(wall_distance(world, ends))
        # the range itself is off by more only where the beam grazes a wall
        assert np.median(np.abs(got[hit] - exact[hit])) < RES
    off = np.concatenate(off)
    # every end point lies on a wall: within a cell of it (the walls drawn 0.7 cell wide)
    assert off.max() < 2 * RES and np.median(off) < 0.75 * RES


def test_virtual_keyframe_points_are_made_as_real_keyframes(saved) -> None:
    opt = SlamOptions()
    for k in (0, len(saved) // 2, len(saved) - 1):
        pts = scan_points(
            saved.virtual_scans[k], np.zeros(3), opt.min_range, opt.max_range, opt.point_spacing
        )
        lo, hi = saved.offsets[k], saved.offsets[k + 1]
        np.testing.assert_array_equal(saved.points[lo:hi], pts.xy)
        np.testing.assert_array_equal(saved.normals[lo:hi], pts.normals)
        np.testing.assert_array_equal(saved.has_normal[lo:hi], pts.has_normal)
    xy, normals, line = saved.world_points()
    top = (np.abs(xy[:, 1] - 12.0) < 0.1) & (np.abs(xy[:, 0] - 8.05) > 0.5)
    on_wall = top & (xy[:, 0] > 0.5) & (xy[:, 0] < 19.5)  # the top wall: normals along y
    assert on_wall.sum() > 50 and line[on_wall].mean() > 0.9
    assert np.abs(normals[on_wall & line, 1]).min() > 0.95


def test_grid_origin_with_a_yaw_turns_the_keyframes(tmp_path, saved) -> None:
    yaw = math.radians(30)
    turned = load_map(write_foreign(tmp_path, rasterise(building()), origin=[2.0, 1.0, yaw]))
    assert len(turned) == len(saved)
    # the same keyframes in the grid's frame, moved by the origin (x, y, yaw) instead
    local = saved.poses - [ORIGIN[0], ORIGIN[1], 0.0]
    c, s = math.cos(yaw), math.sin(yaw)
    expected = np.column_stack(
        [2 + c * local[:, 0] - s * local[:, 1], 1 + s * local[:, 0] + c * local[:, 1]]
    )
    np.testing.assert_allclose(turned.poses[:, :2], expected, atol=1e-9)
    np.testing.assert_allclose(turned.poses[:, 2], yaw)
    # the same scans in the keyframe's frame (but for beams through a cell's corner, where
    # the rounding of the turned start decides which of two cells the beam visits)
    ranges = np.array([s.ranges for s in saved.virtual_scans])
    turned_ranges = np.array([s.ranges for s in turned.virtual_scans])
    same = np.isclose(turned_ranges, ranges, atol=1e-6) | (
        np.isinf(ranges) & np.isinf(turned_ranges)
    )
    assert same.mean() > 0.995
    assert abs(len(turned.points) - len(saved.points)) < 0.001 * len(saved.points)


def test_grid_map_problems_are_one_line(tmp_path: Path) -> None:
    image = rasterise(building())
    bad = write_foreign(tmp_path / "bad", image, mode="ternary")
    with pytest.raises(InputError, match=r"map.yaml: field 'mode': 'ternary' is not one of"):
        Localiser(bad)
    bad = write_foreign(tmp_path / "res", image, resolution=-0.05)
    with pytest.raises(InputError, match=r"map.yaml: field 'resolution': must be a number > 0"):
        load_map(bad)
    missing = write_foreign(tmp_path / "missing", image)
    (tmp_path / "missing" / "map.pgm").unlink()
    with pytest.raises(InputError, match=r"map.yaml: field 'image': its image .* does not exist"):
        load_map(missing)
    # an image of unknown space only (205): nowhere to localise
    wrong = write_foreign(tmp_path / "neg", np.full_like(image, 205))
    with pytest.raises(InputError, match=r"map.yaml: no free cell far enough from the walls"):
        load_map(wrong)
    with pytest.raises(InputError, match=r"map.pgm: not a map folder nor a map_server .yaml"):
        load_map(tmp_path / "bad" / "map.pgm")
    with pytest.raises(InputError, match="no such file"):
        load_map(tmp_path / "none.yaml")


@pytest.mark.parametrize(
    ("values", "name"),
    [
        ({"spacing": 0.0}, "spacing"),
        ({"clearance": -1.0}, "clearance"),
        ({"beams": 2}, "beams"),
        ({"range_max": float("inf")}, "range_max"),
    ],
)
def test_bad_virtual_keyframe_parameters_are_named(values, name) -> None:
    grid = OccupancyGrid(room_grid(), RES, (0.0, 0.0, 0.0))
    with pytest.raises(ValueError, match=f"^{name} must be"):
        virtual_keyframes(grid, **values)


def test_virtual_keyframes_of_an_empty_grid_are_none() -> None:
    grid = OccupancyGrid(np.full((20, 20), -1, np.int8), 0.05, (0.0, 0.0, 0.0))
    assert len(virtual_keyframes(grid)) == 0


def room_grid(size: int = 100) -> np.ndarray:
    """Occupancy of a free square room (``size`` cells of 0.05 m) walled by occupied cells,
    in unknown space (row 0 the bottom)."""
    occupancy = np.full((size + 20, size + 20), -1, np.int8)
    occupancy[10 : size + 10, 10 : size + 10] = 100
    occupancy[11 : size + 9, 11 : size + 9] = 0
    return occupancy


def test_a_wall_with_one_cell_holes_does_not_leak() -> None:
    """A wall seen sparsely (every other cell) stops the beams: they end on it."""
    occupancy = room_grid()
    occupancy[60, 11:109] = 100  # a wall across the room at y = 3.0-3.05 m ...
    occupancy[60, 12:109:2] = 0  # ... every other cell missing (seen sparsely) ...
    occupancy[60, 40:80:2] = -1  # ... here never seen (a foreign map's unknown)
    grid = OccupancyGrid(occupancy, RES, (0.0, 0.0, 0.0))
    pose = np.array([[3.0, 1.5, 0.0]])  # below the wall
    ranges = cast_grid(grid, pose)[0]
    angles = -math.pi + 2 * math.pi / BEAMS * np.arange(BEAMS)
    up = (angles > 0.7) & (angles < math.pi - 0.7)  # the beams reaching the wall
    assert np.all(np.isfinite(ranges[up]))
    ends_y = pose[0, 1] + ranges[up] * np.sin(angles[up])
    assert np.all(np.abs(ends_y - 3.0) < 2 * RES), ends_y.max()  # on the wall, not behind


def test_unknown_specks_in_free_space_do_not_stop_the_beams() -> None:
    occupancy = room_grid()
    rows, cols = np.mgrid[0 : occupancy.shape[0], 0 : occupancy.shape[1]]
    speck = (occupancy == 0) & ((rows * 7 + cols * 3) % 11 == 0)  # isolated cells never seen
    occupancy[speck] = -1
    grid = OccupancyGrid(occupancy, RES, (0.0, 0.0, 0.0))
    virtual = virtual_keyframes(grid)
    # one keyframe per 0.75 m block clear of the walls: 0.3 m clearance in a 4.9 m room
    assert len(virtual) >= 36
    ranges = np.array([s.ranges for s in virtual.scans])
    assert np.isfinite(ranges).mean() > 0.99  # every beam ends on a wall


# ---------------------------------------------------------------- localisation in it
def path_through(waypoints) -> np.ndarray:
    """Poses at RATE Hz along ``waypoints`` at 0.5 m/s, turning in place at each corner."""
    poses = []
    for a, b in itertools.pairwise(waypoints):
        a, b = np.asarray(a, float), np.asarray(b, float)
        heading = math.atan2(b[1] - a[1], b[0] - a[0])
        if poses:  # turn towards the leg, 0.15 rad a scan
            turn = (heading - poses[-1][2] + math.pi) % (2 * math.pi) - math.pi
            n = math.ceil(abs(turn) / 0.15)
            poses.extend((a[0], a[1], poses[-1][2] + turn * k / n) for k in range(1, n))
        n = int(np.hypot(*(b - a)) / 0.05)
        poses.extend((*(a + t * (b - a)), heading) for t in np.arange(n) / n)
    return np.array(poses)


DRIVE = path_through([[1.0, 3.5], [3.5, 3.5], [3.5, 6.0], [16.5, 6.0], [16.5, 9.5], [18.5, 9.5]])
"""From room C through the corridor into room B: 23.5 m."""


def drive(truth: np.ndarray, seed: int) -> tuple[list, np.ndarray]:
    """Scans (SICK LMS 1°, 1 cm noise) and odometry (3 % scale error, a yaw bias, noise)."""
    rng = np.random.default_rng(seed)
    world = building()
    scans = [
        world.scan(tuple(p), SICK_LMS_1DEG, noise_sigma=0.01, rng=rng, stamp=i / RATE)
        for i, p in enumerate(truth)
    ]
    odo = [np.array([5.0, -3.0, 1.0])]  # an odometry frame unrelated to the map's
    for d in between_many(truth[:-1], truth[1:]):
        noisy = np.array([d[0] * 1.03, d[1], d[2] * 1.02 + 0.002])
        odo.append(compose_many(odo[-1], noisy + rng.normal(0.0, [0.004, 0.002, 0.003])))
    return scans, np.array(odo)


def errors(estimates, truth) -> tuple[np.ndarray, np.ndarray]:
    idx = np.array([i for i, e in enumerate(estimates) if e is not None], dtype=int)
    poses = np.array([estimates[i].pose for i in idx]).reshape(-1, 3)
    d = np.hypot(*(poses[:, :2] - truth[idx, :2]).T)
    yaw = np.abs((poses[:, 2] - truth[idx, 2] + np.pi) % (2 * np.pi) - np.pi)
    return d, yaw


def test_localiser_fixes_and_tracks_in_a_foreign_map(foreign) -> None:
    scans, odo = drive(DRIVE, 3)
    loc = Localiser(foreign)  # the YAML path, as the CLI and the ROS node pass it
    assert loc.mount.tolist() == [0.0, 0.0, 0.0]
    estimates = [loc.add(s, o, i / RATE) for i, (s, o) in enumerate(zip(scans, odo, strict=True))]
    assert loc.fixes, "no fix"
    first = loc.fixes[0]
    assert first.travel <= 4.0  # a few metres
    fix = np.asarray(first.pose)
    assert np.hypot(*(fix[:2] - DRIVE[first.scan_index, :2])) < 0.2
    d, yaw = errors(estimates, DRIVE)
    assert len(d) >= 0.95 * (len(DRIVE) - first.scan_index)
    assert np.percentile(d, 95) < 0.1 and d.max() < 0.2 and yaw.max() < math.radians(3)
    assert loc.counts["lost"] == 0


def test_localiser_tracks_from_an_initial_pose_in_a_foreign_map(saved) -> None:
    scans, odo = drive(DRIVE, 4)
    loc = Localiser(saved)
    loc.set_pose(DRIVE[0])
    estimates = [loc.add(s, o, i / RATE) for i, (s, o) in enumerate(zip(scans, odo, strict=True))]
    d, yaw = errors(estimates, DRIVE)
    assert len(d) >= 0.98 * len(DRIVE)
    assert np.mean(d) < 0.05 and d.max() < 0.15 and yaw.max() < math.radians(2)


def test_read_map_of_the_foreign_map_keeps_its_grid(foreign, saved) -> None:
    grid = read_map(foreign)
    assert saved.grid is not None and saved.grid.shape == grid.shape
    np.testing.assert_array_equal(saved.grid.occupancy, grid.occupancy)
    assert saved.folder == foreign


# ---------------------------------------------------------------- fr079: our map.yaml alone
MAPPED = 1500
"""fr079 scans mapped (its first part)."""
LATER = (900, 1500)
"""The scans localised: the later part of the mapped stretch (the robot drives back along
the corridor it mapped)."""


@pytest.fixture(scope="module")
def fr079_yaml(tmp_path_factory):
    """fr079's first part mapped by our SLAM; its map.yaml + map.pgm written as ``slam``
    writes them, without keyframes.npz: localisation sees only the grid."""
    bag = real_file("fr079.bag")
    result = run_slam(bag, stop_scan=MAPPED)
    folder = tmp_path_factory.mktemp("fr079")
    yaml_path, _ = write_map(result_grid(result), folder / "map.yaml")
    assert sorted(p.name for p in folder.iterdir()) == ["map.pgm", "map.yaml"]
    return bag, yaml_path, result


def slam_errors(run, result) -> np.ndarray:
    """Distance (m) of each estimate from the SLAM's pose of its scan."""
    index = np.searchsorted(result.stamps, run.stamps)
    assert np.allclose(result.stamps[index], run.stamps)
    return np.hypot(*(run.poses[:, :2] - result.poses[index, :2]).T)


def test_fr079_our_map_yaml_as_a_foreign_map(fr079_yaml) -> None:
    bag, yaml_path, result = fr079_yaml
    options = LocaliseOptions(smooth=SmoothOptions(enabled=False))
    run = run_localise(yaml_path, bag, options, start_scan=LATER[0], stop_scan=LATER[1])
    assert run.fixes, run.counts
    for fix in run.fixes:  # every fix right
        assert np.hypot(*(np.asarray(fix.pose[:2]) - result.poses[fix.scan_index, :2])) < 0.3
    d = slam_errors(run, result)
    after = LATER[1] - run.fixes[0].scan_index
    assert len(d) >= 0.9 * after and np.mean(d < 0.3) >= 0.98 and np.median(d) < 0.05
    # from an initial pose: every scan tracked
    start = result.poses[LATER[0]]
    run = run_localise(
        yaml_path, bag, options, start_scan=LATER[0], stop_scan=LATER[1], initial_pose=start
    )
    d = slam_errors(run, result)
    assert len(d) >= 0.95 * (LATER[1] - LATER[0])
    assert np.mean(d < 0.3) >= 0.98 and np.percentile(d, 95) < 0.1


def test_virtual_keyframe_points_take_the_slams_defaults() -> None:
    settings, slam = PointSettings(), SlamOptions()
    assert (settings.min_range, settings.max_range, settings.point_spacing) == (
        slam.min_range,
        slam.max_range,
        slam.point_spacing,
    )
    assert settings.places == slam.places
