"""Presets (:mod:`laser_corners.presets`): the robust parameters follow the range noise, estimated
from the scan when the preset needs one."""

from __future__ import annotations

import numpy as np
import pytest

from laser_corners.errors import InvalidParamsError
from laser_corners.presets import PRESETS, get_preset, robust_params
from laser_corners.sim import corner_scan


def test_robust_params_follow_the_noise() -> None:
    low, high = robust_params(0.0), robust_params(0.03)
    assert low.scales[0] == pytest.approx(0.1) and low.scales[-1] == pytest.approx(0.25)
    assert high.scales[-1] == pytest.approx(0.75)
    assert low.max_fit_rmse == pytest.approx(0.025)
    assert high.max_fit_rmse == pytest.approx(1.75 * 0.03)
    assert high.max_point_distance > low.max_point_distance
    assert low.min_extent_ratio > 0 and low.refine_radius > 0
    with pytest.raises(InvalidParamsError):
        robust_params(-0.01)


def test_robust_preset_estimates_noise_from_the_scan() -> None:
    assert "robust" in PRESETS
    with pytest.raises(InvalidParamsError, match="needs a scan"):
        get_preset("robust")
    noisy = corner_scan(noise_sigma=0.03, rng=np.random.default_rng(0))
    assert get_preset("robust", noisy).scales[-1] == pytest.approx(0.75, rel=0.15)
    assert get_preset("robust", corner_scan()).scales[-1] == pytest.approx(0.25)


def test_presets_docstring_examples() -> None:
    import doctest

    import laser_corners.presets

    result = doctest.testmod(laser_corners.presets, optionflags=doctest.ELLIPSIS)
    assert result.attempted > 0 and result.failed == 0
