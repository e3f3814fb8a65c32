"""Figures of the accuracy benchmark. Every helper draws into an ``ax`` it is given."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

__all__ = ["plot_accuracy_metric"]

_LABELS = {
    "recall": "recall of visible corners",
    "false_rate": "false keypoints / keypoints",
    "false_per_scan": "false keypoints per scan",
    "median_error_mm": "median localisation error [mm]",
    "p95_error_mm": "p95 localisation error [mm]",
    "keypoints_per_corner": "keypoints per found corner",
}


def plot_accuracy_metric(ax: Any, rows: Sequence[dict[str, Any]], metric: str) -> Any:
    """Draw one metric against the noise sigma, one line per method.

    Parameters
    ----------
    ax : matplotlib.axes.Axes
        Where to draw.
    rows : sequence of dict
        Rows of :meth:`laser_corners.eval.accuracy.AccuracyStats.row`.
    metric : str
        A key of the rows (``recall``, ``false_rate``, ``median_error_mm``...).
    """
    methods = list(dict.fromkeys(r["method"] for r in rows))
    for method in methods:
        mine = [r for r in rows if r["method"] == method]
        ax.plot([1e3 * r["sigma_m"] for r in mine], [r[metric] for r in mine], "o-", label=method)
    ax.set_xlabel("range noise sigma [mm]")
    ax.set_ylabel(_LABELS.get(metric, metric))
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8)
    return ax
