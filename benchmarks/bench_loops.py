"""Cost of the place-recognition pair loop of ``evaluate loops``, with and without the scan check.

Usage::

    PYTHONPATH=src python benchmarks/bench_loops.py [LOG] [--method paper] [--queries 150]

For one method, detects and describes every scan once (:func:`laser_corners.eval.loops.loop_bank`),
then registers ``--queries`` scans (evenly spread) against every scan outside their 5 m
window with :func:`laser_corners.matching.register_pairs`, ``QUERY_BLOCK`` queries per call,
with :data:`~laser_corners.matching.PLACE_RECOGNITION` and with the same options without the
scan check, and prints wall-clock and CPU time per pair and the share of pairs per outcome
(all measured in this process, so the machine's load affects all alike), single-threaded and
on all cores numba may use.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numba
import numpy as np

from laser_corners.eval.loops import QUERY_BLOCK, LoopsConfig, loop_bank, loop_detectors
from laser_corners.eval.real import load_scans
from laser_corners.eval.revisits import candidates, travel_distance
from laser_corners.matching import PLACE_RECOGNITION, KeypointBank, MatchOptions, register_pairs

DEFAULT_LOG = Path(__file__).parents[1] / "../shared/data/real/fr079-corrected.clf.gz"


def _time(
    bank: KeypointBank, queries: np.ndarray, travel: np.ndarray, options: MatchOptions
) -> tuple[float, float, int, np.ndarray]:
    """Wall and CPU seconds, pairs and the outcome counts for ``queries``."""
    register_pairs(bank, [0], [1], options)  # JIT / cache load
    wall, cpu, pairs = time.perf_counter(), time.process_time(), 0
    status = np.zeros(5, dtype=np.int64)
    for lo in range(0, len(queries), QUERY_BLOCK):
        cands = [candidates(travel, int(q), 5.0) for q in queries[lo : lo + QUERY_BLOCK]]
        counts = [c.shape[0] for c in cands]
        res = register_pairs(
            bank, np.repeat(queries[lo : lo + QUERY_BLOCK], counts), np.concatenate(cands), options
        )
        status += np.bincount(res.status, minlength=5)
        pairs += sum(counts)
    return time.perf_counter() - wall, time.process_time() - cpu, pairs, status


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("log", nargs="?", type=Path, default=DEFAULT_LOG)
    parser.add_argument("--method", default="paper")
    parser.add_argument("--queries", type=int, default=150)
    args = parser.parse_args()
    scans, _ = load_scans(args.log, None, None)
    scans = [s for s in scans if s.pose is not None]
    keypoints = loop_detectors([args.method], scans[0])[args.method](scans)
    bank = loop_bank(scans, keypoints, LoopsConfig())
    travel = travel_distance(np.array([s.pose for s in scans]))
    queries = np.linspace(0, len(scans) - 1, args.queries).round().astype(np.int64)
    threads = numba.get_num_threads()
    print(f"{args.log.name}, {args.method}: {len(scans)} scans, {args.queries} queries")
    print(
        "threads | scan check | ms/pair wall | ms/pair CPU | accepted / keypoints / matches "
        "/ consistent / scans disagree (share of pairs)"
    )
    for n_threads in sorted({1, threads}):
        numba.set_num_threads(n_threads)
        for check in (True, False):
            opt = PLACE_RECOGNITION.with_overrides(
                {"verify_scan": check, "min_inliers": 1 if check else 2}
            )
            wall, cpu, pairs, status = _time(bank, queries, travel, opt)
            share = " / ".join(f"{v / pairs:.3f}" for v in status)
            print(
                f"{n_threads} | {check} | {1e3 * wall / pairs:.4f} | {1e3 * cpu / pairs:.4f} "
                f"| {share}"
            )
    numba.set_num_threads(threads)


if __name__ == "__main__":
    main()
