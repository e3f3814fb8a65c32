"""Simulator: ray casting, worlds, visibility of corners, sensors, trajectories, export, CLI."""

from __future__ import annotations

import math

import numpy as np
import pytest
from typer.testing import CliRunner

from laser_corners.cli import app
from laser_corners.errors import InvalidParamsError
from laser_corners.sim import (
    HOKUYO_270_0352,
    SENSORS,
    SICK_LMS_05DEG,
    SICK_LMS_1DEG,
    UST_10LX,
    WORLD_KINDS,
    World,
    cast_circles,
    cast_ranges,
    corner_scan,
    get_sensor,
    random_poses,
    random_world,
    rectangular_room,
    trajectory,
)
from laser_corners.sim.export import simulate_sequence, write_sequence


def test_cast_ranges_hits_the_nearest_wall_exactly() -> None:
    walls = np.array([[2.0, -5.0, 2.0, 5.0], [3.0, -5.0, 3.0, 5.0]])
    angles = np.radians([0.0, 30.0, -45.0, 180.0])
    r = cast_ranges(walls, (0.0, 0.0, 0.0), angles)
    assert r[:3] == pytest.approx([2.0, 2.0 / math.cos(math.radians(30)), 2.0 * math.sqrt(2)])
    assert math.isinf(r[3])
    # the sensor's heading rotates the beams
    assert cast_ranges(walls, (0.0, 0.0, math.pi), [math.pi])[0] == pytest.approx(2.0)


def test_cast_circles_front_surface_and_misses() -> None:
    circles = np.array([[2.0, 0.0, 0.5]])
    r = cast_circles(circles, (0.0, 0.0, 0.0), [0.0, math.pi / 2])
    assert r[0] == pytest.approx(1.5)
    assert math.isinf(r[1])
    assert math.isinf(cast_circles(np.zeros((0, 3)), (0, 0, 0), [0.0])[0])


def test_world_scan_combines_walls_and_circles_and_caps_range() -> None:
    world = World().add_polygon([[-20, -20], [20, -20], [20, 20], [-20, 20]])
    world.add_circle((1.0, 0.0), 0.1)
    scan = world.scan((0.0, 0.0, 0.0), UST_10LX)
    front = int(np.argmin(np.abs(scan.angles)))
    assert scan.ranges[front] == pytest.approx(0.9)
    # walls 20 m away are beyond the UST-10LX's 10 m: no return
    assert np.isinf(scan.ranges[int(np.argmin(np.abs(scan.angles - 1.0)))])
    assert scan.pose == (0.0, 0.0, 0.0)


def test_noise_has_the_requested_sigma() -> None:
    world = rectangular_room()
    clean = world.scan((0.0, 0.0, 0.0), UST_10LX)
    noisy = world.scan((0.0, 0.0, 0.0), UST_10LX, noise_sigma=0.02, rng=np.random.default_rng(1))
    diff = (noisy.ranges - clean.ranges)[np.isfinite(clean.ranges)]
    assert np.std(diff) == pytest.approx(0.02, rel=0.1)


def test_corners_skip_collinear_vertices_and_report_angles() -> None:
    world = World().add_polygon([[0, 0], [1, 0], [2, 0], [2, 1], [0, 1]])
    assert world.corners.tolist() == [[0, 0], [2, 0], [2, 1], [0, 1]]
    assert world.corner_angles_deg == pytest.approx([90.0] * 4)
    t = 2 * np.pi * np.arange(6) / 6
    hexagon = World().add_polygon(np.column_stack([np.cos(t), np.sin(t)]))
    assert hexagon.corner_angles_deg == pytest.approx([120.0] * 6)


def test_visibility_fov_occlusion_and_hidden_walls() -> None:
    world = rectangular_room(6.0, 4.0)  # room corners at (+-3, +-2), pillar 1-1.5 x 0.5-1
    pose = (0.5, -1.0, 0.0)
    mask = world.visible_corner_mask(pose, UST_10LX)
    room, pillar = mask[:4], mask[4:]
    # 270 deg FOV looking along +x: the two room corners behind (x = -3) are out of view
    assert room.tolist() == [False, True, True, False]
    # the pillar shows the faces towards the sensor: its far corner (1.5, 1.0) is hidden;
    # the near-bottom corner (1.0, 0.5) sees both walls; the two others are silhouettes
    assert pillar.tolist() == [True, False, False, False]
    # a leg right in front of the visible bottom-right room corner occludes it
    world.add_circle((1.75, -1.5), 0.1)
    assert not world.visible_corner_mask(pose, UST_10LX)[1]
    # visible_corners gives them in the sensor frame
    seen = world.visible_corners(pose, UST_10LX)
    assert np.round(seen, 9).tolist() == [[2.5, 3.0], [0.5, 1.5]]  # (3, 2) and (1, 0.5)


