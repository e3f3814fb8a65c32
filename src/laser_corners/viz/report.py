"""Report folders of ``evaluate sim`` and ``evaluate real``: tables, arrays and their figures.

:func:`write_accuracy_report` writes ``accuracy.csv``, ``accuracy.md`` and ``accuracy.png``.
:func:`write_real_report` writes, for a :class:`~laser_corners.eval.real.RealEvaluation`:

======================================  ======================================================
``report.md``                           Markdown summary linking every figure
``summary.json``                        the numbers of ``report.md``, machine-readable
``params.yaml``                         detector parameters of the maps (``DetectorParams``)
``observability.png``                   observability ratio per cell
``observability_n8.png``                the N8 version
``observability.npz``                   ``ratio``, ``ratio_n8`` (float32, NaN: never in view;
                                        row 0 = lowest y), compressed
``observability_counts.npz``            ``in_view``, ``hits``, ``in_view_n8``, ``hits_n8``,
                                        and the grid (``x0``, ``y0``, ``resolution``)
``persistent_features.csv``             ``x, y, ratio_n8, in_view_n8`` per feature
``association_matrix.png``              std of the distance of every feature pair
``association_histogram.png``           histogram of those standard deviations
``association.npz``                     ``std`` (float32, metres, NaN: fewer than 2 scans
                                        together) and ``together`` (scans seen together)
``repeatability.csv``                   the repeatability table
======================================  ======================================================

Every array is written compressed; the grid behind them is bounded by
:attr:`~laser_corners.eval.real_config.RealEvalConfig.max_cells` and the features by
``max_features``, so the folder stays small whatever the recording.
"""

from __future__ import annotations

import csv
import json
from collections.abc import Sequence
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from laser_corners.eval.accuracy import AccuracyStats, write_tables
from laser_corners.eval.real import RealEvaluation
from laser_corners.eval.real_summary import repeatability_rows, summary
from laser_corners.viz.accuracy import plot_accuracy_metric
from laser_corners.viz.evaluation import (
    plot_observability,
    plot_pair_std_histogram,
    plot_pair_std_matrix,
)
from laser_corners.viz.markdown import real_markdown

__all__ = ["write_accuracy_report", "write_real_report"]


def write_accuracy_report(stats: Sequence[AccuracyStats], output: Path) -> dict[str, Path]:
    """Write ``accuracy.csv``, ``accuracy.md`` and ``accuracy.png`` into ``output``."""
    paths = write_tables(stats, output)
    rows = [s.row() for s in stats]
    fig = Figure(figsize=(10, 7.5))
    axes = fig.subplots(2, 2)
    for ax, metric in zip(
        axes.ravel(),
        ("recall", "false_rate", "median_error_mm", "keypoints_per_corner"),
        strict=True,
    ):
        plot_accuracy_metric(ax, rows, metric)
    fig.tight_layout()
    paths["plot"] = output / "accuracy.png"
    fig.savefig(paths["plot"], dpi=110)
    return paths


class _Folder:
    """Writes files into one folder and remembers them by name."""

    def __init__(self, output: Path) -> None:
        self.output = Path(output)
        self.output.mkdir(parents=True, exist_ok=True)
        self.paths: dict[str, Path] = {}

    def path(self, name: str) -> Path:
        self.paths[name] = self.output / name
        return self.paths[name]

    def figure(self, fig: Figure, name: str) -> None:
        fig.savefig(self.path(name), dpi=150, bbox_inches="tight")

    def text(self, name: str, text: str) -> None:
        self.path(name).write_text(text)


def _observability(result: RealEvaluation, out: _Folder) -> None:
    obs = result.obs
    grid = obs.grid
    width = 10.0
    height = max(3.0, min(12.0, width * grid.shape[0] / max(grid.shape[1], 1) + 1.0))
    for name, ratio, label in (
        ("observability", obs.ratio, "observability"),
        ("observability_n8", obs.ratio_n8, "N8 observability"),
    ):
        fig = Figure(figsize=(width, height))
        ax = fig.subplots()
        image = plot_observability(
            ax,
            ratio,
            grid.extent,
            result.scan_points_map_xy,
            result.features.xy,
            result.trajectory_xy,
            title=f"{label}: {result.source}",
        )
        fig.colorbar(image, ax=ax, shrink=0.8, label=label)
        out.figure(fig, f"{name}.png")
    np.savez_compressed(
        out.path("observability.npz"),
        ratio=obs.ratio.astype(np.float32),
        ratio_n8=obs.ratio_n8.astype(np.float32),
    )
    np.savez_compressed(
        out.path("observability_counts.npz"),
        in_view=obs.in_view,
        hits=obs.hits,
        in_view_n8=obs.in_view_n8,
        hits_n8=obs.hits_n8,
        x0=grid.x0,
        y0=grid.y0,
        resolution=grid.resolution,
    )


def _features_and_association(result: RealEvaluation, out: _Folder) -> None:
    f = result.features
    with out.path("persistent_features.csv").open("w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(["x", "y", "ratio_n8", "in_view_n8"])
        for (x, y), ratio, views in zip(f.xy, f.ratio_n8, f.in_view_n8, strict=True):
            writer.writerow([f"{x:.4f}", f"{y:.4f}", f"{ratio:.4f}", int(views)])
    np.savez_compressed(
        out.path("association.npz"),
        std=result.pair_std.astype(np.float32),
        together=result.pair_together.astype(np.int32),
    )
    fig = Figure(figsize=(7, 6))
    ax = fig.subplots()
    image = plot_pair_std_matrix(ax, result.pair_std)
    if image is not None:
        fig.colorbar(image, ax=ax, label="std [mm]")
    out.figure(fig, "association_matrix.png")
    fig = Figure(figsize=(7, 4))
    ax = fig.subplots()
    plot_pair_std_histogram(ax, result.pair_std, result.config.std_threshold)
    out.figure(fig, "association_histogram.png")


def write_real_report(result: RealEvaluation, output: Path) -> dict[str, Path]:
    """Write figures, compressed arrays, ``summary.json`` and ``report.md`` into ``output``.

    Returns
    -------
    dict of str to Path
        The files written, by file name.
    """
    out = _Folder(output)
    _observability(result, out)
    _features_and_association(result, out)
    rows = repeatability_rows(result)
    with out.path("repeatability.csv").open("w", newline="") as handle:
        if rows:
            writer = csv.DictWriter(handle, fieldnames=list(rows[0]))
            writer.writeheader()
            writer.writerows(rows)
    out.text("params.yaml", result.params.to_yaml())
    info = summary(result)
    out.text("summary.json", json.dumps(info, indent=2) + "\n")
    out.text("report.md", real_markdown(result, info))
    return out.paths
