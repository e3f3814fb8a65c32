"""Outputs of ``laser-corners evaluate loops``: ``loops.json``, ``loops.md``, curves, plot.

:func:`write_loops_report` can be called after each method (the CLI does, through
``evaluate_loops(on_method=...)``), so the methods finished so far are on disk if a later
one fails.
"""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.figure import Figure

from laser_corners.errors import OutputError
from laser_corners.eval.loops import LoopsResult
from laser_corners.viz.loops import plot_precision_recall

__all__ = ["check_output_dir", "loops_rows", "write_loops_report"]


def check_output_dir(output: Path) -> Path:
    """Create the output folder; refuse a path that is an existing file.

    Raises
    ------
    OutputError
        ``output`` exists and is not a folder, or cannot be created.
    """
    output = Path(output)
    if output.exists() and not output.is_dir():
        raise OutputError(f"{output}: exists and is not a folder")
    try:
        output.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise OutputError(f"{output}: cannot create the folder ({exc.strerror})") from None
    return output


def _at_precision(curve: dict[str, Any], level: float) -> tuple[int | None, float]:
    """Lowest threshold whose precision reaches ``level`` and its recall."""
    for t, p, r in zip(curve["min_inliers"], curve["precision"], curve["recall"], strict=True):
        if not math.isnan(p) and p >= level:
            return int(t), float(r)
    return None, 0.0


def loops_rows(result: LoopsResult) -> list[dict[str, Any]]:
    """One table row per method: default threshold, operating point at precision 0.98, time."""
    summary = result.summary()["methods"]
    rows = []
    for name, m in result.methods.items():
        s = summary[name]
        t98, r98 = _at_precision(result.curve(name), 0.98)
        detected = m.best_inliers >= result.config.min_inliers
        outside = int((detected & m.correct & ~result.has_revisit).sum())
        rows.append(
            {
                "method": name,
                "keypoints_per_scan": m.keypoints_per_scan,
                "min_inliers": s["min_inliers"],
                "precision": s["precision"],
                "recall": s["recall"],
                "min_inliers_p98": t98,
                "recall_p98": r98,
                "queries": s["queries"],
                "correct_without_revisit": outside,
                "pairs": m.n_pairs,
                "ms_per_pair": s["ms_per_pair"],
                "seconds": sum(m.seconds.values()),
            }
        )
    return rows


def _markdown(result: LoopsResult, rows: list[dict[str, Any]]) -> str:
    cfg = result.config
    n_rev = int(result.has_revisit.sum())
    lines = [
        f"# Place recognition: {result.source}",
        "",
        f"{result.n_scans} queries, {n_rev} with a revisit; window {cfg.window_travel:g} m of "
        f"travel; revisit: another scan sees >= {100 * cfg.revisit_overlap:g} % of the query's "
        f"points; correct within {cfg.max_position_error:g} m and {cfg.max_angle_error:g} rad; "
        f"descriptor `{cfg.descriptor}`, `laser_corners.matching` with the scan check.",
        "",
        "| method | kp/scan | T | precision | recall | T at P>=0.98 | recall at P>=0.98 "
        "| correct w/o revisit | pairs | ms/pair | s |",
        "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for r in rows:
        p = "n/a" if r["precision"] is None else f"{r['precision']:.3f}"
        t98 = "-" if r["min_inliers_p98"] is None else str(r["min_inliers_p98"])
        lines.append(
            f"| {r['method']} | {r['keypoints_per_scan']:.2f} | {r['min_inliers']} | {p} | "
            f"{r['recall']:.3f} | {t98} | {r['recall_p98']:.3f} | "
            f"{r['correct_without_revisit']} | {r['pairs']} | "
            f"{r['ms_per_pair']:.4f} | {r['seconds']:.1f} |"
        )
    lines += ["", *(f"- {note}" for note in result.notes)]
    return "\n".join(lines).rstrip() + "\n"


def write_loops_report(result: LoopsResult, output: Path) -> dict[str, Path]:
    """Write ``loops.json``, ``loops.md``, ``loops_curves.csv``, ``queries.npz`` and
    ``precision_recall.png`` into ``output`` (created; an existing file is refused).

    Returns
    -------
    dict of str to Path
        The files written, by short name.
    """
    output = check_output_dir(output)
    paths: dict[str, Path] = {}
    path = output / "loops.json"
    path.write_text(json.dumps(result.summary(), indent=2) + "\n")
    paths["loops.json"] = path
    rows = loops_rows(result)
    path = output / "loops.md"
    path.write_text(_markdown(result, rows))
    paths["loops.md"] = path
    curves = {name: result.curve(name) for name in result.methods}
    path = output / "loops_curves.csv"
    with path.open("w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(["method", "min_inliers", "detections", "correct", "precision", "recall"])
        for name, c in curves.items():
            for k in range(len(c["min_inliers"])):
                writer.writerow(
                    [
                        name,
                        int(c["min_inliers"][k]),
                        int(c["detections"][k]),
                        int(c["correct"][k]),
                        f"{c['precision'][k]:.4f}",
                        f"{c['recall'][k]:.4f}",
                    ]
                )
    paths["loops_curves.csv"] = path
    arrays: dict[str, Any] = {
        "has_revisit": result.has_revisit,
        "revisit_candidate": result.revisit_candidate,
    }
    for name, m in result.methods.items():
        for key in ("best_candidate", "best_inliers", "position_error", "angle_error", "correct"):
            arrays[f"{name}/{key}"] = getattr(m, key)
    path = output / "queries.npz"
    np.savez_compressed(path, **arrays)
    paths["queries.npz"] = path
    fig = Figure(figsize=(6, 5))  # no pyplot state, the user's backend untouched
    plot_precision_recall(fig.add_subplot(), curves, result.config.min_inliers, title=result.source)
    path = output / "precision_recall.png"
    fig.savefig(path, dpi=150, bbox_inches="tight")
    paths["precision_recall.png"] = path
    return paths