def test_min_beams_drops_corners_seen_at_grazing_angles() -> None:
    world = World().add_polygon([[0, 0], [8, 0], [8, 4], [0, 4]])
    pose = (7.0, 0.3, math.pi)  # the bottom wall runs almost along the beams to (0, 0)
    assert world.visible_corner_mask(pose, UST_10LX, probe=0.25)[0]
    assert not world.visible_corner_mask(pose, UST_10LX, probe=0.25, min_beams=4)[0]


def test_sensor_profiles_match_their_recordings() -> None:
    assert UST_10LX.n_beams == 1081
    assert SICK_LMS_1DEG.n_beams == 180
    assert SICK_LMS_05DEG.n_beams == 360
    assert HOKUYO_270_0352.n_beams == 768
    assert HOKUYO_270_0352.angle_min == pytest.approx(-3 * math.pi / 4)
    assert HOKUYO_270_0352.angle_increment == pytest.approx(2 * math.pi / 1024)
    assert set(SENSORS) >= {"ust-10lx", "sick-1deg", "sick-0.5deg", "hokuyo-0.352deg"}
    with pytest.raises(InvalidParamsError, match="unknown sensor 'lms'"):
        get_sensor("lms")


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


def test_corner_scan_is_a_clean_corner() -> None:
    scan = corner_scan((2.0, 1.0))
    xy, valid = scan.to_cartesian()
    d = np.hypot(xy[valid, 0] - 2.0, xy[valid, 1] - 1.0)
    assert d.min() < 0.01


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


def test_cli_simulate_writes_files_and_reports_bad_sensor(tmp_path) -> None:
    runner = CliRunner()
    out = tmp_path / "s"
    result = runner.invoke(
        app, ["simulate", "-o", str(out), "--scans", "5", "--world", "l_room", "--noise", "0.01"]
    )
    assert result.exit_code == 0, result.output
    assert {p.name for p in out.iterdir()} == {"scans.npz", "truth.npz", "scans.bag"}
    assert "l_room" in result.output
    bad = runner.invoke(app, ["simulate", "-o", str(out), "--sensor", "lms"])
    assert bad.exit_code == 2
    assert "unknown sensor 'lms'" in bad.output


def test_corridor_doors_stay_inside_the_corridor() -> None:
    # regression: a door loop that overshot the corridor's end never stopped
    for seed in range(300):
        outline = random_world(np.random.default_rng(seed), "corridor").polygons[0]
        length = outline[:, 0].max()
        assert outline[:, 0].min() == 0.0 and 8.0 <= length <= 14.0
        assert len(outline) < 60


@pytest.mark.parametrize(
    ("call", "name"),
    [
        (lambda w, rng: w.scan((0.0, 0.0, 0.0), noise_sigma=-1.0), "noise_sigma"),
        (lambda w, rng: w.scan((0.0, 0.0, 0.0), noise_sigma=math.nan), "noise_sigma"),
        (lambda w, rng: trajectory(w, 5, rng, speed=math.nan), "speed"),
        (lambda w, rng: trajectory(w, 5, rng, speed=0.0), "speed"),
        (lambda w, rng: trajectory(w, 5, rng, speed=-0.5), "speed"),
        (lambda w, rng: trajectory(w, 5, rng, rate_hz=math.inf), "rate_hz"),
        (
            lambda w, rng: simulate_sequence(w, UST_10LX, np.zeros((0, 3)), -0.01, rng),
            "noise_sigma",
        ),
        (lambda w, rng: corner_scan(noise_sigma=-0.5), "noise_sigma"),
    ],
)
def test_nonsense_numbers_are_rejected_naming_the_parameter(call, name: str) -> None:
    with pytest.raises(InvalidParamsError, match=f"^{name} must be a finite number"):
        call(rectangular_room(), np.random.default_rng(0))


@pytest.mark.parametrize(("option", "value"), [("--noise", "-1"), ("--speed", "nan")])
def test_cli_simulate_rejects_nonsense_in_one_line(tmp_path, option: str, value: str) -> None:
    out = tmp_path / "sim"
    result = CliRunner().invoke(app, ["simulate", "-o", str(out), "--scans", "3", option, value])
    assert result.exit_code == 2, result.output
    assert result.output.count("\n") == 1 and option in result.output
    assert "must be >= 0" in result.output or "must be a finite number" in result.output
    assert not out.exists()


def test_checks_docstring_examples() -> None:
    import doctest

    import laser_corners.sim.checks

    result = doctest.testmod(laser_corners.sim.checks, optionflags=doctest.ELLIPSIS)
    assert result.attempted > 0 and result.failed == 0
