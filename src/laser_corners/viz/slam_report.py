"""The output folder of ``laser-corners slam``: every file of a SLAM result.

=================  ===========================================================================
``trajectory.tum`` one line per scan: the pose of the odometry's child frame (``base``) in the
                   map frame, TUM ``stamp x y z qx qy qz qw`` (evo reads it)
``odometry.tum``   the odometry at the same stamps, same format (``evaluate slam --odometry``)
``graph.g2o``      the pose graph (``SlamResult.write_g2o``)
``landmarks.csv``  ``x, y, cov_xx, cov_xy, cov_yy, observations, first_stamp, last_stamp``
``keyframes.npz`` keyframe poses and scan points, what ``localise`` reads
                   (:mod:`laser_corners.registration.mapfolder`)
``map.pgm``        occupancy grid, ROS map_server format (see :mod:`laser_corners.io.occupancy`)
``map.yaml``       its map_server metadata
``map.png``        grid, trajectory, landmarks, loop closures
``summary.json``   counts, timings, options, relation metrics, closure consistency, citation
``options.yaml``   the SLAM options of the run (``laser-corners slam --config`` reads it)
``report.md``      the same numbers as a page, linking ``map.png``
=================  ===========================================================================

The folder is written whole: every file into a new folder beside it
(``.NAME.XXXXXXXX.partial``), which then replaces the folder in one step
(:func:`~laser_corners.io.partial.publish_folder`), so a run killed while writing leaves the
previous result (or none) under the final name, never a mix of two runs or a truncated file.
A folder holding files that are not a slam result is refused (:func:`check_slam_folder`): they
would be lost. A partial result (the run stopped early) says so in ``summary.json``
(``"partial": true``, ``"partial_reason"``) and ``report.md``. The numbers measured around
the run (wall time, peak memory, relation metrics) come in a :class:`SlamRunInfo`; this module
computes nothing about the map itself.
"""

from __future__ import annotations

import json
import math
import os
import re
import resource
import shutil
import sys
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from laser_corners.citation import CITATION
from laser_corners.errors import OutputError, first_line
from laser_corners.io.base import PartialOutput
from laser_corners.io.occupancy import write_map
from laser_corners.io.partial import PARTIAL_SUFFIX, publish_folder, staging_folder
from laser_corners.io.trajectory import write_tum
from laser_corners.registration.mapfolder import save_map_data
from laser_corners.slam.grid import result_grid
from laser_corners.viz.slam import save_slam_map

__all__ = [
    "LANDMARK_COLUMNS",
    "RELATION_COLUMNS",
    "SLAM_FILES",
    "SlamRunInfo",
    "check_slam_folder",
    "ms_statistics",
    "ms_text",
    "peak_rss_mb",
    "relation_cells",
    "slam_markdown",
    "slam_summary",
    "write_landmarks",
    "write_slam_outputs",
]

LANDMARK_COLUMNS = (
    "x",
    "y",
    "cov_xx",
    "cov_xy",
    "cov_yy",
    "observations",
    "first_stamp",
    "last_stamp",
)
"""Columns of ``landmarks.csv``."""
SLAM_FILES = (
    "trajectory.tum",
    "odometry.tum",
    "graph.g2o",
    "landmarks.csv",
    "keyframes.npz",
    "map.pgm",
    "map.yaml",
    "map.png",
    "summary.json",
    "options.yaml",
    "report.md",
)
"""The files of the output folder (the table above)."""
RELATION_COLUMNS = ("covered / total", "|t| (m)", "t² (m²)", "|θ| (deg)", "θ² (deg²)")
"""Headers of the relation-metric table (mean ± std; Kümmerle et al. 2009, as Cartographer's
``compute_relations_metrics`` prints it)."""


def peak_rss_mb() -> float:
    """Peak resident memory of this process so far, MB (``getrusage``)."""
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return peak / (1024.0 * 1024.0) if sys.platform == "darwin" else peak / 1024.0


@dataclass
class SlamRunInfo:
    """What was measured around a SLAM run (the result does not know it).

    Attributes
    ----------
    source : str
        The recording.
    wall_s : float
        Wall-clock seconds of the run.
    peak_rss_mb : float
        Peak resident memory, MB.
    relations_file : str or None
        The ``.relations`` file the metrics come from.
    relations : dict
        ``{"trajectory": RelationMetrics.to_dict(), "odometry": ...}`` (empty without
        relations).
    closure_consistency : float or None
        Share of accepted loop closures the final map contradicts (> 0.2 m or 1°).
    resolution : float
        Grid cell size, metres.
    warnings : list of str
        Problems met while writing (an output the library could not write), one line each.
    """

    source: str
    wall_s: float
    peak_rss_mb: float
    relations_file: str | None = None
    relations: dict[str, dict[str, float]] = field(default_factory=dict)
    closure_consistency: float | None = None
    resolution: float = 0.05
    warnings: list[str] = field(default_factory=list)


