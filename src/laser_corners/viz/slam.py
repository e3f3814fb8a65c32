"""Figures of a SLAM run: the map (``map.png``) and the cost per scan.

:func:`plot_slam_map` draws, on a given ``ax``, the occupancy grid (black occupied, white free,
grey unknown), the trajectory, the corner landmarks and the loop closures between keyframe
positions (accepted ones as green lines, rejected ones faint red). :func:`save_slam_map`
makes the figure and writes it atomically. A result is read by its fields only (``poses``,
``keyframe_poses``, ``landmarks.xy``, ``closures``), as
:class:`~laser_corners.slam.SlamResult` has them.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.axes import Axes
from matplotlib.collections import LineCollection
from matplotlib.figure import Figure
from numpy.typing import ArrayLike

from laser_corners.io.base import PartialOutput
from laser_corners.io.occupancy import UNKNOWN_PIXEL, OccupancyGrid

__all__ = ["grid_image", "plot_ms_per_scan", "plot_slam_map", "save_figure", "save_slam_map"]


def grid_image(grid: OccupancyGrid) -> np.ndarray:
    """Grey levels in [0, 1] of the grid (row 0 at the bottom): ``1 - P(occupied)`` where known,
    map_saver's unknown grey elsewhere."""
    occupancy = grid.occupancy.astype(np.float64)
    image = 1.0 - occupancy / 100.0
    image[grid.occupancy < 0] = UNKNOWN_PIXEL / 255.0
    return image


def _closure_segments(closures: Sequence[Any], keyframes: np.ndarray, accepted: bool) -> list:
    return [
        [keyframes[c.query, :2], keyframes[c.match, :2]]
        for c in closures
        if bool(c.accepted) == accepted
        and 0 <= c.query < len(keyframes)
        and 0 <= c.match < len(keyframes)
    ]


def plot_slam_map(
    ax: Axes,
    grid: OccupancyGrid | None,
    poses: ArrayLike,
    keyframe_poses: ArrayLike | None = None,
    landmarks: ArrayLike | None = None,
    closures: Sequence[Any] = (),
) -> None:
    """Draw a SLAM map on ``ax``.

    Parameters
    ----------
    ax : Axes
        Where to draw (equal aspect is set).
    grid : OccupancyGrid or None
        The occupancy grid (``None``: no grid).
    poses : array_like, shape (N, 3)
        The trajectory ``x, y, yaw``.
    keyframe_poses : array_like, shape (K, 3), optional
        Keyframe poses: the ends of the loop-closure lines.
    landmarks : array_like, shape (L, 2), optional
        Corner landmarks.
    closures : sequence
        Loop closures with ``query``, ``match`` (keyframe indices) and ``accepted``.
    """
    if grid is not None:
        ax.imshow(
            grid_image(grid),
            cmap="gray",
            vmin=0.0,
            vmax=1.0,
            origin="lower",
            extent=grid.extent,
            interpolation="nearest",
        )
    track = np.asarray(poses, dtype=np.float64).reshape(-1, 3)
    ax.plot(track[:, 0], track[:, 1], color="tab:blue", lw=0.8, label="trajectory")
    if landmarks is not None and len(np.asarray(landmarks)):
        xy = np.asarray(landmarks, dtype=np.float64).reshape(-1, 2)
        ax.scatter(
            xy[:, 0], xy[:, 1], s=4, color="tab:orange", label=f"{len(xy)} landmarks", zorder=3
        )
    if keyframe_poses is not None and len(closures):
        keyframes = np.asarray(keyframe_poses, dtype=np.float64).reshape(-1, 3)
        for accepted, style in (
            (False, {"color": "tab:red", "alpha": 0.15, "lw": 0.5}),
            (True, {"color": "tab:green", "alpha": 0.8, "lw": 0.8}),
        ):
            segments = _closure_segments(closures, keyframes, accepted)
            if segments:
                word = "accepted" if accepted else "rejected"
                label = f"{len(segments)} {word} loop closures"
                ax.add_collection(LineCollection(segments, label=label, zorder=2, **style))
    ax.set_aspect("equal")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.legend(loc="upper right", fontsize="small", framealpha=0.8)


def save_figure(fig: Figure, path: Path, dpi: int = 150) -> Path:
    """Write ``fig`` as a PNG under a temporary name, renamed when complete."""
    partial = PartialOutput(path, overwrite=True)
    with partial.writing() as temporary:
        fig.savefig(temporary, format="png", dpi=dpi, bbox_inches="tight")
    return path


def save_slam_map(
    path: Path, result: Any, grid: OccupancyGrid | None, title: str = "", dpi: int = 150
) -> Path:
    """``map.png`` of a SLAM result (see :func:`plot_slam_map`), written atomically."""
    if grid is not None:
        left, right, bottom, top = grid.extent
        aspect = (top - bottom) / max(right - left, 1e-9)
    else:
        aspect = 1.0
    width = 10.0
    fig = Figure(figsize=(width, float(np.clip(width * aspect, 4.0, 16.0))))
    ax = fig.subplots()
    plot_slam_map(
        ax, grid, result.poses, result.keyframe_poses, result.landmarks.xy, result.closures
    )
    if title:
        ax.set_title(title)
    return save_figure(fig, path, dpi)


def plot_ms_per_scan(ax: Axes, series: dict[str, ArrayLike], window: int = 50) -> None:
    """Milliseconds per scan against scan index, one line per run: the raw values faint, a
    running mean over ``window`` scans drawn over them. The y axis stops at 1.2 x the 99.5th
    percentile, so a few slow scans (the first one loads the compiled kernels) do not flatten
    the rest; the legend says how many scans lie above and the slowest."""
    top = 0.0
    for name, values in series.items():
        ms = np.asarray(values, dtype=np.float64).reshape(-1)
        if not len(ms):
            continue
        limit = 1.2 * float(np.percentile(ms, 99.5))
        top = max(top, limit)
        above = int(np.count_nonzero(ms > limit))
        label = f"{name} (mean {ms.mean():.2f} ms"
        label += f"; {above} above the axis, max {ms.max():.0f} ms)" if above else ")"
        (line,) = ax.plot(np.arange(len(ms)), ms, lw=0.3, alpha=0.35)
        if len(ms) >= window:
            mean = np.convolve(ms, np.ones(window) / window, mode="valid")
            ax.plot(
                np.arange(window - 1, len(ms)), mean, color=line.get_color(), lw=1.2, label=label
            )
        else:
            line.set_label(label)
    ax.set_xlabel("scan index")
    ax.set_ylabel("ms per scan")
    ax.set_ylim(0.0, top if top > 0.0 else None)
    ax.legend(fontsize="small")
