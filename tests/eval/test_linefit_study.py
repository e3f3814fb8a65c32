"""The line-fit study (:mod:`laser_corners.eval.linefit_study`): choosing the fit by the line's
direction is never worse than either fixed fit."""

from __future__ import annotations

import numpy as np
import pytest

from laser_corners.eval.linefit_study import line_fit_study


def test_line_fit_study_selection_never_worse() -> None:
    study = line_fit_study(np.array([-90.0, -45.0, 0.0, 30.0, 89.0]), n_samples=100, seed=1)
    assert study.sel_worse_than_yx == 0 and study.sel_worse_than_xy == 0
    assert np.all(study.rmse_sel <= np.minimum(study.rmse_yx, study.rmse_xy) + 1e-15)
    # horizontal line: y|x fits with residual ~ sigma, x|y breaks down (and vice versa)
    assert study.rmse_yx[2] == pytest.approx(0.03, rel=0.1)
    assert study.rmse_xy[2] > 0.1 and study.rmse_yx[0] > 0.1
    assert study.angle_err_xy_deg[2] > 10 * study.angle_err_yx_deg[2]
    assert np.all(study.angle_err_sel_deg < 2.0)