def write_landmarks(path: Path, landmarks: Any) -> Path:
    """Write ``landmarks.csv`` (:data:`LANDMARK_COLUMNS`) atomically."""
    xy = np.asarray(landmarks.xy, dtype=np.float64).reshape(-1, 2)
    cov = np.asarray(landmarks.cov, dtype=np.float64).reshape(-1, 2, 2)
    table = np.column_stack(
        [
            xy,
            cov[:, 0, 0],
            cov[:, 0, 1],
            cov[:, 1, 1],
            np.asarray(landmarks.n_obs).reshape(-1),
            np.asarray(landmarks.first_stamp).reshape(-1),
            np.asarray(landmarks.last_stamp).reshape(-1),
        ]
    )
    partial = PartialOutput(path, overwrite=True)
    with partial.writing() as temporary:
        np.savetxt(
            temporary,
            table,
            delimiter=",",
            header=",".join(LANDMARK_COLUMNS),
            comments="",
            fmt=["%.6f"] * 5 + ["%d"] + ["%.6f"] * 2,
        )
    return path


def _options_record(options: Any) -> dict[str, Any]:
    if hasattr(options, "model_dump"):
        return dict(options.model_dump(mode="json"))
    return dict(options) if options is not None else {}


def _reason_kind(reason: object) -> str:
    """A rejection reason without its numbers (``"low overlap 0.43"`` -> ``"low overlap"``)."""
    text = re.sub(r"\s*[-+]?\d[\d.eE+-]*(\s?(m|deg|°))?(?=\W|$)", "", str(reason)).strip()
    return text.removesuffix(" by").strip() or str(reason)


def _closure_counts(closures: list[Any]) -> dict[str, Any]:
    accepted = sum(1 for c in closures if c.accepted)
    reasons = Counter(_reason_kind(c.reason) for c in closures if not c.accepted)
    return {
        "proposed": len(closures),
        "accepted": accepted,
        "rejected": len(closures) - accepted,
        "rejected_by_reason": dict(reasons),
    }


def slam_summary(result: Any, info: SlamRunInfo) -> dict[str, Any]:
    """``summary.json``: counts, timings, options, relation metrics, consistency, citation."""
    stamps = np.asarray(result.stamps, dtype=np.float64)
    ms = np.asarray(result.ms_per_scan, dtype=np.float64)
    duration = float(stamps[-1] - stamps[0]) if len(stamps) > 1 else 0.0
    reason = getattr(result, "partial_reason", None)
    if reason is None and result.interrupted:
        reason = "interrupted"
    closures = _closure_counts(list(result.closures))
    return {
        "input": info.source,
        "interrupted": bool(result.interrupted),
        "partial": reason is not None,
        "partial_reason": reason,
        "warnings": [*getattr(result, "warnings", []), *info.warnings],
        "counts": {
            "scans": len(stamps),
            "keyframes": len(result.keyframes),
            "landmarks": len(np.asarray(result.landmarks.xy).reshape(-1, 2)),
            **{k: int(v) for k, v in dict(result.counts).items()},
            **{f"closures_{k}": closures[k] for k in ("proposed", "accepted", "rejected")},
        },
        "prior_map": _prior_map(result),
        "skipped": dict(getattr(result, "skipped", {})),
        "closures": closures,
        "closure_consistency": info.closure_consistency,
        "timings": {
            "total_s": info.wall_s,
            "data_s": duration,
            "real_time_factor": duration / info.wall_s if info.wall_s > 0 else None,
            **ms_statistics(ms),
            "peak_rss_mb": info.peak_rss_mb,
        },
        "relations": {"file": info.relations_file, **info.relations} if info.relations else None,
        "mount": [float(v) for v in np.asarray(result.mount).reshape(3)],
        "grid_resolution_m": info.resolution,
        "options": _options_record(result.options),
        "citation": CITATION,
    }


def _prior_map(result: Any) -> dict[str, Any] | None:
    """The map a grown map grew from: its folder and keyframe count (None: a map of its own)."""
    folder = getattr(result, "prior_map", None)
    if folder is None:
        return None
    return {"folder": folder, "keyframes": int(getattr(result, "prior_keyframes", 0))}


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


def ms_statistics(ms: Any, prefix: str = "ms_per_scan") -> dict[str, float | None]:
    """Mean, 95th percentile and maximum of the times per scan (ms), keyed
    ``{prefix}_mean / _p95 / _max`` (None without scans). A few slow scans (the first
    search, a compilation) put the mean above the p95: the max shows them."""
    ms = np.asarray(ms, dtype=np.float64).reshape(-1)
    values = (ms.mean(), np.percentile(ms, 95), ms.max()) if ms.size else (None,) * 3
    return {
        f"{prefix}_{name}": None if v is None else float(v)
        for name, v in zip(("mean", "p95", "max"), values, strict=True)
    }


def ms_text(values: dict[str, Any], prefix: str = "ms_per_scan", sep: str = " / ") -> str:
    """``mean / p95 / max`` of :func:`ms_statistics` as text (``-`` without scans)."""
    mean, p95, most = (values.get(f"{prefix}_{k}") for k in ("mean", "p95", "max"))
    return "-" if mean is None else sep.join(f"{v:.2f}" for v in (mean, p95, most))


def _ms(timings: dict[str, Any]) -> str:
    return ms_text(timings)


