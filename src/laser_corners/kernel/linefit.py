"""Closed-form line fits, model selection and line intersection (paper eqs. 2-13).

Two models are fitted to every neighbourhood:

* ``Y_ON_X``: y = β0 + β1·x  (eqs. 2-4), RMSE of the vertical residuals (eq. 8);
* ``X_ON_Y``: x = α0 + α1·y  (eqs. 5-7), RMSE of the horizontal residuals (eq. 9);

the one with the lower RMSE is kept, and two kept lines are intersected with the case of
eqs. 10-13 that matches their models. Everything is computed from the sufficient statistics
``n, Σx, Σy, Σx², Σy², Σxy`` so that the detector can take them from prefix sums in O(1).

The functions are compiled with numba (``cache=True``) and callable from plain Python.
A model whose independent variable has zero variance (e.g. ``Y_ON_X`` on a vertical line) has
an infinite RMSE and is never selected; two parallel lines have no intersection.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np
from numpy.typing import ArrayLike

__all__ = [
    "INVALID",
    "X_ON_Y",
    "Y_ON_X",
    "LineFit",
    "centred_moments",
    "fit_from_sums",
    "fit_line",
    "fit_x_on_y",
    "fit_y_on_x",
    "intersect",
    "line_direction",
    "select_from_sums",
]

INVALID = -1
"""Model code: no line could be fitted (fewer than two distinct points)."""
Y_ON_X = 0
"""Model code of y = β0 + β1·x (eqs. 2-4)."""
X_ON_Y = 1
"""Model code of x = α0 + α1·y (eqs. 5-7)."""


@nb.njit(cache=True, error_model="numpy")
def fit_y_on_x(
    n: float, sx: float, sy: float, sxx: float, syy: float, sxy: float
) -> tuple[float, float, float]:
    """Least-squares y = β0 + β1·x from sums; returns ``(β0, β1, rmse)``.

    ``rmse`` is ``inf`` when the x values have no spread.
    """
    # centred second moments: n·Sxx - (Sx)^2 = n·Σ(x - x̄)^2, used by eq. 3
    dxx = sxx - sx * sx / n
    dxy = sxy - sx * sy / n
    dyy = syy - sy * sy / n
    if not dxx > 0.0:
        return math.nan, math.nan, math.inf
    beta1 = dxy / dxx  # eq. 3
    beta0 = (sy - beta1 * sx) / n  # eq. 4
    # eq. 8: Σ(y - β0 - β1 x)^2 = Σ(y-ȳ)^2 - β1 Σ(x-x̄)(y-ȳ)
    sse = dyy - beta1 * dxy
    if sse < 0.0:
        sse = 0.0
    return beta0, beta1, math.sqrt(sse / n)


@nb.njit(cache=True, error_model="numpy")
def fit_x_on_y(
    n: float, sx: float, sy: float, sxx: float, syy: float, sxy: float
) -> tuple[float, float, float]:
    """Least-squares x = α0 + α1·y from sums; returns ``(α0, α1, rmse)`` (eqs. 5-7, 9)."""
    alpha0, alpha1, rmse = fit_y_on_x(n, sy, sx, syy, sxx, sxy)  # roles of x and y swapped
    return alpha0, alpha1, rmse


@nb.njit(cache=True, error_model="numpy", inline="always")
def centred_moments(
    inv_n: float, sx: float, sy: float, sxx: float, syy: float, sxy: float
) -> tuple[float, float, float]:
    """Centred second moments Σ(x-x̄)², Σ(y-ȳ)², Σ(x-x̄)(y-ȳ) from raw sums (``inv_n`` = 1/n).

    They are n times the denominators and numerators of eqs. 3 and 6.
    """
    return sxx - sx * sx * inv_n, syy - sy * sy * inv_n, sxy - sx * sy * inv_n


@nb.njit(cache=True, error_model="numpy")
def select_from_sums(
    n: float, sx: float, sy: float, sxx: float, syy: float, sxy: float
) -> tuple[int, float, float, float]:
    """Like :func:`fit_from_sums` but returns the kept model's mean squared residual.

    With the centred moments Sxx = Σ(x-x̄)², Syy = Σ(y-ȳ)², Sxy = Σ(x-x̄)(y-ȳ) and
    D = Sxx·Syy - Sxy², the residual sums of eqs. 8-9 are D/Sxx (y|x) and D/Syy (x|y), so
    the lower-RMSE model is y|x exactly when Sxx > Syy, and x|y when Sxx < Syy. When D = 0
    (collinear points) both RMSEs are zero and the models describe the same line; then, and
    when Sxx = Syy, the model of the larger-or-equal spread is kept (y|x on equality).
    The detector compares the returned RMSE² with the squared threshold (no square root).
    """
    inv_n = 1.0 / n
    dxx, dyy, dxy = centred_moments(inv_n, sx, sy, sxx, syy, sxy)
    det = max(dxx * dyy - dxy * dxy, 0.0)  # >= 0; rounding on collinear points
    # written with selects, not branches, so the detector's loop over points stays branch-free
    y_on_x = dxx >= dyy
    spread = dxx if y_on_x else dyy
    slope = dxy / spread  # eq. 3 (y|x) or eq. 6 (x|y)
    intercept = ((sy - slope * sx) if y_on_x else (sx - slope * sy)) * inv_n  # eq. 4 / eq. 7
    mse = det / spread * inv_n  # eq. 8 / eq. 9, squared
    model = Y_ON_X if y_on_x else X_ON_Y
    degenerate = not spread > 0.0  # all points coincide (or fewer than two)
    return (
        INVALID if degenerate else model,
        math.nan if degenerate else intercept,
        math.nan if degenerate else slope,
        math.inf if degenerate else mse,
    )


@nb.njit(cache=True, error_model="numpy")
def fit_from_sums(
    n: float, sx: float, sy: float, sxx: float, syy: float, sxy: float
) -> tuple[int, float, float, float]:
    """Fit both models and keep the one with the lower RMSE (eqs. 8-9).

    Returns
    -------
    model : int
        ``Y_ON_X``, ``X_ON_Y`` or ``INVALID``.
    c0, c1 : float
        Intercept and slope of the kept model.
    rmse : float
        Its RMSE (``inf`` when ``INVALID``).
    """
    model, c0, c1, mse = select_from_sums(n, sx, sy, sxx, syy, sxy)
    return model, c0, c1, math.sqrt(mse)


@nb.njit(cache=True, error_model="numpy", inline="always")
def intersect(
    model_a: int, a0: float, a1: float, model_b: int, b0: float, b1: float
) -> tuple[float, float, bool]:
    """Intersection of two fitted lines with the case of eqs. 10-13 matching their models.

    Returns ``(x, y, ok)``; ``ok`` is False for parallel lines or an invalid model.
    """
    if model_a == INVALID or model_b == INVALID:
        return math.nan, math.nan, False
    if model_a == Y_ON_X and model_b == Y_ON_X:
        # eq. 10: a0 + a1 x = b0 + b1 x
        den = a1 - b1
        if den == 0.0:
            return math.nan, math.nan, False
        x = (b0 - a0) / den
        return x, a0 + a1 * x, True
    if model_a == X_ON_Y and model_b == X_ON_Y:
        # eq. 11: a0 + a1 y = b0 + b1 y
        den = a1 - b1
        if den == 0.0:
            return math.nan, math.nan, False
        y = (b0 - a0) / den
        return a0 + a1 * y, y, True
    if model_a == Y_ON_X:
        # eq. 12: y = a0 + a1 x and x = b0 + b1 y
        den = 1.0 - a1 * b1
        if den == 0.0:
            return math.nan, math.nan, False
        x = (b0 + b1 * a0) / den
        return x, a0 + a1 * x, True
    # eq. 13: x = a0 + a1 y and y = b0 + b1 x
    den = 1.0 - a1 * b1
    if den == 0.0:
        return math.nan, math.nan, False
    y = (b0 + b1 * a0) / den
    return a0 + a1 * y, y, True


@nb.njit(cache=True, error_model="numpy", inline="always")
def line_direction(model: int, c1: float) -> tuple[float, float]:
    """Unit direction vector of a fitted line (sign arbitrary)."""
    if model == Y_ON_X:
        norm = math.sqrt(1.0 + c1 * c1)
        return 1.0 / norm, c1 / norm
    norm = math.sqrt(1.0 + c1 * c1)
    return c1 / norm, 1.0 / norm


class LineFit:
    """A fitted line, as returned by :func:`fit_line`.

    Attributes
    ----------
    model : int
        ``Y_ON_X`` or ``X_ON_Y`` (``INVALID`` when fewer than two distinct points).
    intercept, slope : float
        β0, β1 for ``Y_ON_X``; α0, α1 for ``X_ON_Y``.
    rmse : float
        RMSE of the kept model (eqs. 8-9).
    n : int
        Number of points fitted.
    """

    __slots__ = ("intercept", "model", "n", "rmse", "slope")

    def __init__(self, model: int, intercept: float, slope: float, rmse: float, n: int) -> None:
        self.model = model
        self.intercept = intercept
        self.slope = slope
        self.rmse = rmse
        self.n = n

    def __repr__(self) -> str:
        name = {Y_ON_X: "y|x", X_ON_Y: "x|y"}.get(self.model, "invalid")
        return (
            f"LineFit({name}, intercept={self.intercept:.6g}, slope={self.slope:.6g}, "
            f"rmse={self.rmse:.3g}, n={self.n})"
        )

    def intersect(self, other: LineFit) -> tuple[float, float] | None:
        """Intersection with another fitted line (eqs. 10-13), or None if parallel/invalid."""
        x, y, ok = intersect(
            self.model, self.intercept, self.slope, other.model, other.intercept, other.slope
        )
        return (x, y) if ok else None

    @property
    def direction(self) -> tuple[float, float]:
        """Unit direction vector (sign arbitrary)."""
        if self.model == INVALID:
            return (math.nan, math.nan)
        return line_direction(self.model, self.slope)


def fit_line(points: ArrayLike) -> LineFit:
    """Fit both closed-form models to ``points`` (shape (n, 2)) and keep the lower-RMSE one.

    Examples
    --------
    >>> fit = fit_line([[0.0, 1.0], [1.0, 1.5], [2.0, 2.0], [3.0, 2.6]])
    >>> fit.model == Y_ON_X, round(fit.slope, 2), round(fit.intercept, 2)
    (True, 0.53, 0.98)
    >>> fit_line([[1.0, 0.0], [1.1, 1.0], [0.9, 2.0]]).model == X_ON_Y
    True
    """
    pts = np.asarray(points, dtype=np.float64)
    if pts.ndim != 2 or pts.shape[1] != 2:
        raise ValueError(f"points must have shape (n, 2), got {pts.shape}")
    n = pts.shape[0]
    if n < 2:
        return LineFit(INVALID, math.nan, math.nan, math.inf, n)
    # centre first for accuracy; shift the intercept back afterwards
    mx, my = pts.mean(axis=0)
    x = pts[:, 0] - mx
    y = pts[:, 1] - my
    model, c0, c1, rmse = fit_from_sums(
        float(n), x.sum(), y.sum(), (x * x).sum(), (y * y).sum(), (x * y).sum()
    )
    if model == Y_ON_X:
        c0 = c0 + my - c1 * mx
    elif model == X_ON_Y:
        c0 = c0 + mx - c1 * my
    return LineFit(int(model), float(c0), float(c1), float(rmse), n)
