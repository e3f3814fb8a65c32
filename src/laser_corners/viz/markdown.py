"""``report.md`` of ``evaluate real``: the summary's numbers with links to every figure."""

from __future__ import annotations

from typing import Any

from laser_corners.citation import CITATION
from laser_corners.eval.real import PERSISTENCE_LEVELS, RealEvaluation

__all__ = ["real_markdown"]


def _percent(value: float | None) -> str:
    return "not enough evidence" if value is None else f"{100.0 * value:.1f} %"


def real_markdown(result: RealEvaluation, info: dict[str, Any]) -> str:
    """``report.md``: the numbers of ``info`` (:func:`~laser_corners.eval.real_summary.summary`)
    with links to the figures and files :func:`~laser_corners.viz.report.write_real_report` writes.
    """
    lines = _head(result, info)
    if info["warnings"]:  # first, so nobody reads a thin number without the warning
        lines += ["## Warnings", ""] + [f"- **{w}**" for w in info["warnings"]] + [""]
    lines += _maps(info) + _association(info) + _repeatability(info)
    if info["notes"]:
        lines += ["", "## Notes", ""] + [f"- {note}" for note in info["notes"]]
    seconds = ", ".join(f"{k} {v:.1f} s" for k, v in info["seconds"].items())
    lines += ["", f"Run time: {seconds}.", "", f"Method: {CITATION}", ""]
    return "\n".join(lines)


def _head(result: RealEvaluation, info: dict[str, Any]) -> list[str]:
    grid = info["grid"]
    visibility = (
        "ray-cast against each scan (occlusion on)"
        if info["occlusion"]
        else "field of view and range only"
    )
    if info["max_range"]:
        visibility += f", max range {info['max_range']:g} m"
    return [
        f"# Real-data evaluation: {result.source}",
        "",
        f"- scans: {info['scans']} ({info['scans_with_pose']} with a pose from "
        f"{info['pose_source']})",
        f"- detector for the maps: `{info['maps_detector']}` ({info['keypoints_per_scan']} "
        "keypoints per scan; parameters in [params.yaml](params.yaml))",
        f"- grid: {grid['cols']} x {grid['rows']} cells of {grid['resolution']:.3g} m; "
        f"visibility {visibility}",
        "",
    ]


def _maps(info: dict[str, Any]) -> list[str]:
    pf = info["persistent_features"]
    lines = [
        "## Observability map",
        "",
        "Ratio of the scans with a keypoint in the cell to the scans that had the cell in view.",
        "",
        "| plain | N8 (cell or its 8 neighbours) |",
        "|---|---|",
        "| ![observability](observability.png) | ![observability N8](observability_n8.png) |",
        "",
        "Arrays: [observability.npz](observability.npz) (`ratio`, `ratio_n8`), "
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
    return lines + [
        f"| >= {100 * level:g} % | {pf[f'n8_at_least_{level:g}']} |" for level in PERSISTENCE_LEVELS
    ]


def _association(info: dict[str, Any]) -> list[str]:
    asc = info["association"]
    return [
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
        f"{_percent(asc['share_std_within_threshold'])}"
        + ("" if asc["enough_evidence"] else " (too little evidence, see Warnings)"),
        "",
        "| matrix | histogram |",
        "|---|---|",
        "| ![association matrix](association_matrix.png) | "
        "![association histogram](association_histogram.png) |",
    ]


def _repeatability(info: dict[str, Any]) -> list[str]:
    rep = info["repeatability"]
    radii = rep["radii"]
    lines = [
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
        flag = "" if row["enough_evidence"] else " (too little evidence)"
        per_scan = row["keypoints_per_scan"]
        per_scan_text = "-" if per_scan is None else f"{per_scan:.2f}"
        lines.append(
            f"| {row['method']}{flag} | {per_scan_text} | {row['visible']} | "
            + " | ".join(values)
            + " |"
        )
    return [*lines, "", "Table: [repeatability.csv](repeatability.csv)."]


def _mm(value: float | None) -> str:
    return "not enough evidence" if value is None else f"{value * 1000:.1f} mm"
