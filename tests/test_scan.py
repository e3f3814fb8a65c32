"""LaserScan (:mod:`laser_corners.scan`): validation naming the field, gaps, conversion."""

from __future__ import annotations

import math

import numpy as np
import pytest

from laser_corners import LaserScan


def make(**kw):
    fields = dict(
        ranges=[1.0, 2.0, 3.0], angle_min=0.0, angle_increment=0.1, range_min=0.06, range_max=10.0
    )
    fields.update(kw)
    return LaserScan(**fields)


@pytest.mark.parametrize(
    ("field", "value", "message"),
    [
        ("angle_min", math.nan, "angle_min must be finite"),
        ("angle_increment", math.inf, "angle_increment must be finite"),
        ("angle_increment", 0.0, "angle_increment must be non-zero"),
        ("range_min", 10.0, "range_min .* must be < range_max"),
        ("ranges", np.ones((2, 3)), "ranges must be 1-D"),
        ("ranges", ["a", "b"], "ranges must be numeric"),
        ("range_min", -1.0, "range_min must be a finite number >= 0"),
        ("ranges", np.ones(1081), r"angle_increment \(0.1 rad\) with 1081 beams spans"),
    ],
)
def test_scan_validation_names_the_field(field, value, message) -> None:
    with pytest.raises(ValueError, match=message):
        make(**{field: value})


def test_full_turn_and_clockwise_scans_are_accepted() -> None:
    n = 1440
    full = make(ranges=np.ones(n), angle_min=-math.pi, angle_increment=2 * math.pi / (n - 1))
    assert full.n_beams == n
    clockwise = make(ranges=np.ones(5), angle_increment=-0.1)
    assert clockwise.angles[-1] == pytest.approx(-0.4)
    with pytest.raises(ValueError, match="angle_increment"):
        make(ranges=np.ones(1081), angle_increment=-1.0)


def test_gaps_are_counted_never_errors() -> None:
    scan = make(ranges=[np.nan, np.inf, 0.06, 0.05, 10.0, 11.0, 1.0, -np.inf])
    assert scan.n_gaps == 7
    assert scan.valid.tolist() == [False] * 6 + [True, False]
    xy, valid = scan.to_cartesian()
    assert np.isnan(xy[~valid]).all()
    assert np.allclose(xy[6], [math.cos(0.6), math.sin(0.6)])


def test_cartesian_in_angular_order() -> None:
    scan = make(ranges=[1.0, 1.0, 1.0], angle_min=-0.5, angle_increment=0.5)
    xy, _ = scan.to_cartesian()
    assert np.allclose(
        xy, [[math.cos(-0.5), math.sin(-0.5)], [1, 0], [math.cos(0.5), math.sin(0.5)]]
    )
    assert not scan.ranges.flags.writeable
