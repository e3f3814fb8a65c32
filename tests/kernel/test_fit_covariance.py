"""Line-fit covariances of the kernel (:mod:`laser_corners.kernel.fit_covariance`) against
numpy's least squares: the kept model and its residual variance (eqs. 2-9), and the textbook
covariance of a line's intercept and slope."""

from __future__ import annotations

import numpy as np
import pytest

from laser_corners.kernel.fit_covariance import centred_sums, fit_terms, line_fit_covariance


def sums(x: np.ndarray, y: np.ndarray) -> tuple[float, ...]:
    return len(x), x.sum(), y.sum(), (x * x).sum(), (y * y).sum(), (x * y).sum()


@pytest.mark.parametrize("steep", [False, True])
def test_fit_terms_are_numpys_least_squares_of_the_kept_model(steep: bool) -> None:
    rng = np.random.default_rng(5)
    v = np.linspace(0.0, 2.0, 25)
    u = 0.3 + 0.4 * v + rng.normal(0.0, 0.01, v.size)
    x, y = (u, v) if steep else (v, u)  # a steep line is fitted as x on y
    y_on_x, c0, c1, s2, v_mean, s_vv, n = fit_terms(*sums(x, y))
    assert y_on_x is (not steep) and n == 25
    (slope, intercept), residuals, *_ = np.polyfit(v, u, 1, full=True)
    assert (c0, c1) == pytest.approx((intercept, slope), rel=1e-9)
    assert s2 == pytest.approx(residuals[0] / (25 - 2), rel=1e-6)
    assert v_mean == pytest.approx(v.mean()) and s_vv == pytest.approx(((v - v.mean()) ** 2).sum())


def test_line_fit_covariance_is_the_textbook_one() -> None:
    v = np.array([0.0, 1.0, 2.0, 3.0, 4.0])
    s2 = 0.04
    design = np.column_stack([np.ones_like(v), v])
    expected = s2 * np.linalg.inv(design.T @ design)  # cov of (c0, c1)
    var_c0, cov_01, var_c1 = line_fit_covariance(5.0, v.mean(), ((v - v.mean()) ** 2).sum(), s2)
    np.testing.assert_allclose([var_c0, cov_01, var_c1], expected[[0, 0, 1], [0, 1, 1]])


def test_two_points_have_no_residual_variance() -> None:
    x, y = np.array([0.0, 1.0]), np.array([0.0, 1.0])
    assert fit_terms(*sums(x, y))[3] == 0.0


def test_centred_sums_skip_dropped_beams_and_shift_the_origin() -> None:
    x = np.array([1.0, np.nan, np.nan, 4.0, 100.0])  # a dropped beam is NaN in x and y
    y = np.array([2.0, np.nan, np.nan, 1.0, 100.0])
    n, sx, sy, sxx, syy, sxy = centred_sums(x, y, 0, 3, 1.0, 1.0)
    # kept: (1, 2), (4, 1) relative to (1, 1): (0, 1), (3, 0); index 4 is beyond hi
    assert (n, sx, sy, sxx, syy, sxy) == (2.0, 3.0, 1.0, 9.0, 1.0, 0.0)
