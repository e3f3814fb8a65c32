"""Global relocalisation: the place index (corner keypoints) against the correlative search.

Usage::

    PYTHONPATH=src python benchmarks/bench_relocalise.py [LOG ...] [--starts 20]
        [--methods keypoints correlative] [--cache DIR] [--kidnap 300] [--max-scans 900]
        [--output docs/benchmarks/relocalise.md]

LOG is a file of ``../shared/data/real`` with odometry (default: ``fr079.bag aces.bag
intel.bag edmonton.clf.gz``). Each is mapped once by ``laser-corners slam`` with default
options (cached under ``--cache``, never in the repository); its ``trajectory.tum`` is the
reference. Then, per method (``keypoints``: the place index proposes and the exhaustive
search runs only after ``places.fallback_travel`` without a fix; ``correlative``:
``places.enabled=false``, the exhaustive search alone, as before the index):

* **start**: the localiser, with no initial pose, starts at ``--starts`` scans spread evenly
  over the log and runs until ``--after`` scans past its first fix (at most ``--max-scans``).
  Reported: odometry travel to the first fix; the fix *wrong* when more than 0.5 m or 5 degrees
  from the reference; estimates more than 0.5 m / 5 degrees off among the scans after it.
* **kidnap**: from each start the localiser tracks 300 scans, then the input jumps
  ``--kidnap`` scans ahead with the odometry made continuous across the jump (a robot carried
  away); reported: whether and after how much travel it relocalised, and wrong estimates.
* **cost**: milliseconds per place-index attempt (query + dense check), per exhaustive search
  slice (one a scan while a search runs) and per scan while searching (everything the
  localiser does for the scan: detection, the attempt, hypotheses' ICP), mean / p95 / max
  over every start.

Writes the table (with the command, the date and the machine) to ``--output`` (``--append``:
adds to it) and, with ``--json FILE``, every run's numbers. Times are this machine's, with
whatever else runs.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from laser_corners.io.trajectory import read_tum
from laser_corners.localise import LocaliseOptions, Localiser
from laser_corners.pose import between_many
from laser_corners.registration.mapfolder import load_map

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_localise import REAL, cached_map, carried, read_log
from report import write_table

LOGS = ["fr079.bag", "aces.bag", "intel.bag", "edmonton.clf.gz"]
WRONG_XY, WRONG_DEG = 0.5, 5.0


def _error(pose: np.ndarray, ref: np.ndarray) -> tuple[float, float]:
    d = between_many(ref, pose)
    return math.hypot(d[0], d[1]), abs(math.degrees(d[2]))


def _wrong(err: tuple[float, float]) -> bool:
    return err[0] > WRONG_XY or err[1] > WRONG_DEG


def _drive(loc, scans, odo, stamps, ref, order, stop_after: int | None) -> dict:
    """Feed ``order``; the first fix at or after position ``fix_from``, wrong estimates."""
    travel, first, wrong, searching_ms = 0.0, None, 0, []
    for n, i in enumerate(order):
        if n:
            d = between_many(odo[order[n - 1]], odo[i])
            travel += math.hypot(d[0], d[1])
        searching = loc.status != "tracking"
        e = loc.add(scans[i], odo[i], stamps[i])
        if searching:
            searching_ms.append(loc.ms_per_scan[-1])
        if e is None:
            continue
        err = _error(e.pose, ref[i])
        wrong += _wrong(err)
        if first is None:
            first = {"position": n, "travel": travel, "error_m": err[0], "error_deg": err[1]}
        if stop_after is not None and n - first["position"] >= stop_after:
            break
    return {"first": first, "wrong": wrong, "searching_ms": searching_ms, "travel": travel}


def _costs(loc) -> dict:
    """The times the localiser kept (its last ``TIMINGS_KEPT`` of each) and how many slices
    of the exhaustive search ran (a counter: every one, however many the times kept)."""
    return {
        "place_ms": list(loc.places.ms),
        "search_ms": list(loc.search_ms),
        "search_slices": loc.counts["search_slices"],
    }


def start_runs(saved, log, starts, options, args) -> list[dict]:
    scans, odo, stamps, ref = log
    out = []
    for s in starts:
        loc = Localiser(saved, options)
        order = np.arange(s, min(s + args.max_scans, len(scans)))
        run = _drive(loc, scans, odo, stamps, ref, order, args.after)
        first = run["first"]
        out.append(
            {
                "start": int(s),
                "fix_travel": None if first is None else first["travel"],
                "fix_error_m": None if first is None else first["error_m"],
                "fix_error_deg": None if first is None else first["error_deg"],
                "fix_wrong": bool(
                    first is not None and _wrong((first["error_m"], first["error_deg"]))
                ),
                "wrong_estimates": run["wrong"],
                "searching_ms": run["searching_ms"],
                **_costs(loc),
            }
        )
        print(json.dumps({k: v for k, v in out[-1].items() if not k.endswith("ms")}), flush=True)
    return out


def kidnap_runs(saved, log, starts, options, args) -> list[dict]:
    scans, odo, stamps, ref = log
    out = []
    for s in starts:
        before = np.arange(s, s + 300)
        after = np.arange(s + 300 + args.kidnap, s + 300 + args.kidnap + args.max_scans)
        if after[-1] >= len(scans):
            continue
        odo2 = carried(odo, before[-1], after)
        loc = Localiser(saved, options)
        _drive(loc, scans, odo2, stamps, ref, before, None)
        tracked = loc.status == "tracking"
        fixes_before = len(loc.fixes)
        run = _drive(loc, scans, odo2, stamps, ref, after, args.after)
        later = loc.fixes[fixes_before:]
        out.append(
            {
                "start": int(s),
                "tracking_before": tracked,
                "relocalised": bool(later),
                "reloc_travel": later[0].travel if later else None,
                "wrong_estimates": run["wrong"],
                "searching_ms": run["searching_ms"],
                **_costs(loc),
            }
        )
        print(json.dumps({k: v for k, v in out[-1].items() if not k.endswith("ms")}), flush=True)
    return out


def load_log(name: str, cache: Path):
    path = REAL / name
    stem = name.split(".")[0]
    folder = cached_map(path, cache / f"{stem}-full", None)
    saved = load_map(folder)
    scans, odo, stamps = read_log(path)
    traj = read_tum(folder / "trajectory.tum")
    idx = np.clip(np.searchsorted(traj[0], stamps - 1e-4), 0, len(traj[0]) - 1)
    return saved, (scans, odo, stamps, traj[1][idx])


def _stats(values: list[float]) -> str:
    if not values:
        return "-"
    a = np.asarray(values)
    return f"{a.mean():.1f} / {np.percentile(a, 95):.1f} / {a.max():.1f}"


def summary(name: str, method: str, starts: list[dict], kidnaps: list[dict]) -> dict:
    travels = [r["fix_travel"] for r in starts if r["fix_travel"] is not None]
    gather = lambda key: [v for r in starts + kidnaps for v in r[key]]  # noqa: E731
    return {
        "log": name,
        "method": method,
        "starts": len(starts),
        "fixed": len(travels),
        "within_3m": sum(t <= 3.0 for t in travels),
        "wrong_fixes": sum(r["fix_wrong"] for r in starts),
        "travel_median": float(np.median(travels)) if travels else None,
        "travel_max": max(travels) if travels else None,
        "wrong_estimates": sum(r["wrong_estimates"] for r in starts + kidnaps),
        "kidnaps": len(kidnaps),
        "relocalised": sum(r["relocalised"] for r in kidnaps),
        "reloc_within_3m": sum(
            r["reloc_travel"] is not None and r["reloc_travel"] <= 3.0 for r in kidnaps
        ),
        "place_ms": _stats(gather("place_ms")),
        "search_ms": _stats(gather("search_ms")),
        "searches": sum(r["search_slices"] for r in starts + kidnaps),
        "searching_ms": _stats(gather("searching_ms")),
    }


def table(rows: list[dict]) -> list[str]:
    lines = [
        "| log | method | first fix within 3 m | wrong fixes | travel to fix median / max m "
        "| wrong estimates | kidnaps relocalised (within 3 m) | ms per index attempt "
        "mean / p95 / max | exhaustive search slices (one a scan), ms mean / p95 / max "
        "| ms per scan while searching mean / p95 / max |",
        "|---|---|---|---:|---|---:|---|---|---|---|",
    ]
    for r in rows:
        med = "-" if r["travel_median"] is None else f"{r['travel_median']:.2f}"
        top = "-" if r["travel_max"] is None else f"{r['travel_max']:.2f}"
        lines.append(
            f"| `{r['log']}` | {r['method']} | {r['within_3m']} / {r['starts']} "
            f"(fixed {r['fixed']}) | {r['wrong_fixes']} | {med} / {top} | {r['wrong_estimates']} "
            f"| {r['relocalised']} / {r['kidnaps']} ({r['reloc_within_3m']}) | {r['place_ms']} "
            f"| {r['searches']}: {r['search_ms']} | {r['searching_ms']} |"
        )
    return lines


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("logs", nargs="*", default=LOGS)
    parser.add_argument("--starts", type=int, default=20)
    parser.add_argument("--methods", nargs="+", default=["keypoints", "correlative"])
    parser.add_argument(
        "--cache", type=Path, default=Path(tempfile.gettempdir()) / "laser-corners-reloc"
    )
    parser.add_argument("--kidnap", type=int, default=300)
    parser.add_argument("--kidnaps", type=int, default=5, help="kidnap runs per log")
    parser.add_argument("--max-scans", type=int, default=900)
    parser.add_argument("--after", type=int, default=100)
    parser.add_argument("--set", action="append", default=[])
    parser.add_argument("--output", type=Path, default=Path("docs/benchmarks/relocalise.md"))
    parser.add_argument("--append", action="store_true", help="add to --output, not replace it")
    parser.add_argument("--json", type=Path, help="every run's numbers (not in the repository)")
    args = parser.parse_args()
    rows, records = [], []
    for name in args.logs:
        saved, log = load_log(name, args.cache)
        n = len(log[0])
        warm = Localiser(saved)  # compiles (or loads) every kernel before anything is timed
        for i in range(min(50, n)):
            warm.add(log[0][i], log[1][i], log[2][i])
        starts = np.linspace(0, n - args.max_scans - 1, args.starts).astype(int)
        k_starts = np.linspace(0, n - 300 - args.kidnap - args.max_scans - 1, args.kidnaps)
        for method in args.methods:
            options = LocaliseOptions().with_overrides(
                [*args.set, f"places.enabled={method == 'keypoints'}"]
            )
            t = time.perf_counter()
            s = start_runs(saved, log, starts, options, args)
            k = kidnap_runs(saved, log, k_starts.astype(int), options, args)
            rows.append(summary(name, method, s, k))
            rows[-1]["wall_s"] = time.perf_counter() - t
            records.append({"log": name, "method": method, "starts": s, "kidnaps": k})
            print(json.dumps(rows[-1], default=float), flush=True)
    title = "Global relocalisation: place index vs correlative search"
    write_table(args.output, title, table(rows), args.append)
    if args.json:
        args.json.write_text(json.dumps(records, default=float))
    print(args.output.read_text())


if __name__ == "__main__":
    main()
