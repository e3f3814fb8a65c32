"""Cost of the matching chain on a real log: covariance, descriptors, pairwise registration.

Usage::

    PYTHONPATH=src python benchmarks/bench_matching.py [LOG] [--max-scans N] [--preset auto]

Prints the cost per keypoint of the covariance and of each descriptor, and the cost per scan
pair of :func:`laser_corners.matching.register_many` (one query against every scan of the
log, as place recognition does; wall-clock and CPU time of the process), single-threaded and
on all cores numba may use.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numba
import numpy as np

from laser_corners import CornerDetector
from laser_corners.eval.real import load_scans
from laser_corners.kernel.candidates import kernel_config
from laser_corners.kernel.covariance import keypoint_covariances
from laser_corners.matching import KeypointBank, MatchOptions, describe, register_many
from laser_corners.presets import get_preset


def _best(fn, repeat: int = 3) -> float:
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return min(times)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("path", nargs="?", default="../shared/data/real/fr079.bag")
    ap.add_argument("--max-scans", type=int, default=None)
    ap.add_argument("--preset", default="auto")
    ap.add_argument("--queries", type=int, default=20)
    args = ap.parse_args()
    scans, _ = load_scans(Path(args.path), max_scans=args.max_scans)
    det = CornerDetector(get_preset(args.preset, scans[0]))
    kps = det.detect_many(scans)
    n_kp = sum(len(k) for k in kps)
    print(
        f"{args.path}: {len(scans)} scans, {n_kp} keypoints ({n_kp / len(scans):.1f}/scan), "
        f"preset {args.preset}"
    )

    xy = [s.to_cartesian()[0] for s in scans]
    config = kernel_config(det.params)

    def covs() -> None:
        for s, k, pts in zip(scans, kps, xy, strict=True):
            keypoint_covariances(
                np.ascontiguousarray(pts[:, 0]),
                np.ascontiguousarray(pts[:, 1]),
                k.xy,
                k.beam_index,
                k.scale_index,
                k.n_scales,
                s.angle_increment,
                config,
            )

    covs()
    t = _best(covs)
    print(f"covariance: {1e6 * t / n_kp:.2f} us/keypoint")
    banks = {}
    for kind in ("bsc", "csc"):
        descs = [describe(s, k, kind) for s, k in zip(scans, kps, strict=True)]
        t = _best(lambda kind=kind: [describe(s, k, kind) for s, k in zip(scans, kps, strict=True)])
        print(f"descriptor {kind}: {1e6 * t / n_kp:.2f} us/keypoint (incl. per-scan overhead)")
        banks[kind] = (descs, KeypointBank.from_lists(kps, descs))

    rng = np.random.default_rng(0)
    queries = rng.choice(len(scans), size=min(args.queries, len(scans)), replace=False)
    for kind, (descs, bank) in banks.items():
        for verification in ("ransac", "clique"):
            opts = MatchOptions(verification=verification)
            register_many(kps[0], descs[0], bank, options=opts)  # compile
            for threads in sorted({1, numba.config.NUMBA_NUM_THREADS}):
                numba.set_num_threads(threads)
                t0, c0 = time.perf_counter(), time.process_time()
                n_acc = 0
                for q in queries:
                    out = register_many(kps[q], descs[q], bank, options=opts)
                    n_acc += int(out.accepted.sum())
                dt, dc = time.perf_counter() - t0, time.process_time() - c0
                pairs = len(queries) * len(bank)
                print(
                    f"register_many {kind}/{verification}, {threads} thread(s): "
                    f"{1e6 * dt / pairs:.2f} us/pair wall, {1e6 * dc / pairs:.2f} us/pair CPU "
                    f"({pairs} pairs, {n_acc / pairs:.3%} accepted)"
                )
            numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)


if __name__ == "__main__":
    main()
