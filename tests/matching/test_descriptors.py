"""Descriptors: rotation invariance, shapes, parameters."""

from __future__ import annotations

import math

import numpy as np
import pytest
from matching_world import corner_room

from laser_corners import CornerDetector, LaserScan
from laser_corners.errors import InvalidParamsError
from laser_corners.matching import DescriptorParams, describe
from laser_corners.matching.nearest import _distance
from laser_corners.sim import World


@pytest.fixture(scope="module")
def room() -> World:
    return corner_room()


def _rotated(scan: LaserScan, delta: float) -> LaserScan:
    """The same ranges seen by a sensor turned by -delta: every point turns by +delta."""
    return LaserScan(
        scan.ranges, scan.angle_min + delta, scan.angle_increment, scan.range_min, scan.range_max
    )


@pytest.mark.parametrize("kind", ["bsc", "csc"])
@pytest.mark.parametrize("delta", [0.3, 1.7, -2.9])
def test_descriptors_are_rotation_invariant(room: World, kind: str, delta: float) -> None:
    scan = room.scan((0.2, -0.4, 0.3), noise_sigma=0.005, rng=np.random.default_rng(1))
    det = CornerDetector()
    ka = det.detect(scan)
    turned = _rotated(scan, delta)
    kb = det.detect(turned)
    assert len(ka) >= 5 and len(ka) == len(kb)
    c, s = math.cos(delta), math.sin(delta)
    assert np.allclose(ka.xy @ np.array([[c, s], [-s, c]]), kb.xy, atol=0.01)
    da, db = describe(scan, ka, kind), describe(turned, kb, kind)
    inv = 1.0 / da.n_bits if da.n_bits else 0.0
    for i in range(len(ka)):
        dist = [
            _distance(da.kind_code, da.bits, da.values, i, db.bits, db.values, j, inv)
            for j in range(len(kb))
        ]
        # the same corner: a small distance (a few cells flip at sector borders) and the
        # nearest of all
        assert dist[i] <= 0.08, (i, dist)
        assert dist[i] == min(dist)


def test_descriptor_shapes_and_parameters(room: World) -> None:
    scan = room.scan((0.0, 0.0, 0.0))
    kps = CornerDetector().detect(scan)
    bsc = describe(scan, kps, DescriptorParams("bsc", n_sectors=16, n_rings=8))
    assert bsc.bits.shape == (len(kps), 2) and bsc.n_bits == 128 and bsc.bits.dtype == np.uint64
    csc = describe(scan, kps, "csc")
    assert csc.values.shape == (len(kps), 12 * 5 + 1)
    # histogram part sums to 1/2 (normalised); the last entry carries the opening angle
    assert np.allclose(csc.values[:, :-1].sum(axis=1), 0.5)
    assert np.allclose(csc.values[:, -1], 0.5 * kps.opening_angle_deg / 180.0)
    with pytest.raises(InvalidParamsError):
        DescriptorParams("nope").resolved()  # type: ignore[arg-type]
    with pytest.raises(InvalidParamsError):
        DescriptorParams("bsc", radius=-1.0).resolved()