def _json_safe(value: Any) -> Any:
    """``value`` with NaN and infinities as ``None`` (JSON has no NaN)."""
    if isinstance(value, dict):
        return {k: _json_safe(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_json_safe(v) for v in value]
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


def _write_text(path: Path, text: str) -> Path:
    partial = PartialOutput(path, overwrite=True)
    with partial.writing() as temporary:
        temporary.write_text(text, encoding="utf-8")
    return path


def _write_graph(result: Any, path: Path, paths: dict[str, Path], info: SlamRunInfo) -> None:
    """``graph.g2o``; a graph the writer refuses is a warning, not the loss of every other file."""
    try:
        with PartialOutput(path, overwrite=True).writing() as temporary:
            result.write_g2o(temporary)
    except (ValueError, RuntimeError, OutputError) as exc:
        info.warnings.append(f"{path.name} not written: {first_line(exc)}")
        path.unlink(missing_ok=True)  # no stale graph of an earlier run beside this run's files
    else:
        paths["graph"] = path


def check_slam_folder(folder: Path) -> None:
    """Refuse an output folder :func:`write_slam_outputs` cannot replace whole: a file, a
    folder that cannot be written or is marked read-only (no owner write bit: also for root),
    or one holding files that are not a slam result (they
    would be lost). A missing folder is fine (it is created).

    Raises
    ------
    OutputError
        Naming the folder and what is wrong, one line.
    """
    if not folder.exists():
        return
    if not folder.is_dir():
        raise OutputError(f"{folder}: is a file; the map output needs a folder")
    if not os.access(folder, os.W_OK | os.X_OK) or not folder.stat().st_mode & 0o200:
        raise OutputError(f"{folder}: cannot write into the folder (read-only)")
    other = sorted(
        p.name
        for p in folder.iterdir()
        if p.name not in SLAM_FILES and PARTIAL_SUFFIX not in p.name
    )
    if other:
        shown = ", ".join(other[:3]) + (f" and {len(other) - 3} more" if len(other) > 3 else "")
        raise OutputError(
            f"{folder}: holds files that are not a slam result ({shown}); the map folder is "
            "replaced whole, so choose a new or empty folder"
        )


def write_slam_outputs(result: Any, folder: Path, info: SlamRunInfo) -> dict[str, Path]:
    """Write every file of the table above as the folder ``folder``, whole (see the module
    notes): a previous result there is replaced only once the new one is complete.

    Returns
    -------
    dict of str to Path
        ``trajectory``, ``odometry``, ``graph``, ``landmarks``, ``keyframes``, ``map_yaml``,
        ``map_pgm``, ``map_png``, ``options``, ``summary``, ``report``.

    Raises
    ------
    OutputError
        The folder is refused (:func:`check_slam_folder`) or a file cannot be written
        (``graph.g2o`` excepted: a graph the library cannot write is recorded in
        ``info.warnings``, ``summary.json`` and ``report.md``, and the other files are still
        written); nothing is changed under ``folder`` then.
    InvalidParamsError
        The grid would be too big at ``info.resolution`` (before anything is written).
    """
    check_slam_folder(folder)
    grid = result_grid(result, info.resolution) if len(result.scans) else None
    staging = staging_folder(folder)
    try:
        paths = _write_files(result, staging, info, grid)
    except BaseException:
        shutil.rmtree(staging, ignore_errors=True)
        raise
    publish_folder(staging, folder)
    return {key: folder / path.name for key, path in paths.items()}


def _write_files(result: Any, folder: Path, info: SlamRunInfo, grid: Any) -> dict[str, Path]:
    """Every file into the (new, empty) ``folder``; the grid made already (None: no map)."""
    paths = {"trajectory": folder / "trajectory.tum"}
    header = f"laser-corners slam {info.source}: base pose in the map frame, one line per scan"
    write_tum(paths["trajectory"], result.stamps, result.poses, header=header)
    write_tum(
        folder / "odometry.tum",
        result.stamps,
        result.odometry,
        header=f"laser-corners slam {info.source}: odometry, one line per scan",
    )
    paths["odometry"] = folder / "odometry.tum"
    _write_graph(result, folder / "graph.g2o", paths, info)
    paths["landmarks"] = write_landmarks(folder / "landmarks.csv", result.landmarks)
    paths["keyframes"] = save_map_data(result, folder)  # what `localise` reads
    if grid is not None:
        paths["map_yaml"], paths["map_pgm"] = write_map(grid, folder / "map.yaml")
    title = Path(info.source).name + (" (interrupted)" if result.interrupted else "")
    paths["map_png"] = save_slam_map(folder / "map.png", result, grid, title)
    summary = slam_summary(result, info)
    paths["options"] = _write_text(folder / "options.yaml", result.options.to_yaml())
    summary["files"] = {k: p.name for k, p in paths.items()}
    paths["summary"] = _write_text(
        folder / "summary.json", json.dumps(_json_safe(summary), indent=2, allow_nan=False) + "\n"
    )
    paths["report"] = _write_text(folder / "report.md", slam_markdown(summary))
    return paths
