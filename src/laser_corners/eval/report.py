"""Write a :class:`~laser_corners.eval.real.RealEvaluation` to a folder: figures, arrays, Markdown.

Files written by :func:`write_real_report` (all in ``output``):

======================================  ======================================================
``report.md``                           Markdown summary linking every figure
``summary.json``                        the numbers of ``report.md``, machine-readable
``params.yaml``                         detector parameters of the maps (``DetectorParams``)
``observability.png`` / ``.npy``        observability ratio per cell (NaN: never in view)
``observability_n8.png`` / ``.npy``     the N8 version
``observability_counts.npz``            ``in_view``, ``hits``, ``in_view_n8``, ``hits_n8``,
                                        and the grid (``x0``, ``y0``, ``resolution``)
``persistent_features.csv``             ``x, y, ratio_n8, in_view_n8`` per feature
``association_matrix.png``              std of the distance of every feature pair
``association_histogram.png``           histogram of those standard deviations
``association_std.npy``                 the matrix (metres, NaN: fewer than 2 scans together)
``association_together.npy``            scans in which each pair was seen together
``repeatability.csv``                   the repeatability table
======================================  ======================================================
"""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path
from typing import Any

import numpy as np

from laser_corners.eval.real import PERSISTENCE_LEVELS, RealEvaluation

__all__ = ["repeatability_rows", "summary", "write_real_report"]


def repeatability_rows(result: RealEvaluation) -> list[dict[str, Any]]:
    """One dict per method: method, keypoints per scan, visible, repeatability per radius."""
    rows = []
    for name, rep in result.repeatability.items():
        row: dict[str, Any] = {
            "method": name,
            "keypoints_per_scan": round(rep.keypoints_per_scan, 3),
            "pairs": rep.n_pairs,
            "visible": rep.n_visible,
        }
        for r, value in zip(rep.radii, rep.repeatability, strict=True):
            row[f"repeatability_r{r:g}"] = None if math.isnan(value) else round(value, 4)
        rows.append(row)
    return rows


def _number(value: float) -> float | None:
    return None if not math.isfinite(value) else round(float(value), 6)


def summary(result: RealEvaluation) -> dict[str, Any]:
    """The report's numbers as a JSON-friendly dict."""
    grid = result.obs.grid
    a = result.association
    return {
        "source": result.source,
        "scans": result.n_scans,
        "scans_with_pose": result.n_scans_with_pose,
        "pose_source": result.pose_source,
        "preset": result.config.preset,
        "overrides": list(result.config.overrides),
        "keypoints_per_scan": round(
            len(result.keypoints_map_xy) / max(result.n_scans_with_pose, 1), 3
        ),
        "grid": {
            "x0": grid.x0,
            "y0": grid.y0,
            "resolution": grid.resolution,
            "rows": grid.shape[0],
            "cols": grid.shape[1],
        },
        "persistent_features": {
            "count": len(result.features),
            "min_ratio": result.config.min_ratio,
            "min_views": result.config.min_views,
            "nms_radius": result.config.nms_radius,
            **{f"n8_at_least_{level:g}": n for level, n in result.persistence_counts().items()},
        },
        "association": {
            "radius": result.config.association_radius,
            "features": a.n_features,
            "pairs": a.n_pairs,
            "pairs_with_std": a.n_pairs_with_std,
            "pairs_never_together": a.n_pairs_never_together,
            "max_std": _number(a.max_std),
            "median_std": _number(a.median_std),
            "threshold": a.threshold,
            "share_std_within_threshold": _number(a.share_std_within),
        },
        "repeatability": {
            "pairs_source": result.pairs_source,
            "pairs": result.n_pairs,
            "radii": list(result.config.radii),
            "rows": repeatability_rows(result),
        },
        "occlusion": result.config.occlusion,
        "max_range": result.config.max_range,
        "notes": result.notes,
        "seconds": {k: round(v, 2) for k, v in result.seconds.items()},
    }


def _percent(value: float | None) -> str:
    return "n/a" if value is None else f"{100.0 * value:.1f} %"


