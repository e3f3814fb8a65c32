"""Maps that grow, on the Freiburg logs: map the first half, grow it with the second half.

Usage::

    PYTHONPATH=src python benchmarks/bench_grow.py [LOG ...] [--split 0.5] [--out DIR]
        [--table docs/benchmarks/grow.md]

LOG defaults to ``fr079``, ``aces`` and ``intel`` (``../shared/data/real/LOG.bag`` with
``LOG.relations``; fr079 with the mount -0.04,0,0 of ``docs/benchmarks/slam.md``). For each:

1. the one-run SLAM of the whole log (:func:`laser_corners.slam.run_slam`, default options);
2. the first half of the scans mapped (``stop_scan``) and written as a map folder OLD
   (under ``--out``, never in the repository);
3. OLD grown with the second half (``start_scan``, ``prior_map=OLD``, no initial pose: the
   global fix by the place index), timed.

The grown trajectory (the first half's scans where the grown map has OLD's keyframes now:
each keyframe's correction, blended between the keyframes around a scan, on the scan's pose
in OLD; the grown run's for the second half) and the one-run SLAM's are scored with the
relation metric on the relations with a stamp in the second half (the ones that reach it);
*ratio* = grown / one-run mean translation error (and rotation). The real-time factor is the
second half's duration over the grow run's wall time (this machine, 2 cores shared with
other work; the kernels compiled before anything is timed, as ``laser-corners warmup`` does).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

from laser_corners.cli.kernels import warm_slam_kernels
from laser_corners.eval.relations import read_relations, relation_metrics
from laser_corners.pose import compose_many, invert_many
from laser_corners.slam import SlamOptions, SlamResult, run_slam
from laser_corners.slam.output import SlamRunInfo
from laser_corners.viz.slam_report import write_slam_outputs

sys.path.insert(0, str(Path(__file__).resolve().parent))
from report import write_table

DATA = Path(__file__).resolve().parents[1] / ".." / "shared" / "data" / "real"
MOUNTS = {"fr079": (-0.04, 0.0, 0.0)}
"""Mounts that override a bag's (``docs/benchmarks/slam.md``)."""


def grow_log(name: str, out: Path, split: float) -> dict:
    """The three runs of one log and their scores (module notes)."""
    path = DATA / f"{name}.bag"
    relations = read_relations(DATA / f"{name}.relations")
    options = SlamOptions(mount=MOUNTS.get(name))
    full = run_slam(path, options)
    total = full.counts["scans"] + full.counts["skipped_no_odometry"]
    half = int(total * split)
    old = run_slam(path, options, stop_scan=half)
    folder = out / f"{name}-old"
    write_slam_outputs(old, folder, SlamRunInfo(str(path), 0.0, 0.0))
    start = time.perf_counter()
    grown = run_slam(path, options, start_scan=half, prior_map=folder)
    wall = time.perf_counter() - start
    t_half = float(grown.stamps[0])
    rel = relations[(relations[:, 0] >= t_half) | (relations[:, 1] >= t_half)]
    before = old.stamps < t_half
    stamps = np.concatenate([old.stamps[before], grown.stamps])
    poses = np.vstack([old_as_grown(old, grown)[before], grown.poses])
    ours = relation_metrics(stamps, poses, rel)
    one = relation_metrics(full.stamps, full.poses, rel)
    across = np.minimum(rel[:, 0], rel[:, 1]) < t_half  # one stamp in OLD, one after
    parts = {
        kind: (
            int(keep.sum()),
            relation_metrics(stamps, poses, rel[keep]).trans_mean,
            relation_metrics(full.stamps, full.poses, rel[keep]).trans_mean,
        )
        for kind, keep in (("across", across), ("second", ~across))
    }
    duration = float(grown.stamps[-1] - grown.stamps[0])
    return {
        "log": name,
        "scans": total,
        "split_scan": half,
        "relations": len(rel),
        "grown_trans": ours.trans_mean,
        "grown_rot": ours.rot_deg_mean,
        "full_trans": one.trans_mean,
        "full_rot": one.rot_deg_mean,
        "ratio_trans": ours.trans_mean / one.trans_mean,
        "ratio_rot": ours.rot_deg_mean / one.rot_deg_mean,
        **{
            f"{kind}_{key}": value
            for kind, part in parts.items()
            for key, value in zip(("relations", "grown_trans", "full_trans"), part, strict=True)
        },
        "wall_s": wall,
        "duration_s": duration,
        "real_time_factor": duration / wall,
        "old_keyframes": grown.counts.get("prior_keyframes"),
        "keyframes": grown.counts["keyframes"],
        "relocalisations_accepted": grown.counts["relocalisations_accepted"],
        "closures_accepted": grown.counts["closures_accepted"],
        "unjoined": grown.counts.get("grow_unjoined"),
        "warnings": grown.warnings,
    }


