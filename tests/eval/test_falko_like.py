"""The FALKO-like baseline detector (:mod:`laser_corners.eval.falko_like`): a corner found, a wall
not, parameters checked."""

from __future__ import annotations

import numpy as np
import pytest

from laser_corners.eval.falko_like import FalkoLikeDetector, FalkoLikeParams
from laser_corners.scan import LaserScan
from laser_corners.sim import corner_scan


def test_falko_finds_the_corner_and_not_a_wall() -> None:
    kps = FalkoLikeDetector().detect(corner_scan())
    assert len(kps) == 1
    assert np.hypot(*(kps.xy[0] - [2.0, 1.0])) < 0.02
    assert 80.0 < kps.opening_angle_deg[0] < 100.0
    straight = LaserScan(2.0 / np.cos(np.linspace(-0.6, 0.6, 200)), -0.6, 1.2 / 199, 0.05, 30.0)
    assert len(FalkoLikeDetector().detect(straight)) == 0


def test_falko_params_validated() -> None:
    from laser_corners.errors import InvalidParamsError

    with pytest.raises(InvalidParamsError, match="side_ratio"):
        FalkoLikeParams(side_ratio=0.5)
