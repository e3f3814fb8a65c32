"""Figures of the real-data evaluation (observability map, association distance).

Every helper draws into an ``ax`` it is given and never creates figures.
"""

from __future__ import annotations

from typing import Any

import matplotlib as mpl
import numpy as np
from numpy.typing import ArrayLike

__all__ = ["plot_observability", "plot_pair_std_histogram", "plot_pair_std_matrix"]


def plot_observability(
    ax: Any,
    ratio: ArrayLike,
    extent: tuple[float, float, float, float],
    scan_points: ArrayLike | None = None,
    features: ArrayLike | None = None,
    trajectory: ArrayLike | None = None,
    title: str = "",
) -> Any:
    """Heat map of an observability ratio over the map, with the map's scan points.

    Parameters
    ----------
    ax : matplotlib.axes.Axes
        Where to draw.
    ratio : array_like, shape (rows, cols)
        Observability per cell in [0, 1]; NaN and 0 cells are left transparent.
    extent : (left, right, bottom, top)
        Map-frame extent of the grid (``Grid.extent``), metres.
    scan_points : array_like, shape (P, 2), optional
        Map-frame scan points drawn in light grey underneath.
    features : array_like, shape (F, 2), optional
        Persistent features, drawn as circles.
    trajectory : array_like, shape (T, 2), optional
        Sensor positions, drawn as a thin line.
    title : str
        Axes title.

    Returns
    -------
    matplotlib.image.AxesImage
        The heat map (for a colour bar).
    """
    r = np.asarray(ratio, dtype=float)
    shown = np.ma.masked_where(~np.isfinite(r) | (r <= 0.0), r)
    _layer(ax, scan_points, ",", color="0.75", zorder=1)
    trajectory_style = {"lw": 0.5, "color": "tab:blue", "alpha": 0.6, "label": "sensor path"}
    _layer(ax, trajectory, "-", zorder=2, **trajectory_style)
    image = ax.imshow(
        shown,
        origin="lower",
        extent=extent,
        cmap="inferno_r",
        vmin=0.0,
        vmax=1.0,
        interpolation="nearest",
        zorder=3,
    )
    feature_style = {"mfc": "none", "mec": "tab:green", "ms": 6, "mew": 1.0}
    _layer(ax, features, "o", zorder=4, label="persistent features", **feature_style)
    _map_axes(ax, extent, title)
    return image


def _layer(ax: Any, xy: ArrayLike | None, fmt: str, **style: Any) -> None:
    """Draw map-frame points (N, 2) with ``ax.plot``; nothing for None or no points."""
    if xy is None:
        return
    pts = np.asarray(xy, dtype=float).reshape(-1, 2)
    if len(pts):
        ax.plot(pts[:, 0], pts[:, 1], fmt, **style)


def _map_axes(ax: Any, extent: tuple[float, float, float, float], title: str) -> None:
    """Limits to the map's extent, equal aspect, metre labels, the title and a legend."""
    ax.set_xlim(extent[0], extent[1])
    ax.set_ylim(extent[2], extent[3])
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    if title:
        ax.set_title(title)
    if ax.get_legend_handles_labels()[0]:
        ax.legend(loc="upper right", fontsize=7)


def plot_pair_std_matrix(ax: Any, pair_std: ArrayLike, title: str = "") -> Any:
    """Matrix of the std of the distance between persistent features (paper fig. 5).

    Parameters
    ----------
    ax : matplotlib.axes.Axes
        Where to draw.
    pair_std : array_like, shape (F, F)
        Standard deviations in metres, NaN for pairs without one (drawn light grey).
    title : str
        Axes title.

    Returns
    -------
    matplotlib.image.AxesImage or None
        The matrix image, in millimetres (for a colour bar); ``None`` without features.
    """
    std_mm = np.asarray(pair_std, dtype=float) * 1000.0
    if std_mm.size == 0:
        ax.text(
            0.5, 0.5, "no persistent features", ha="center", va="center", transform=ax.transAxes
        )
        ax.set_axis_off()
        return None
    cmap = mpl.colormaps["viridis"].with_extremes(bad="0.9")
    finite = std_mm[np.isfinite(std_mm)]
    vmax = float(finite.max()) if finite.size else 1.0
    image = ax.imshow(
        np.ma.masked_invalid(std_mm), cmap=cmap, vmin=0.0, vmax=vmax, interpolation="nearest"
    )
    ax.set_xlabel("feature")
    ax.set_ylabel("feature")
    ax.set_title(title or "std of pair distance [mm] (grey: never seen together)")
    return image


def plot_pair_std_histogram(
    ax: Any, pair_std: ArrayLike, threshold: float | None = 0.03, title: str = ""
) -> Any:
    """Histogram of the pair-distance standard deviations (each pair once), in millimetres.

    Parameters
    ----------
    ax : matplotlib.axes.Axes
        Where to draw.
    pair_std : array_like, shape (F, F)
        Symmetric matrix of standard deviations, metres (NaN: none).
    threshold : float, optional
        Drawn as a dashed vertical line, metres.
    title : str
        Axes title.
    """
    std = np.asarray(pair_std, dtype=float)
    iu = np.triu_indices(std.shape[0], k=1)
    values = std[iu]
    values = values[np.isfinite(values)] * 1000.0
    if values.size:
        ax.hist(values, bins=min(50, max(5, values.size // 5)), color="tab:blue", edgecolor="white")
    if threshold is not None:
        ax.axvline(threshold * 1000.0, ls="--", color="tab:red", label=f"{threshold * 1000:g} mm")
        ax.legend(fontsize=8)
    ax.set_xlabel("std of pair distance [mm]")
    ax.set_ylabel("feature pairs")
    ax.set_title(title or f"{values.size} pairs seen together in >= 2 scans")
    return ax
