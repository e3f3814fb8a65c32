"""Exact ray casting (:mod:`laser_corners.sim.raycast`): segments and circles, nearest hit,
misses."""

from __future__ import annotations

import math

import numpy as np
import pytest

from laser_corners.sim import (
    cast_circles,
    cast_ranges,
)


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
