"""Figure of the place-recognition evaluation. The helper draws into an ``ax`` it is given."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

__all__ = ["plot_precision_recall"]


def plot_precision_recall(
    ax: Any,
    curves: Mapping[str, Mapping[str, Sequence[float]]],
    default_threshold: int | None = None,
    title: str = "",
) -> Any:
    """Precision against recall over the inlier threshold T, one line per method.

    Parameters
    ----------
    ax : matplotlib.axes.Axes
        Where to draw (the legend goes to its lower left).
    curves : mapping of str to mapping
        Per method, arrays ``min_inliers``, ``precision`` and ``recall`` (as
        :func:`laser_corners.eval.loops.precision_recall` returns); points without detections
        (NaN precision) are left out.
    default_threshold : int, optional
        Mark the point of each line at this threshold.
    title : str
        Axes title.
    """
    for name, curve in curves.items():
        pts = [
            (float(r), float(p), int(t))
            for t, p, r in zip(
                curve["min_inliers"], curve["precision"], curve["recall"], strict=True
            )
            if not math.isnan(float(p))
        ]
        if not pts:
            continue
        (line,) = ax.plot([p[0] for p in pts], [p[1] for p in pts], "o-", ms=3, label=name)
        for r, p, t in pts:
            if t == default_threshold:
                ax.plot([r], [p], "s", ms=8, mfc="none", color=line.get_color())
    ax.set_xlabel("recall (correct / queries with a revisit)")
    ax.set_ylabel("precision (correct / detections)")
    ax.set_ylim(0.0, 1.02)
    ax.set_xlim(left=0.0)
    ax.grid(True, alpha=0.3)
    if default_threshold is not None:
        ax.plot([], [], "s", ms=8, mfc="none", color="k", label=f"T = {default_threshold}")
    ax.legend(fontsize=8, loc="lower left")
    if title:
        ax.set_title(title)
    return ax
