"""The paper's fig. 1 experiment: the two closed-form line models and their selection.

For each line orientation, ``n_samples`` noisy copies of a line of ``n_points`` points are
fitted with y = β0 + β1·x (eqs. 2-4), x = α0 + α1·y (eqs. 5-7) and the lower-RMSE selection
(eqs. 8-9), using the same compiled functions as the detector
(:mod:`laser_corners.kernel.linefit`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba as nb
import numpy as np
from numpy.typing import NDArray

from laser_corners.kernel.linefit import fit_x_on_y, fit_y_on_x

__all__ = ["LineFitStudy", "line_fit_study"]


@dataclass(frozen=True)
class LineFitStudy:
    """Mean RMSE and mean absolute line-angle error per orientation (arrays of shape (A,)).

    ``rmse_*`` in metres (eqs. 8-9: vertical residuals for y|x, horizontal for x|y; the
    selection's is the smaller of the two), ``angle_err_*_deg`` the mean absolute difference
    between the fitted and the true line direction, degrees. ``*_worse`` counts the samples
    where the selection's RMSE exceeds the model's (always 0: the selection is the minimum).
    """

    angles_deg: NDArray[np.float64]
    rmse_yx: NDArray[np.float64]
    rmse_xy: NDArray[np.float64]
    rmse_sel: NDArray[np.float64]
    angle_err_yx_deg: NDArray[np.float64]
    angle_err_xy_deg: NDArray[np.float64]
    angle_err_sel_deg: NDArray[np.float64]
    sel_worse_than_yx: int
    sel_worse_than_xy: int

    def as_table(self) -> dict[str, NDArray[np.float64]]:
        """Columns for a CSV."""
        return {
            "angle_deg": self.angles_deg,
            "rmse_y_on_x_m": self.rmse_yx,
            "rmse_x_on_y_m": self.rmse_xy,
            "rmse_selected_m": self.rmse_sel,
            "angle_err_y_on_x_deg": self.angle_err_yx_deg,
            "angle_err_x_on_y_deg": self.angle_err_xy_deg,
            "angle_err_selected_deg": self.angle_err_sel_deg,
        }


@nb.njit(cache=True)
def _undirected_error(fitted: float, true: float) -> float:
    """Absolute angle between two undirected lines, radians, in [0, pi/2]."""
    d = 2.0 * (fitted - true)
    return abs(math.atan2(math.sin(d), math.cos(d))) / 2.0


@nb.njit(cache=True)
def _study(
    angles: NDArray[np.float64], along: NDArray[np.float64], noise: NDArray[np.float64]
) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    n_angles = angles.shape[0]
    n_samples = noise.shape[1]
    n_points = along.shape[0]
    out = np.zeros((n_angles, 6))
    worse = np.zeros(2, dtype=np.int64)
    for a in range(n_angles):
        c = math.cos(angles[a])
        s = math.sin(angles[a])
        for m in range(n_samples):
            sx = sy = sxx = syy = sxy = 0.0
            for i in range(n_points):
                x = along[i] * c + noise[a, m, i, 0]
                y = along[i] * s + noise[a, m, i, 1]
                sx += x
                sy += y
                sxx += x * x
                syy += y * y
                sxy += x * y
            n = float(n_points)
            _, b1, r_yx = fit_y_on_x(n, sx, sy, sxx, syy, sxy)
            _, a1, r_xy = fit_x_on_y(n, sx, sy, sxx, syy, sxy)
            # fitted directions: (1, b1) and (a1, 1)
            e_yx = _undirected_error(math.atan2(b1, 1.0), angles[a])
            e_xy = _undirected_error(math.atan2(1.0, a1), angles[a])
            if math.isnan(e_yx):
                e_yx = math.pi / 2
            if math.isnan(e_xy):
                e_xy = math.pi / 2
            sel_is_yx = r_yx <= r_xy
            r_sel = r_yx if sel_is_yx else r_xy
            out[a, 0] += r_yx
            out[a, 1] += r_xy
            out[a, 2] += r_sel
            out[a, 3] += e_yx
            out[a, 4] += e_xy
            out[a, 5] += e_yx if sel_is_yx else e_xy
            worse[0] += r_sel > r_yx
            worse[1] += r_sel > r_xy
    return out / n_samples, worse


def line_fit_study(
    angles_deg: NDArray[np.float64] | None = None,
    n_points: int = 100,
    sigma: float = 0.03,
    n_samples: int = 1000,
    length: float = 1.0,
    seed: int = 0,
) -> LineFitStudy:
    """Run the fig. 1 experiment.

    Parameters
    ----------
    angles_deg : array_like, optional
        Line orientations, degrees (default -90..90 step 0.25, as in the paper).
    n_points : int
        Points per line, evenly spaced over ``length`` metres, centred on the origin.
    sigma : float
        Standard deviation of the Gaussian noise added to x and to y, metres.
    n_samples : int
        Noisy lines per orientation.
    length : float
        Length of the line, metres.
    seed : int
        Random seed.
    """
    if angles_deg is None:
        angles_deg = np.arange(-90.0, 90.0 + 1e-9, 0.25)
    angles_deg = np.asarray(angles_deg, dtype=np.float64)
    rng = np.random.default_rng(seed)
    along = np.linspace(-length / 2, length / 2, n_points)
    mean = np.zeros((len(angles_deg), 6))
    worse = np.zeros(2, dtype=np.int64)
    for chunk in np.array_split(np.arange(len(angles_deg)), max(1, len(angles_deg) // 50)):
        noise = rng.normal(0.0, sigma, size=(len(chunk), n_samples, n_points, 2))
        m, w = _study(np.radians(angles_deg[chunk]), along, noise)
        mean[chunk] = m
        worse += w
    return LineFitStudy(
        angles_deg,
        mean[:, 0],
        mean[:, 1],
        mean[:, 2],
        np.degrees(mean[:, 3]),
        np.degrees(mean[:, 4]),
        np.degrees(mean[:, 5]),
        int(worse[0]),
        int(worse[1]),
    )
