"""The pictures of a SLAM map folder: ``map.png`` (grid, trajectory, landmarks, loop
closures) and ``report.md`` (the numbers of ``summary.json`` as a page, linking ``map.png``).

The folder itself (trajectories, ``graph.g2o``, ``keyframes.npz``, the grid, ``summary.json``,
``options.yaml``) is written whole by :mod:`laser_corners.registration.mapfolder` from the
plain data :func:`laser_corners.slam.output.map_contents` makes of a result; this module
renders the pictures into it (:func:`slam_pictures`, a
:data:`~laser_corners.registration.mapfolder.Render`), and :func:`write_slam_outputs` writes
a folder with them. A partial result (the run stopped early) says so in ``report.md``.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

from laser_corners.io.base import PartialOutput
from laser_corners.registration.mapfolder import MapContents, Render
from laser_corners.slam.output import SlamRunInfo, write_slam_map
from laser_corners.slam.result import SlamResult
from laser_corners.viz.slam import save_slam_map

__all__ = [
    "RELATION_COLUMNS",
    "ms_text",
    "relation_cells",
    "slam_markdown",
    "slam_pictures",
    "write_slam_outputs",
]

RELATION_COLUMNS = ("covered / total", "|t| (m)", "t² (m²)", "|θ| (deg)", "θ² (deg²)")
"""Headers of the relation-metric table (mean ± std; Kümmerle et al. 2009, as Cartographer's
``compute_relations_metrics`` prints it)."""


def relation_cells(metrics: dict[str, float]) -> list[str]:
    """One row of the relation-metric table (:data:`RELATION_COLUMNS`) from
    ``RelationMetrics.to_dict()``."""

    def pm(key: str, digits: int) -> str:
        mean, std = metrics[key + "_mean"], metrics[key + "_std"]
        if mean is None or not math.isfinite(mean):  # no relation covered
            return "-"
        return f"{mean:.{digits}f} ± {std:.{digits}f}"

    return [
        f"{int(metrics['n_covered'])} / {int(metrics['n_total'])}",
        pm("trans", 4),
        pm("trans2", 5),
        pm("rot_deg", 3),
        pm("rot2", 3),
    ]


def _markdown_table(head: list[str], rows: list[list[str]]) -> list[str]:
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    return lines + ["| " + " | ".join(row) + " |" for row in rows] + [""]


def slam_markdown(summary: dict[str, Any]) -> str:
    """``report.md`` from :func:`slam_summary`'s dictionary."""
    counts, timings, closures = summary["counts"], summary["timings"], summary["closures"]
    lines = [f"# SLAM: {summary['input']}", ""]
    if summary["partial"]:
        lines += [
            f"**Interrupted ({summary['partial_reason']}): these files hold the map up to the "
            "last scan processed, not the whole recording.**",
            "",
        ]
    lines += [f"**Warning: {w}**" for w in summary["warnings"]] + [""] * bool(summary["warnings"])
    rtf = timings["real_time_factor"]
    lines += _markdown_table(
        ["", "value"],
        [
            ["scans", str(counts["scans"])],
            ["keyframes", str(counts["keyframes"])],
            ["landmarks", str(counts["landmarks"])],
            [
                "loop closures proposed / accepted / rejected",
                f"{closures['proposed']} / {closures['accepted']} / {closures['rejected']}",
            ],
            ["data (s) / wall (s)", f"{timings['data_s']:.1f} / {timings['total_s']:.1f}"],
            ["real-time factor", "-" if rtf is None else f"{rtf:.1f}x"],
            ["ms per scan mean / p95 / max", _ms(timings)],
            ["peak memory (MB)", f"{timings['peak_rss_mb']:.0f}"],
            ["base -> laser mount (x, y, yaw)", ", ".join(f"{v:g}" for v in summary["mount"])],
        ],
    )
    consistency = summary["closure_consistency"]
    if consistency is not None:
        lines += [
            f"Accepted loop closures the final map contradicts by more than 0.2 m or 1°: "
            f"{100.0 * consistency:.1f} %.",
            "",
        ]
    if closures["rejected_by_reason"]:
        reasons = ", ".join(f"{n} {r}" for r, n in sorted(closures["rejected_by_reason"].items()))
        lines += [f"Rejected closures by reason: {reasons}.", ""]
    relations = summary["relations"]
    if relations:
        rows = [
            [name, *relation_cells(relations[name])]
            for name in ("trajectory", "odometry")
            if name in relations
        ]
        lines += [
            f"## Relation metric ({relations['file']})",
            "",
            "Mean ± std over the relations whose two stamps the trajectory covers.",
            "",
        ]
        lines += _markdown_table(["", *RELATION_COLUMNS], rows)
    lines += [
        "## Map",
        "",
        "![map](map.png)",
        "",
        "Files: `trajectory.tum` (and `odometry.tum`), `graph.g2o`, `landmarks.csv`, "
        "`map.pgm` + `map.yaml`, `summary.json`, `options.yaml` (the options of this run: "
        "`laser-corners slam --config options.yaml` repeats it).",
        "",
        f"Keypoint detector: {summary['citation']}",
        "",
    ]
    return "\n".join(lines)


def ms_text(values: dict[str, Any], prefix: str = "ms_per_scan", sep: str = " / ") -> str:
    """``mean / p95 / max`` of :func:`ms_statistics` as text (``-`` without scans)."""
    mean, p95, most = (values.get(f"{prefix}_{k}") for k in ("mean", "p95", "max"))
    return "-" if mean is None else sep.join(f"{v:.2f}" for v in (mean, p95, most))


def _ms(timings: dict[str, Any]) -> str:
    return ms_text(timings)


def _write_text(path: Path, text: str) -> Path:
    partial = PartialOutput(path, overwrite=True)
    with partial.writing() as temporary:
        temporary.write_text(text, encoding="utf-8")
    return path


def slam_pictures(result: SlamResult, info: SlamRunInfo) -> Render:
    """The :data:`~laser_corners.registration.mapfolder.Render` of a SLAM result: ``map.png``
    (its grid, trajectory, landmarks, closures) and ``report.md`` (the summary as a page)."""
    title = Path(info.source).name + (" (interrupted)" if result.interrupted else "")

    def render(folder: Path, contents: MapContents) -> dict[str, Path]:
        paths = {"map_png": save_slam_map(folder / "map.png", result, contents.grid, title)}
        paths["report"] = _write_text(folder / "report.md", slam_markdown(contents.summary))
        return paths

    return render


def write_slam_outputs(result: SlamResult, folder: Path, info: SlamRunInfo) -> dict[str, Path]:
    """Write the map folder of ``result`` whole with its pictures
    (:func:`~laser_corners.slam.output.write_slam_map` with :func:`slam_pictures`).

    Returns
    -------
    dict of str to Path
        ``trajectory``, ``odometry``, ``graph``, ``landmarks``, ``keyframes``, ``map_yaml``,
        ``map_pgm``, ``map_png``, ``report``, ``options``, ``summary``.

    Raises
    ------
    OutputError
        The folder is refused or a file cannot be written (``graph.g2o`` excepted: a graph
        the library cannot write is recorded in ``info.warnings``, ``summary.json`` and
        ``report.md``); nothing is changed under ``folder`` then.
    InvalidParamsError
        The grid would be too big at ``info.resolution`` (before anything is written).
    """
    return write_slam_map(result, folder, info, slam_pictures(result, info))
