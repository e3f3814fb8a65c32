"""Cost of the place-recognition pair loop: ``local`` vs ``matching`` scorer, same process.

Usage::

    PYTHONPATH=src python benchmarks/bench_loops.py [LOG] [--method paper] [--queries 200]

For one method, describes every scan once with each scorer of
:mod:`laser_corners.eval.loop_scorers`, then registers ``--queries`` scans (evenly spread)
against every scan outside their 5 m window, one query per call and ``QUERY_BLOCK`` queries
per call, and prints wall-clock and CPU time per pair (all measured in this process, so the
machine's load affects all alike), single-threaded and on all cores numba may use.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numba
import numpy as np

from laser_corners.eval.loop_match import MatchOptions
from laser_corners.eval.loop_scorers import MATCHERS, Scorer, make_scorer
from laser_corners.eval.loops import QUERY_BLOCK, loop_detectors
from laser_corners.eval.real import load_scans
from laser_corners.eval.revisits import candidates, travel_distance

DEFAULT_LOG = Path(__file__).parents[1] / "../shared/data/real/fr079-corrected.clf.gz"


def _time_scorer(
    score: Scorer, queries: np.ndarray, travel: np.ndarray, block: int
) -> tuple[float, float, int]:
    """Wall and CPU seconds and pairs for ``queries``, ``block`` queries per call."""
    warm = candidates(travel, int(queries[0]), 5.0)
    score(np.full(warm.shape[0], int(queries[0])), warm)  # JIT / cache load
    wall, cpu, pairs = time.perf_counter(), time.process_time(), 0
    for lo in range(0, len(queries), block):
        cands = [candidates(travel, int(q), 5.0) for q in queries[lo : lo + block]]
        counts = [c.shape[0] for c in cands]
        score(np.repeat(queries[lo : lo + block], counts), np.concatenate(cands))
        pairs += sum(counts)
    return time.perf_counter() - wall, time.process_time() - cpu, pairs


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("log", nargs="?", type=Path, default=DEFAULT_LOG)
    parser.add_argument("--method", default="paper")
    parser.add_argument("--queries", type=int, default=200)
    args = parser.parse_args()
    scans, _ = load_scans(args.log)
    keypoints = loop_detectors([args.method], scans[0])[args.method](scans)
    travel = travel_distance(np.array([s.pose for s in scans]))
    queries = np.linspace(0, len(scans) - 1, min(args.queries, len(scans))).round().astype(int)
    kp_per_scan = np.mean([len(k) for k in keypoints])
    print(f"{args.log.name}: {len(scans)} scans, {args.method}, {kp_per_scan:.2f} kp/scan, "
          f"{len(queries)} queries")  # fmt: skip
    for threads in sorted({1, numba.config.NUMBA_NUM_THREADS}):
        numba.set_num_threads(threads)
        per_pair = {}
        for matcher in MATCHERS:
            t0 = time.perf_counter()
            score = make_scorer(matcher, scans, keypoints, MatchOptions())
            describe_s = time.perf_counter() - t0
            for block in (1, QUERY_BLOCK):
                wall, cpu, pairs = _time_scorer(score, queries, travel, block)
                per_pair[matcher] = wall / pairs
                print(f"  {threads} thread(s) {matcher:9s} {block:2d} queries/call: describe "
                      f"{describe_s:.2f} s, {pairs} pairs, {1e3 * wall / pairs:.4f} ms/pair "
                      f"wall, {1e3 * cpu / pairs:.4f} ms/pair CPU")  # fmt: skip
        print(
            f"  matching / local wall time per pair: {per_pair['matching'] / per_pair['local']:.2f}"
        )


if __name__ == "__main__":
    main()
