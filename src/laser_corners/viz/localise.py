"""What ``laser-corners localise`` writes: ``trajectory.tum``, ``summary.json``, the plot.

``online.tum`` is written while the run goes (by the CLI, one line per estimate, from the
first fix on); this module writes the rest from a :class:`~laser_corners.localise.LocaliseRun`:
``trajectory.tum`` (the smoothed trajectory, else the online estimates), the summary (first
fix: stamp, scan index, travel; relocalisations; lost count; ms per scan mean / p95; the
smoothing's numbers) and the trajectory drawn on the map's occupancy grid, fixes marked.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.figure import Figure

from laser_corners.io.base import PartialOutput, skip_warning
from laser_corners.io.occupancy import OccupancyGrid
from laser_corners.io.trajectory import write_tum
from laser_corners.viz.slam import plot_slam_map, save_figure

__all__ = ["localise_summary", "save_localise_map", "write_localise_outputs"]


def _fix_record(fix: Any) -> dict[str, Any]:
    return {
        "scan_index": int(fix.scan_index),
        "stamp": float(fix.stamp),
        "travel_m": round(float(fix.travel), 3),
        "pose": [round(float(v), 4) for v in fix.pose],
    }


def localise_summary(run: Any, source: str, map_folder: str, wall_s: float) -> dict[str, Any]:
    """The numbers of a localisation run as a JSON-ready mapping."""
    ms = np.asarray(run.ms_per_scan, dtype=np.float64)
    fixes = [_fix_record(f) for f in run.fixes]
    skipped = dict(getattr(run, "skipped", {}))
    warning = skip_warning(source, skipped)
    return {
        "input": source,
        "map": map_folder,
        "warnings": [] if warning is None else [warning],
        "skipped": skipped,
        "first_fix": fixes[0] if fixes else None,
        "relocalisations": fixes[1:],
        "lost": int(run.counts.get("lost", 0)),
        "counts": {k: int(v) for k, v in run.counts.items()},
        "ms_per_scan_mean": float(ms.mean()) if ms.size else None,
        "ms_per_scan_p95": float(np.percentile(ms, 95)) if ms.size else None,
        "wall_s": round(float(wall_s), 3),
        "interrupted": bool(run.interrupted),
        "smoothed": _smoothed_record(run),
    }


def _smoothed_record(run: Any) -> dict[str, Any] | None:
    """The smoothing's numbers (``localise.smooth``), or None when it did not run."""
    sm = run.smoothed
    if sm is None:
        return None
    slam_ms = np.asarray(run.slam_ms_per_scan, dtype=np.float64)
    return {
        "scans": len(sm.index),
        "anchors": sm.anchors,
        "closures": sm.closures,
        "segments_dropped": sm.segments_dropped,
        "slam_ms_per_scan_mean": float(slam_ms.mean()) if slam_ms.size else None,
    }


def save_localise_map(
    path: Path, grid: OccupancyGrid | None, poses: np.ndarray, fixes: np.ndarray, title: str = ""
) -> Path:
    """The trajectory (base poses in the map) on the grid, fixes as red crosses."""
    aspect = 1.0
    if grid is not None:
        left, right, bottom, top = grid.extent
        aspect = (top - bottom) / max(right - left, 1e-9)
    fig = Figure(figsize=(10.0, float(np.clip(10.0 * aspect, 4.0, 16.0))))
    ax = fig.subplots()
    plot_slam_map(ax, grid, poses)
    if len(fixes):
        ax.scatter(fixes[:, 0], fixes[:, 1], marker="x", s=60, color="tab:red", label="fixes")
        ax.legend(loc="upper right", fontsize="small", framealpha=0.8)
    if title:
        ax.set_title(title)
    return save_figure(fig, path)


def write_localise_outputs(
    run: Any, folder: Path, grid: OccupancyGrid | None, summary: dict[str, Any], header: str = ""
) -> dict[str, Path]:
    """``trajectory.tum`` (smoothed when the run has it, else the online estimates),
    ``summary.json`` and ``trajectory.png`` into ``folder`` (atomically)."""
    paths = {
        "trajectory": folder / "trajectory.tum",
        "summary": folder / "summary.json",
        "plot": folder / "trajectory.png",
    }
    sm = run.smoothed
    stamps, poses = (sm.stamps, sm.poses) if sm is not None else (run.stamps, run.poses)
    kind = "smoothed (localise.smooth)" if sm is not None else "online estimates"
    write_tum(paths["trajectory"], stamps, poses, header=f"{header}, {kind}" if header else kind)
    with PartialOutput(paths["summary"], overwrite=True).writing() as temporary:
        temporary.write_text(json.dumps(summary, indent=2) + "\n", encoding="utf-8")
    fixes = np.array([f.pose for f in run.fixes], dtype=np.float64).reshape(-1, 3)
    title = Path(summary["input"]).name + (" (interrupted)" if run.interrupted else "")
    save_localise_map(paths["plot"], grid, poses, fixes, title)
    return paths
