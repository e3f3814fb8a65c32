"""Worlds (:mod:`laser_corners.sim.worlds`): scans of walls and circles, noise, corners and their
visibility."""

from __future__ import annotations

import math

import numpy as np
import pytest

from laser_corners.sim import (
    UST_10LX,
    World,
    corner_scan,
    rectangular_room,
)


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


def test_corner_scan_is_a_clean_corner() -> None:
    scan = corner_scan((2.0, 1.0))
    xy, valid = scan.to_cartesian()
    d = np.hypot(xy[valid, 0] - 2.0, xy[valid, 1] - 1.0)
    assert d.min() < 0.01
