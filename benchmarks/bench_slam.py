"""SLAM on the Freiburg benchmark logs: speed, memory, relation error, loop closures.

Usage::

    PYTHONPATH=src python benchmarks/bench_slam.py [LOG ...] [--set key=value ...]
        [--mount x,y,theta] [--out DIR]

LOG defaults to ``fr079.bag``, ``aces.bag`` and ``intel.bag`` in ``../shared/data/real``; each
is read with the ``.relations`` file beside it (``fr079.bag`` -> ``fr079.relations``). Every
log runs in a child process of its own (so its peak resident memory, ``getrusage``, is its
own) with :func:`laser_corners.slam.run_slam`; the wall time is the run only (imports and the
numba cache load before it are not counted; the kernels are compiled first, by
:func:`laser_corners.cli.kernels.warm_slam_kernels`, as ``laser-corners warmup`` does: a
fresh checkout would otherwise count a minute of compiling in its first log's first scans).
Prints a markdown table:

log | scans | duration s | wall s | real-time factor | ms/scan mean / p95 | peak RSS MB |
relation error trans m (ours, odometry) | rot deg (ours, odometry) | closures proposed /
accepted / rejected | contradicted closures

and writes ``DIR/ms_per_scan.png`` (milliseconds per scan against scan index, one line per
log: the cost must stay flat as the map grows), ``DIR/ms_per_scan.npz`` (the values, one array
per log in the order given) and ``DIR/bench_slam.json`` (every number).

``--mount x,y,theta`` overrides the base -> laser mounting for every log given (the bags'
``/tf_static`` otherwise): fr079 is reported both ways by running it twice, e.g.
``bench_slam.py ../shared/data/real/fr079.bag --mount=-0.04,0,0`` (the original CARMEN log's
mounting, 0.04 m behind the robot centre) and without ``--mount`` (the bag's, 0.04 m ahead).
Timings are of this machine under whatever else runs on it.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from laser_corners.cli.kernels import warm_slam_kernels
from laser_corners.viz.slam import plot_ms_per_scan, save_figure

sys.path.insert(0, str(Path(__file__).resolve().parent))
from report import write_table

DATA = Path(__file__).resolve().parents[1] / ".." / "shared" / "data" / "real"
DEFAULT_LOGS = ("fr079.bag", "aces.bag", "intel.bag")


def _mount_override(text: str | None) -> list[str]:
    if text is None:
        return []
    values = [float(v) for v in text.split(",")]
    if len(values) != 3:
        raise SystemExit(f"--mount needs x,y,theta, got {text!r}")
    return [f"mount=[{values[0]!r}, {values[1]!r}, {values[2]!r}]"]


def _worker(log: Path, overrides: list[str], output: Path) -> None:
    """Run one log and write its numbers (JSON) and ms per scan (``.npy``) next to ``output``."""
    import resource

    from laser_corners.eval.relations import closure_consistency, read_relations, relation_metrics
    from laser_corners.slam import SlamOptions, run_slam

    options = SlamOptions().with_overrides(overrides) if overrides else SlamOptions()
    relations_path = log.with_suffix(".relations")
    relations = read_relations(relations_path) if relations_path.is_file() else None
    start = time.perf_counter()
    result = run_slam(log, options)
    wall = time.perf_counter() - start
    accepted = sum(1 for c in result.closures if c.accepted)
    record = {
        "log": log.name,
        "overrides": overrides,
        "scans": len(result.stamps),
        "duration_s": float(result.stamps[-1] - result.stamps[0]),
        "wall_s": wall,
        "ms_mean": float(np.mean(result.ms_per_scan)),
        "ms_p95": float(np.percentile(result.ms_per_scan, 95)),
        "peak_rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0,
        "closures": [len(result.closures), accepted, len(result.closures) - accepted],
        "contradicted": float(closure_consistency(result)) if accepted else None,
        "mount": [float(v) for v in np.asarray(result.mount).reshape(3)],
        "interrupted": bool(result.interrupted),
        "counts": {key: int(value) for key, value in result.counts.items()},
    }
    if relations is not None:
        record["relations"] = relations_path.name
        record["ours"] = relation_metrics(result.stamps, result.poses, relations).to_dict()
        record["odometry"] = relation_metrics(result.stamps, result.odometry, relations).to_dict()
    np.save(output.with_suffix(".npy"), np.asarray(result.ms_per_scan, dtype=np.float64))
    output.write_text(json.dumps(record, indent=2))


def _pm(metrics: dict | None, key: str, digits: int) -> str:
    if metrics is None:
        return "-"
    return f"{metrics[key + '_mean']:.{digits}f} ± {metrics[key + '_std']:.{digits}f}"


def _row(r: dict) -> str:
    ours, odom = r.get("ours"), r.get("odometry")
    contradicted = "-" if r["contradicted"] is None else f"{100 * r['contradicted']:.1f} %"
    mount = ", ".join(f"{v:g}" for v in r["mount"])
    cells = [
        f"{r['log']} (mount {mount})",
        str(r["scans"]),
        f"{r['duration_s']:.0f}",
        f"{r['wall_s']:.1f}",
        f"{r['duration_s'] / r['wall_s']:.0f}x",
        f"{r['ms_mean']:.2f} / {r['ms_p95']:.2f}",
        f"{r['peak_rss_mb']:.0f}",
        f"{_pm(ours, 'trans', 4)} ({_pm(odom, 'trans', 2)})",
        f"{_pm(ours, 'rot_deg', 3)} ({_pm(odom, 'rot_deg', 1)})",
        " / ".join(str(v) for v in r["closures"]),
        contradicted,
        " / ".join(
            str(r["counts"].get(k, 0))
            for k in (
                "lost",
                "relocalisations_attempted",
                "relocalisations_accepted",
                "relocalisations_exhaustive",
            )
        ),
    ]
    return "| " + " | ".join(cells) + " |"


def _plot(records: list[dict], series: list[np.ndarray], path: Path) -> None:
    fig = Figure(figsize=(10, 5))
    ax = fig.subplots()
    names = [f"{r['log']}" + (" (--mount)" if r["overrides"] else "") for r in records]
    plot_ms_per_scan(ax, dict(zip(names, series, strict=True)))
    ax.set_title("laser-corners slam: cost per scan as the map grows")
    save_figure(fig, path)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("logs", nargs="*", type=Path)
    parser.add_argument(
        "--set",
        dest="overrides",
        action="append",
        default=[],
        help="SLAM option key=value (repeatable)",
    )
    parser.add_argument(
        "--mount", help="base -> laser x,y,theta for every log (negative: --mount=-0.04,0,0)"
    )
    parser.add_argument("--out", type=Path, default=Path("bench_slam_out"))
    parser.add_argument(
        "--table", type=Path, help="also write the table (command, date, machine) to this file"
    )
    parser.add_argument("--append", action="store_true", help="add to --table, not replace it")
    parser.add_argument("--worker", nargs=2, metavar=("LOG", "JSON"), help=argparse.SUPPRESS)
    parser.add_argument("--warm", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.warm:
        warm_slam_kernels()
        return
    overrides = list(args.overrides) + _mount_override(args.mount)
    if args.worker:
        _worker(Path(args.worker[0]), overrides, Path(args.worker[1]))
        return
    logs = args.logs or [DATA / name for name in DEFAULT_LOGS]
    args.out.mkdir(parents=True, exist_ok=True)
    # compiled once, in a process of its own (the workers load them from the cache; done in
    # this process, its memory showed in the first worker's peak: fr079 772 MB, alone 322)
    subprocess.run([sys.executable, __file__, "--warm"], check=True)
    records, series = [], []
    with tempfile.TemporaryDirectory() as scratch:
        for i, log in enumerate(logs):
            output = Path(scratch) / f"{i}.json"
            command = [sys.executable, __file__, "--worker", str(log), str(output)]
            command += [f"--set={item}" for item in overrides]
            print(f"running {log.name} ...", file=sys.stderr, flush=True)
            subprocess.run(command, check=True)
            records.append(json.loads(output.read_text()))
            series.append(np.load(output.with_suffix(".npy")))
    lines = [
        "| log | scans | duration s | wall s | real-time factor | ms/scan mean / p95 | "
        "peak RSS MB | relation trans m, ours (odometry) | relation rot deg, ours (odometry) | "
        "closures proposed / accepted / rejected | contradicted closures | lost / "
        "relocalisations attempted / accepted / exhaustive searches |",
        "|" + "---|" * 12,
        *(_row(record) for record in records),
    ]
    if overrides:
        lines.append(f"\noptions: {' '.join(overrides)}")
    print("\n".join(lines))
    if args.table:
        write_table(args.table, "SLAM on the shared logs", lines, args.append)
    _plot(records, series, args.out / "ms_per_scan.png")
    np.savez_compressed(args.out / "ms_per_scan.npz", *series)
    (args.out / "bench_slam.json").write_text(json.dumps(records, indent=2))
    print(f"\nwrote ms_per_scan.png, ms_per_scan.npz and bench_slam.json in {args.out}")


if __name__ == "__main__":
    main()
