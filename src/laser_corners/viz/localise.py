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
from laser_corners.slam.output import ms_statistics
from laser_corners.viz.slam import plot_slam_map, save_figure

__all__ = ["initial_text", "localise_summary", "save_localise_map", "write_localise_outputs"]


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
    initial = _initial_record(getattr(run, "initial", None))
    warnings = [skip_warning(source, skipped), _rejected(initial)]
    return {
        "input": source,
        "map": map_folder,
        "warnings": [w for w in warnings if w is not None],
        "skipped": skipped,
        "initial_pose": initial,
        "first_fix": fixes[0] if fixes else None,
        "relocalisations": fixes[1:],
        "lost": int(run.counts.get("lost", 0)),
        "counts": {k: int(v) for k, v in run.counts.items()},
        **ms_statistics(ms),
        "wall_s": round(float(wall_s), 3),
        "interrupted": bool(run.interrupted),
        "partial": bool(run.interrupted),
        "partial_reason": getattr(run, "partial_reason", None)
        or ("interrupted" if run.interrupted else None),
        "smoothed": _smoothed_record(run),
    }


def _initial_record(initial: Any) -> dict[str, Any] | None:
    """The given initial pose and its fate (``localise.run.InitialPose``), or None."""
    if initial is None:
        return None
    return {
        "pose": [round(float(v), 4) for v in initial.pose],
        "accepted": initial.accepted,
        "rejected_at_scan": initial.rejected_at_scan,
    }


def _rejected(initial: dict[str, Any] | None) -> str | None:
    """The warning for an initial pose the localiser did not keep, or None."""
    if initial is None or initial["accepted"] is not False:
        return None
    pose = ", ".join(f"{v:g}" for v in initial["pose"])
    return (
        f"the initial pose ({pose}) was rejected: the scans did not fit the map there (track "
        f"lost at scan {initial['rejected_at_scan']}); searched the whole map instead"
    )


def initial_text(initial: dict[str, Any] | None) -> str:
    """The ``initial pose`` row of the summary table: the pose given and what became of it."""
    if initial is None:
        return "none given (global search)"
    pose = ", ".join(f"{v:g}" for v in initial["pose"])
    fate = {True: "followed", False: f"rejected at scan {initial['rejected_at_scan']}"}
    return f"given ({pose}), {fate.get(initial['accepted'], 'never confirmed')}"


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
        **ms_statistics(slam_ms, "slam_ms_per_scan"),
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
