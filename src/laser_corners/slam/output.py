"""A SLAM result as a map folder: its contents as plain data for the folder's writer.

:func:`map_contents` turns a :class:`~laser_corners.slam.SlamResult` and what was measured
around the run (:class:`SlamRunInfo`) into a
:class:`~laser_corners.registration.mapfolder.MapContents` (trajectories, keyframes,
landmarks, the grid, ``summary.json`` by :func:`slam_summary`, the pose graph's writer);
:func:`write_slam_map` writes it whole (:func:`~laser_corners.registration.mapfolder.
write_map_folder`), with the pictures a caller renders (``laser_corners.viz.slam_report``
renders ``map.png`` and ``report.md``; the ROS node writes none). This module computes nothing
about the map itself.
"""

from __future__ import annotations

import math
import re
import resource
import sys
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from laser_corners.citation import CITATION
from laser_corners.registration.mapfolder import (
    MapContents,
    Render,
    check_map_folder,
    keyframe_arrays,
    write_map_folder,
)
from laser_corners.slam.grid import result_grid
from laser_corners.slam.result import SlamResult

__all__ = [
    "SlamRunInfo",
    "landmark_table",
    "map_contents",
    "ms_statistics",
    "peak_rss_mb",
    "slam_summary",
    "write_slam_map",
]


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


def landmark_table(landmarks: Any) -> np.ndarray:
    """``landmarks.csv``'s rows (:data:`~laser_corners.registration.mapfolder.LANDMARK_COLUMNS`)
    of a result's :class:`~laser_corners.slam.result.Landmarks`."""
    xy = np.asarray(landmarks.xy, dtype=np.float64).reshape(-1, 2)
    cov = np.asarray(landmarks.cov, dtype=np.float64).reshape(-1, 2, 2)
    return np.column_stack(
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


def _prior_map(result: Any) -> dict[str, Any] | None:
    """The map a grown map grew from: its folder and keyframe count (None: a map of its own)."""
    folder = getattr(result, "prior_map", None)
    if folder is None:
        return None
    return {"folder": folder, "keyframes": int(getattr(result, "prior_keyframes", 0))}


def slam_summary(result: SlamResult, info: SlamRunInfo) -> dict[str, Any]:
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


def _json_safe(value: Any) -> Any:
    """``value`` with NaN and infinities as ``None`` (JSON has no NaN)."""
    if isinstance(value, dict):
        return {k: _json_safe(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_json_safe(v) for v in value]
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


def map_contents(result: SlamResult, info: SlamRunInfo) -> MapContents:
    """Everything of the map folder but its pictures, as plain data.

    Raises
    ------
    InvalidParamsError
        The grid would be too big at ``info.resolution``.
    """
    grid = result_grid(result, info.resolution) if len(result.scans) else None
    return MapContents(
        source=info.source,
        keyframes=keyframe_arrays(result),
        stamps=np.asarray(result.stamps, dtype=np.float64),
        poses=np.asarray(result.poses, dtype=np.float64).reshape(-1, 3),
        odometry=np.asarray(result.odometry, dtype=np.float64).reshape(-1, 3),
        landmarks=landmark_table(result.landmarks),
        options_yaml=result.options.to_yaml(),
        summary=_json_safe(slam_summary(result, info)),
        grid=grid,
        write_graph=result.write_g2o,
    )


def write_slam_map(
    result: SlamResult, folder: Path, info: SlamRunInfo, render: Render | None = None
) -> dict[str, Path]:
    """Write ``result`` as the map folder ``folder``, whole
    (:func:`~laser_corners.registration.mapfolder.write_map_folder`), with the pictures
    ``render`` writes (None: none). A graph that cannot be written is named in
    ``info.warnings`` too.

    Raises
    ------
    OutputError
        The folder is refused or a file cannot be written; nothing is changed then.
    InvalidParamsError
        The grid would be too big at ``info.resolution`` (before anything is written).
    """
    check_map_folder(folder)
    contents = map_contents(result, info)
    before = len(contents.summary["warnings"])
    paths = write_map_folder(folder, contents, render)
    info.warnings += contents.summary["warnings"][before:]
    return paths
