"""Matplotlib figures. Every helper draws into an ``ax`` it is given and never creates figures."""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from laser_corners.keypoints import Keypoints
from laser_corners.scan import LaserScan

__all__ = ["plot_scan"]


def plot_scan(
    ax: Any,
    scan: LaserScan,
    keypoints: Keypoints | None = None,
    candidates: Keypoints | None = None,
    truth: ArrayLike | None = None,
) -> Any:
    """Draw a scan's points, its candidates, keypoints and optional true corners (sensor frame).

    Parameters
    ----------
    ax : matplotlib.axes.Axes
        Where to draw.
    scan : LaserScan
        The scan.
    keypoints, candidates : Keypoints, optional
        Merged keypoints (drawn as red crosses with their bisector) and raw per-point
        candidates (small orange dots).
    truth : array_like, shape (C, 2), optional
        True corners (green circles).
    """
    xy, valid = scan.to_cartesian()
    ax.plot(xy[valid, 0], xy[valid, 1], ".", ms=2, color="0.35", label="scan points")
    ax.plot([0], [0], marker=(3, 0, -90), ms=12, color="tab:blue", ls="none", label="sensor")
    if truth is not None:
        t = np.asarray(truth, dtype=float).reshape(-1, 2)
        ax.plot(
            t[:, 0], t[:, 1], "o", mfc="none", mec="tab:green", ms=12, mew=1.5, label="true corners"
        )
    if candidates is not None and len(candidates):
        ax.plot(
            candidates.xy[:, 0],
            candidates.xy[:, 1],
            ".",
            ms=4,
            color="tab:orange",
            label="candidates",
        )
    if keypoints is not None and len(keypoints):
        ax.plot(
            keypoints.xy[:, 0],
            keypoints.xy[:, 1],
            "x",
            ms=10,
            mew=2,
            color="tab:red",
            label="keypoints",
        )
        u = 0.2 * np.cos(keypoints.orientation)
        v = 0.2 * np.sin(keypoints.orientation)
        ax.quiver(
            keypoints.xy[:, 0],
            keypoints.xy[:, 1],
            u,
            v,
            color="tab:red",
            angles="xy",
            scale_units="xy",
            scale=1,
            width=0.003,
        )
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.legend(loc="best", fontsize=8)
    ax.grid(True, alpha=0.3)
    return ax
