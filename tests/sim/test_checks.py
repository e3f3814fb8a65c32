"""Number checks of the simulator (:mod:`laser_corners.sim.checks`): nonsense numbers are refused
naming the parameter, in every entry point."""

from __future__ import annotations

import math

import numpy as np
import pytest

from laser_corners.errors import InvalidParamsError
from laser_corners.sim import (
    UST_10LX,
    corner_scan,
    rectangular_room,
    trajectory,
)
from laser_corners.sim.export import simulate_sequence


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


def test_checks_docstring_examples() -> None:
    import doctest

    import laser_corners.sim.checks

    result = doctest.testmod(laser_corners.sim.checks, optionflags=doctest.ELLIPSIS)
    assert result.attempted > 0 and result.failed == 0
