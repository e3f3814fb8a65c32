"""Relation errors of ``laser-corners`` SLAM on the Freiburg logs (and odometry alone).

    PYTHONPATH=src python benchmarks/slam_relations.py [fr079 aces intel] [--set key=value ...]

Prints, per log: scans, wall time, real-time factor, the relation metrics of the trajectory
(and of odometry alone), closures and their consistency. fr079 is reported twice: with the
bag's ``/tf_static`` mount (laser 0.04 m ahead of ``base_link``) and with the original log's
(laser 0.04 m behind the robot centre, ``mount=-0.04,0,0``).
"""

from __future__ import annotations

import argparse
import json
import resource
import time
from pathlib import Path

from laser_corners.eval.relations import closure_consistency, read_relations, relation_metrics
from laser_corners.slam import SlamOptions, run_slam

DATA = Path("/work/shared/data/real")


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("logs", nargs="*", default=["fr079", "aces", "intel"])
    parser.add_argument("--set", dest="overrides", action="append", default=[])
    parser.add_argument("--data", type=Path, default=DATA)
    parser.add_argument("--json", type=Path)
    args = parser.parse_args()
    rows = []
    for log in args.logs:
        variants = [("bag mount", [])]
        if log == "fr079":
            variants.append(("log mount -0.04", ["mount=-0.04,0,0"]))
        for label, extra in variants:
            options = SlamOptions().with_overrides([*args.overrides, *extra])
            start = time.perf_counter()
            result = run_slam(args.data / f"{log}.bag", options)
            wall = time.perf_counter() - start
            rel = read_relations(args.data / f"{log}.relations")
            m = relation_metrics(result.stamps, result.poses, rel)
            o = relation_metrics(result.stamps, result.odometry, rel)
            duration = float(result.stamps[-1] - result.stamps[0])
            row = {
                "log": log,
                "variant": label,
                "scans": result.counts["scans"],
                "wall_s": wall,
                "rt_factor": duration / wall,
                "metrics": m.to_dict(),
                "odometry": o.to_dict(),
                "counts": result.counts,
                "inconsistent": closure_consistency(result),
                "ms_per_scan_p50": float(result.ms_per_scan.mean()),
                "peak_rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
            }
            rows.append(row)
            print(
                f"{log:6s} {label:16s} {m.trans_mean:.4f} ± {m.trans_std:.4f} m  "
                f"{m.rot_deg_mean:.3f} ± {m.rot_deg_std:.3f} deg  ({m.n_covered}/{m.n_total})  "
                f"odom {o.trans_mean:.3f} m {o.rot_deg_mean:.2f} deg  {wall:.1f} s "
                f"({duration / wall:.0f}x)  closures {result.counts['closures_accepted']}/"
                f"{result.counts['closures_proposed']} inconsistent "
                f"{100 * row['inconsistent']:.1f} %  "
                f"align-fail {result.counts['alignment_failures']}",
                flush=True,
            )
    if args.json:
        args.json.write_text(json.dumps(rows, indent=2))


if __name__ == "__main__":
    main()
