"""The numbers of a :class:`~laser_corners.eval.real.RealEvaluation`, as plain data and text.

:func:`summary` (written as ``summary.json``), :func:`repeatability_rows` (``repeatability.csv``)
and :func:`headline` (the console line of ``evaluate real``) never state a NaN: a number without
evidence is ``None`` / "not enough evidence", and :attr:`RealEvaluation.warnings` says why.
The report with its figures: :func:`laser_corners.viz.report.write_real_report`.
"""

from __future__ import annotations

import math
from typing import Any

from laser_corners.citation import CITATION
from laser_corners.eval.real import RealEvaluation

__all__ = ["CITATION", "headline", "repeatability_rows", "summary"]


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
        row["enough_evidence"] = (
            rep.n_visible >= result.config.min_visible and rep.n_pairs >= result.config.min_pairs
        )
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
        "method_reference": CITATION,
        "scans": result.n_scans,
        "scans_with_pose": result.n_scans_with_pose,
        "pose_source": result.pose_source,
        "preset": result.config.preset,
        "maps_detector": result.maps_label,
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
            "enough_evidence": a.n_pairs_with_std >= result.config.min_pairs,
        },
        "repeatability": {
            "pairs_source": result.pairs_source,
            "pairs": result.n_pairs,
            "radii": list(result.config.radii),
            "rows": [
                {k: _number(v) if isinstance(v, float) else v for k, v in row.items()}
                for row in repeatability_rows(result)
            ],
        },
        "occlusion": result.config.occlusion,
        "max_range": result.config.max_range,
        "no_return_range": result.no_return_range,
        "notes": result.notes,
        "warnings": result.warnings,
        "seconds": {k: round(v, 2) for k, v in result.seconds.items()},
    }


def headline(result: RealEvaluation) -> str:
    """One line: persistent features and the association distance (no NaN, ever)."""
    counts = result.persistence_counts()
    a = result.association
    text = (
        f"{len(result.features)} persistent features (N8 >= 50 %: {counts[0.5]}, >= 75 %: "
        f"{counts[0.75]}, 100 %: {counts[1.0]}); association: "
    )
    if a.n_pairs_with_std == 0:
        return text + "not enough evidence (no feature pair seen together in 2 or more scans)"
    text += (
        f"max std {a.max_std * 1000:.1f} mm, {100 * a.share_std_within:.1f} % of "
        f"{a.n_pairs_with_std} pairs <= {a.threshold * 1000:g} mm, "
        f"{a.n_pairs_never_together} pairs never together"
    )
    if a.n_pairs_with_std < result.config.min_pairs:
        text += f" (too little evidence: fewer than {result.config.min_pairs} pairs)"
    return text
