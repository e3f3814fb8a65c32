"""The line fit of the kernel (:mod:`laser_corners.kernel.linefit`): the model follows the line's
direction; degenerate fits have no intersection."""

from __future__ import annotations

import math

import pytest

from laser_corners.kernel.linefit import X_ON_Y, Y_ON_X, fit_line


def test_line_fit_models_and_degenerate_cases() -> None:
    horizontal = fit_line([[0, 1], [1, 1.01], [2, 0.99], [3, 1.0]])
    vertical = fit_line([[2, 0], [2.01, 1], [1.99, 2], [2, 3]])
    assert horizontal.model == Y_ON_X and vertical.model == X_ON_Y
    assert horizontal.intersect(vertical) == pytest.approx((2.0, 1.0), abs=0.02)
    exactly_vertical = fit_line([[1, 0], [1, 1], [1, 2]])
    assert exactly_vertical.model == X_ON_Y and exactly_vertical.rmse == 0.0
    parallel = fit_line([[0, 2], [1, 2], [2, 2]])
    assert fit_line([[0, 0], [1, 0], [2, 0]]).intersect(parallel) is None
    single = fit_line([[1, 1], [1, 1]])
    assert single.rmse == math.inf and single.intersect(horizontal) is None
