"""Figures of the paper's section III (fig. 1 and fig. 2). Helpers draw into given axes."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import NDArray

from laser_corners.eval.linefit_study import LineFitStudy
from laser_corners.kernel.linefit import Y_ON_X, fit_line, intersect
from laser_corners.scan import LaserScan

__all__ = ["neighbourhoods", "plot_line_fit_study", "plot_neighbourhoods"]


def plot_line_fit_study(ax_rmse: Any, ax_angle: Any, study: LineFitStudy) -> tuple[Any, Any]:
    """Fig. 1: RMSE (top) and line-angle error (bottom) of both models and the selection."""
    a = study.angles_deg
    for ax, series, unit in (
        (ax_rmse, (study.rmse_yx, study.rmse_xy, study.rmse_sel), "mean RMSE [m]"),
        (
            ax_angle,
            (study.angle_err_yx_deg, study.angle_err_xy_deg, study.angle_err_sel_deg),
            "mean |angle error| [deg]",
        ),
    ):
        ax.plot(a, series[0], color="tab:blue", lw=1.2, label="y = b0 + b1 x (eqs. 2-4)")
        ax.plot(a, series[1], color="tab:orange", lw=1.2, label="x = a0 + a1 y (eqs. 5-7)")
        ax.plot(a, series[2], color="k", lw=1.6, ls="--", label="lower-RMSE selection")
        ax.set_yscale("log")
        ax.set_ylabel(unit)
        ax.set_xlim(a[0], a[-1])
        ax.set_xticks(np.arange(-90, 91, 30))
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=8, loc="upper center")
    ax_angle.set_xlabel("line orientation [deg]")
    return ax_rmse, ax_angle


def neighbourhoods(scan: LaserScan, j: int, radius: float) -> tuple[slice, slice]:
    """Arrival and departure neighbourhoods of point ``j`` at scale ``radius`` (slices).

    As in the paper: the runs of consecutive valid points before and after ``j`` up to the
    first point farther than ``radius`` from p_j or a gap, p_j included in both.
    """
    xy, valid = scan.to_cartesian()
    bounds = []
    for step in (-1, 1):
        i = j
        while 0 <= i + step < len(xy) and valid[i + step]:
            if math.hypot(*(xy[i + step] - xy[j])) > radius:
                break
            i += step
        bounds.append(i)
    return slice(bounds[0], j + 1), slice(j, bounds[1] + 1)


def plot_neighbourhoods(
    ax: Any, scan: LaserScan, j: int, radius: float, span: float | None = None
) -> dict[str, Any]:
    """Fig. 2: p_j, its arrival/departure neighbourhoods at ``radius``, the fitted lines and
    their intersection (the scale's candidate keypoint).

    Returns the fits, intersection and opening angle (degrees) that were drawn.
    """
    xy, valid = scan.to_cartesian()
    arrival, departure = neighbourhoods(scan, j, radius)
    span = span if span is not None else 2.5 * radius
    near = valid & (np.hypot(*(xy - xy[j]).T) < span)
    ax.plot(xy[near, 0], xy[near, 1], ".", color="0.6", ms=4, label="scan points")
    pa, pd = xy[arrival], xy[departure]
    ax.plot(
        pa[:, 0],
        pa[:, 1],
        "o",
        ms=5,
        mfc="none",
        color="tab:blue",
        label=f"arrival N_a ({len(pa)} points)",
    )
    ax.plot(
        pd[:, 0],
        pd[:, 1],
        "s",
        ms=5,
        mfc="none",
        color="tab:orange",
        label=f"departure N_d ({len(pd)} points)",
    )
    circle = np.linspace(0, 2 * np.pi, 200)
    ax.plot(
        xy[j, 0] + radius * np.cos(circle),
        xy[j, 1] + radius * np.sin(circle),
        ":",
        color="0.3",
        lw=1,
        label=f"R = {radius:g} m",
    )
    fa, fd = fit_line(pa), fit_line(pd)
    qx, qy, ok = intersect(fa.model, fa.intercept, fa.slope, fd.model, fd.intercept, fd.slope)
    info: dict[str, Any] = {"arrival": fa, "departure": fd, "intersection": None, "opening": None}
    for fit, colour, pts in ((fa, "tab:blue", pa), (fd, "tab:orange", pd)):
        _draw_fit(ax, fit, pts, colour, span if ok else radius, xy[j])
    ax.plot(*xy[j], "D", color="k", ms=7, label="p_j")
    if ok:
        q = np.array([qx, qy])
        ua = _towards(fa, q, pa[0])
        ud = _towards(fd, q, pd[-1])
        opening = math.degrees(math.acos(float(np.clip(ua @ ud, -1.0, 1.0))))
        info.update(intersection=q, opening=opening)
        ax.plot(qx, qy, "X", color="tab:red", ms=12, label=f"intersection ({opening:.1f} deg)")
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=7, loc="best")
    return info


def _direction(fit: Any) -> NDArray[np.float64]:
    d = np.array([1.0, fit.slope]) if fit.model == Y_ON_X else np.array([fit.slope, 1.0])
    return d / np.hypot(*d)


def _towards(fit: Any, origin: NDArray[np.float64], target: NDArray[np.float64]) -> Any:
    d = _direction(fit)
    return d if d @ (target - origin) >= 0 else -d


def _draw_fit(
    ax: Any,
    fit: Any,
    pts: NDArray[np.float64],
    colour: str,
    extent: float,
    centre: NDArray[np.float64],
) -> None:
    d = _direction(fit)
    mean = pts.mean(axis=0)
    # a point of the fitted line near the neighbourhood's centroid
    if fit.model == Y_ON_X:
        base = np.array([mean[0], fit.intercept + fit.slope * mean[0]])
    else:
        base = np.array([fit.intercept + fit.slope * mean[1], mean[1]])
    t0 = (centre - base) @ d
    t = np.array([t0 - extent, t0 + extent])
    ax.plot(
        base[0] + t * d[0],
        base[1] + t * d[1],
        "-",
        color=colour,
        lw=1.5,
        label=f"fit ({'y|x' if fit.model == Y_ON_X else 'x|y'}, RMSE {1e3 * fit.rmse:.1f} mm)",
    )