def _markdown(result: RealEvaluation, info: dict[str, Any]) -> str:
    pf = info["persistent_features"]
    asc = info["association"]
    rep = info["repeatability"]
    radii = rep["radii"]
    lines = [
        f"# Real-data evaluation: {result.source}",
        "",
        f"- scans: {info['scans']} ({info['scans_with_pose']} with a pose from "
        f"{info['pose_source']})",
        f"- detector for the maps: preset `{info['preset']}`"
        + (f" with `{' '.join(info['overrides'])}`" if info["overrides"] else "")
        + f" ({info['keypoints_per_scan']} keypoints per scan; parameters in "
        "[params.yaml](params.yaml))",
        f"- grid: {info['grid']['cols']} x {info['grid']['rows']} cells of "
        f"{info['grid']['resolution']:g} m; visibility "
        + (
            "ray-cast against each scan (occlusion on)"
            if info["occlusion"]
            else "field of view and range only"
        )
        + (f", max range {info['max_range']:g} m" if info["max_range"] else ""),
        "",
        "## Observability map",
        "",
        "Ratio of the scans with a keypoint in the cell to the scans that had the cell in view.",
        "",
        "| plain | N8 (cell or its 8 neighbours) |",
        "|---|---|",
        "| ![observability](observability.png) | ![observability N8](observability_n8.png) |",
        "",
        "Arrays: [observability.npy](observability.npy), "
        "[observability_n8.npy](observability_n8.npy), "
        "[observability_counts.npz](observability_counts.npz).",
        "",
        "## Persistent features",
        "",
        f"Peaks of the N8 observability >= {pf['min_ratio']:g} in cells seen by >= "
        f"{pf['min_views']} scans, non-maximum suppression within {pf['nms_radius']:g} m: "
        f"**{pf['count']} features** ([persistent_features.csv](persistent_features.csv)).",
        "",
        "| N8 observability | features |",
        "|---|---|",
    ]
    lines += [f"| >= {100 * level:g} % | {pf[f'n8_at_least_{level:g}']} |"
              for level in PERSISTENCE_LEVELS]  # fmt: skip
    lines += [
        "",
        "## Association distance",
        "",
        f"Keypoints associated to persistent features within {asc['radius']:g} m; for each "
        "pair of features seen in the same scan, the std over time of their distance.",
        "",
        f"- feature pairs: {asc['pairs']}; with a std (seen together in >= 2 scans): "
        f"{asc['pairs_with_std']}; never seen together: {asc['pairs_never_together']}",
        f"- max std: {_mm(asc['max_std'])}; median std: {_mm(asc['median_std'])}",
        f"- pairs with std <= {asc['threshold'] * 1000:g} mm: "
        f"{_percent(asc['share_std_within_threshold'])}",
        "",
        "| matrix | histogram |",
        "|---|---|",
        "| ![association matrix](association_matrix.png) | "
        "![association histogram](association_histogram.png) |",
        "",
        "## Repeatability",
        "",
        f"Pairs: {rep['pairs']} ({rep['pairs_source']}). Share of the keypoints of scan A "
        "visible in scan B that reappear in B within r.",
        "",
        "| method | keypoints / scan | visible | "
        + " | ".join(f"r = {r:g} m" for r in radii)
        + " |",
        "|---|---|---|" + "---|" * len(radii),
    ]
    for row in rep["rows"]:
        values = [_percent(row[f"repeatability_r{r:g}"]) for r in radii]
        lines.append(f"| {row['method']} | {row['keypoints_per_scan']:.2f} | {row['visible']} | "
                     + " | ".join(values) + " |")  # fmt: skip
    lines += ["", "Table: [repeatability.csv](repeatability.csv)."]
    if info["notes"]:
        lines += ["", "## Notes", ""] + [f"- {note}" for note in info["notes"]]
    seconds = ", ".join(f"{k} {v:.1f} s" for k, v in info["seconds"].items())
    lines += ["", f"Run time: {seconds}.", ""]
    return "\n".join(lines)


