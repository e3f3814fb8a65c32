"""Registration accuracy on the Freiburg relations and on consecutive scans of corrected logs.

Usage::

    PYTHONPATH=src python benchmarks/registration_accuracy.py [--data ../shared/data/real]
        [--preset auto] [--out docs/matching-registration.md] [--min-inliers N]
        [--verify-scan] [--configs csc/ransac,bsc/clique]

For ``fr079.bag`` and ``aces.bag`` the pairs are those of ``<name>.relations`` (ground truth,
robot frame, mount = identity as in ``evaluate real``), split into local pairs (at most 10
scans apart) and revisits (loop closures), and the odometry is the bag's /odom (+ tf); for
``fr079-corrected.clf.gz`` and ``intel-corrected.clf.gz`` the pairs are consecutive scans
with the corrected poses as ground truth (no odometry in those logs).
Prints a Markdown table: acceptance, median / p90 translation and rotation errors of the
accepted registrations, of the odometry on all pairs and on the accepted pairs, and the rate
of gross errors among accepted registrations (> 0.5 m or > 0.2 rad).
"""

from __future__ import annotations

import argparse
from itertools import product
from pathlib import Path

from laser_corners import CornerDetector
from laser_corners.eval.poses import read_relations
from laser_corners.eval.real import load_scans, pairs_from_relations
from laser_corners.matching import MatchOptions
from laser_corners.presets import get_preset
from registration_errors import consecutive_pairs, registration_errors

LOCAL_GAP = 10
"""Relation pairs at most this many scans apart are 'local', the others 'revisits'."""
CONFIGS = (("csc", "ransac"), ("csc", "clique"), ("bsc", "ransac"), ("bsc", "clique"))


def _fmt(v: float, digits: int = 3) -> str:
    return "-" if v != v else f"{v:.{digits}f}"


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--data", default="../shared/data/real")
    ap.add_argument("--preset", default="auto")
    ap.add_argument("--min-inliers", type=int, default=MatchOptions().min_inliers)
    ap.add_argument("--out", default=None)
    ap.add_argument("--verify-scan", action="store_true", help="MatchOptions(verify_scan=True)")
    ap.add_argument(
        "--configs",
        default=",".join(f"{d}/{v}" for d, v in CONFIGS),
        help="Comma-separated descriptor/verification pairs",
    )
    args = ap.parse_args()
    root = Path(args.data)
    lines = [
        "| data | pairs | method | accepted | trans med / p90 (m) | rot med / p90 (deg) "
        "| odom all: trans med / p90, rot med / p90 | odom on accepted: trans, rot med "
        "| gross | ms/pair |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    datasets = (
        ("fr079.bag", "rel"),
        ("aces.bag", "rel"),
        ("fr079-corrected.clf.gz", "seq"),
        ("intel-corrected.clf.gz", "seq"),
    )
    for name, kind in datasets:
        path = root / name
        if not path.is_file():
            print(f"skip {path}: missing")
            continue
        scans, _ = load_scans(path)
        if kind == "rel":
            rel = read_relations(path.with_suffix(".relations"))
            pairs = pairs_from_relations([s.stamp for s in scans], rel, max_pairs=len(rel))
            # the relations mix nearby scans and revisits (loop closures, hundreds of scans
            # apart, where the odometry has drifted): scored separately
            subsets = [
                ("relations, local", [p for p in pairs if abs(p[1] - p[0]) <= LOCAL_GAP]),
                ("relations, revisit", [p for p in pairs if abs(p[1] - p[0]) > LOCAL_GAP]),
            ]
        else:
            subsets = [("consecutive", consecutive_pairs(scans))]
        det = CornerDetector(get_preset(args.preset, scans[0]))
        configs = [tuple(c.split("/")) for c in args.configs.split(",")]
        for (label, pairs), (desc, ver) in product(subsets, configs):
            if not pairs:
                continue
            opts = MatchOptions(
                verification=ver,
                min_inliers=args.min_inliers,  # type: ignore[arg-type]
                verify_scan=args.verify_scan,
            )
            res = registration_errors(scans, pairs, det, desc, opts, odometry=kind == "rel")
            s = res.summary()
            lines.append(
                f"| {name} ({label}) | {len(pairs)} | {desc}/{ver} | {s['accepted']:.1%} "
                f"| {_fmt(s['trans_median'])} / {_fmt(s['trans_p90'])} "
                f"| {_fmt(s['rot_deg_median'], 2)} / {_fmt(s['rot_deg_p90'], 2)} "
                f"| {_fmt(s['odom_trans_median'])} / {_fmt(s['odom_trans_p90'])}, "
                f"{_fmt(s['odom_rot_deg_median'], 2)} / {_fmt(s['odom_rot_deg_p90'], 2)} "
                f"| {_fmt(s['odom_trans_acc_median'])}, {_fmt(s['odom_rot_deg_acc_median'], 2)} "
                f"| {s['gross']:.1%} | {s['ms_per_pair']:.3f} |"
            )
            print(lines[-1], flush=True)
    table = "\n".join(lines)
    print(table)
    if args.out:
        Path(args.out).write_text(table + "\n")


if __name__ == "__main__":
    main()