def old_as_grown(old: SlamResult, grown: SlamResult) -> np.ndarray:
    """OLD's scan poses where the grown map put OLD's keyframes: each keyframe's correction
    (its grown pose after its pose in OLD, in the map frame) blended by time between the
    keyframes before and after a scan (as the SLAM blends its scans between keyframes),
    applied to the scan's pose in OLD."""
    n = len(old.keyframes)
    fix = compose_many(grown.keyframe_poses[:n], invert_many(old.keyframe_poses))
    t_kf = old.stamps[old.keyframes]
    after = np.clip(np.searchsorted(t_kf, old.stamps, side="right"), 1, max(n - 1, 1))
    before = after - 1
    span = np.maximum(t_kf[after] - t_kf[before], 1e-9)
    w = np.clip((old.stamps - t_kf[before]) / span, 0.0, 1.0)[:, None]
    turn = np.angle(np.exp(1j * (fix[after, 2] - fix[before, 2])))
    blend = fix[before] + w * np.column_stack([fix[after, :2] - fix[before, :2], turn])
    return compose_many(blend, old.poses)


def table(rows: list[dict]) -> list[str]:
    """The markdown table of :func:`grow_log`'s records."""
    head = (
        "| log | split at scan | relations (2nd half) | grown trans m / rot deg | one-run trans m "
        "/ rot deg | ratio trans / rot | grow wall s | real-time factor | old / all keyframes "
        "| relocalised / closures | unjoined |"
    )
    lines = [head, "|" + "---|" * 11]
    for r in rows:
        lines.append(
            f"| {r['log']} | {r['split_scan']} of {r['scans']} | {r['relations']} | "
            f"{r['grown_trans']:.4f} / {r['grown_rot']:.3f} | "
            f"{r['full_trans']:.4f} / {r['full_rot']:.3f} | "
            f"{r['ratio_trans']:.2f}x / {r['ratio_rot']:.2f}x | {r['wall_s']:.1f} | "
            f"{r['real_time_factor']:.0f}x | {r['old_keyframes']} / {r['keyframes']} | "
            f"{r['relocalisations_accepted']} / {r['closures_accepted']} | {r['unjoined']} |"
        )
    return lines


def part_table(rows: list[dict]) -> list[str]:
    """Where the error is: the relations reaching back into OLD and those of the second half
    alone, grown / one-run mean translation error."""
    lines = [
        "| log | across the split: relations, grown / one-run trans m, ratio | second half "
        "alone: relations, grown / one-run trans m, ratio |",
        "|---|---|---|",
    ]
    for r in rows:
        cells = [
            f"{r[k + '_relations']}, {r[k + '_grown_trans']:.4f} / {r[k + '_full_trans']:.4f}, "
            f"{r[k + '_grown_trans'] / r[k + '_full_trans']:.2f}x"
            for k in ("across", "second")
        ]
        lines.append(f"| {r['log']} | " + " | ".join(cells) + " |")
    return lines


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("logs", nargs="*", default=["fr079", "aces", "intel"])
    parser.add_argument("--split", type=float, default=0.5)
    parser.add_argument("--out", type=Path, default=Path("bench_grow_out"))
    parser.add_argument("--table", type=Path, help="write the markdown table here")
    args = parser.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    warm_slam_kernels()  # no compiling inside a timed run
    rows = []
    for name in args.logs:
        rows.append(grow_log(name, args.out, args.split))
        print(json.dumps(rows[-1]), flush=True)
    (args.out / "bench_grow.json").write_text(json.dumps(rows, indent=1))
    lines = [*table(rows), "", *part_table(rows)]
    print("\n".join(lines))
    if args.table is not None:
        notes = [
            "",
            "Grown: the first half mapped, then grown with the second half (no initial pose); "
            "scored on the relations with a stamp in the second half, beside the one-run SLAM "
            "of the whole log. Ratio = grown / one-run mean error (the bar: 1.1x). OLD's scans "
            "are scored where the grown map put OLD's keyframes (their corrections blended "
            "between the keyframes around a scan); the second table splits the relations into "
            "those reaching back into OLD (across the split) and those of the second half alone.",
        ]
        write_table(args.table, "Maps that grow (slam --map)", lines + notes)


if __name__ == "__main__":
    main()