def _mm(value: float | None) -> str:
    return "n/a" if value is None else f"{value * 1000:.1f} mm"


def write_real_report(result: RealEvaluation, output: Path) -> dict[str, Path]:
    """Write figures, arrays, ``summary.json`` and ``report.md`` into ``output``.

    Returns
    -------
    dict of str to Path
        The files written, by short name.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from laser_corners.viz.evaluation import (
        plot_observability,
        plot_pair_std_histogram,
        plot_pair_std_matrix,
    )

    output = Path(output)
    output.mkdir(parents=True, exist_ok=True)
    obs = result.obs
    grid = obs.grid
    paths: dict[str, Path] = {}

    def save(fig: Any, name: str) -> None:
        path = output / name
        fig.savefig(path, dpi=150, bbox_inches="tight")
        plt.close(fig)
        paths[name] = path

    # --- observability
    width = 10.0
    height = max(3.0, min(12.0, width * grid.shape[0] / max(grid.shape[1], 1) + 1.0))
    for name, ratio, label in (
        ("observability", obs.ratio, "observability"),
        ("observability_n8", obs.ratio_n8, "N8 observability"),
    ):
        np.save(output / f"{name}.npy", ratio)
        paths[f"{name}.npy"] = output / f"{name}.npy"
        fig, ax = plt.subplots(figsize=(width, height))
        image = plot_observability(
            ax, ratio, grid.extent, result.scan_points_map_xy, result.features.xy,
            result.trajectory_xy, title=f"{label}: {result.source}",
        )  # fmt: skip
        fig.colorbar(image, ax=ax, shrink=0.8, label=label)
        save(fig, f"{name}.png")
    np.savez_compressed(
        output / "observability_counts.npz", in_view=obs.in_view, hits=obs.hits,
        in_view_n8=obs.in_view_n8, hits_n8=obs.hits_n8, x0=grid.x0, y0=grid.y0,
        resolution=grid.resolution,
    )  # fmt: skip
    paths["observability_counts.npz"] = output / "observability_counts.npz"

    # --- persistent features
    with (output / "persistent_features.csv").open("w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(["x", "y", "ratio_n8", "in_view_n8"])
        for (x, y), ratio, views in zip(result.features.xy, result.features.ratio_n8,
                                        result.features.in_view_n8, strict=True):  # fmt: skip
            writer.writerow([f"{x:.4f}", f"{y:.4f}", f"{ratio:.4f}", int(views)])
    paths["persistent_features.csv"] = output / "persistent_features.csv"

    # --- association distance
    np.save(output / "association_std.npy", result.pair_std)
    np.save(output / "association_together.npy", result.pair_together)
    paths["association_std.npy"] = output / "association_std.npy"
    paths["association_together.npy"] = output / "association_together.npy"
    fig, ax = plt.subplots(figsize=(7, 6))
    image = plot_pair_std_matrix(ax, result.pair_std)
    fig.colorbar(image, ax=ax, label="std [mm]")
    save(fig, "association_matrix.png")
    fig, ax = plt.subplots(figsize=(7, 4))
    plot_pair_std_histogram(ax, result.pair_std, result.config.std_threshold)
    save(fig, "association_histogram.png")

    # --- tables and summary
    rows = repeatability_rows(result)
    with (output / "repeatability.csv").open("w", newline="") as handle:
        if rows:
            writer = csv.DictWriter(handle, fieldnames=list(rows[0]))
            writer.writeheader()
            writer.writerows(rows)
    paths["repeatability.csv"] = output / "repeatability.csv"
    (output / "params.yaml").write_text(result.params.to_yaml())
    paths["params.yaml"] = output / "params.yaml"
    info = summary(result)
    (output / "summary.json").write_text(json.dumps(info, indent=2) + "\n")
    paths["summary.json"] = output / "summary.json"
    (output / "report.md").write_text(_markdown(result, info))
    paths["report.md"] = output / "report.md"
    return paths
