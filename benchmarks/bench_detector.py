"""Benchmark of the detector kernel: ms per scan and scans/s, printed as a Markdown table.

Usage::

    .venv/bin/python benchmarks/bench_detector.py [--repeats 5] [--sim-scans 400]

Simulated scans: Hokuyo UST-10LX (1081 beams, 270 deg, 0.25 deg) from random poses in the demo
world (an L-shaped room with a pillar), range noise sigma 0, 0.01 and 0.03 m. Real scans: the
first scans of the 180/360/768-beam bags in ../shared/data/real (read once, not timed).
Timings use the paper preset, one scan per ``detect`` call pinned to one core; ``detect_many``
runs the whole set as one batch (numba threads over scans). JIT start-up (compile, or load
from numba's cache) is measured on the first call and reported separately.
"""

from __future__ import annotations

import argparse
import os
import platform
import sys
import time
from pathlib import Path

import numba
import numpy as np

from laser_corners import CornerDetector, DetectorParams, LaserScan
from laser_corners.demo import demo_world
from laser_corners.sim import UST_10LX

REAL = Path(__file__).resolve().parents[1] / ".." / "shared" / "data" / "real"
REAL_SETS = [("fr079.bag", "/scan"), ("intel.bag", "/scan"), ("hokuyo270_rooms.bag", "/left_scan")]


def simulated_scans(n: int, seed: int = 0, noise_sigma: float = 0.01) -> list[LaserScan]:
    rng = np.random.default_rng(seed)
    world = demo_world()
    scans = []
    while len(scans) < n:
        pose = (rng.uniform(-2.5, 3.5), rng.uniform(-2.0, 2.5), rng.uniform(-np.pi, np.pi))
        if 1.0 < pose[0] < 4.0 and 1.0 < pose[1] < 3.0:  # outside the L
            continue
        scan = world.scan(pose, UST_10LX, noise_sigma=noise_sigma, rng=rng, stamp=len(scans))
        scans.append(scan)
    return scans


def real_scans(name: str, topic: str, limit: int) -> list[LaserScan] | str:
    path = REAL / name
    if not path.is_file():
        return f"skipped: {path} not found"
    try:
        from laser_corners.io import open_scans
    except ImportError as exc:  # pragma: no cover - the io package ships with the library
        return f"skipped: laser_corners.io unavailable ({exc})"
    scans = []
    for scan in open_scans(path, topic=topic):
        scans.append(scan)
        if len(scans) >= limit:
            break
    return scans


def time_per_scan(detector: CornerDetector, scans: list[LaserScan], repeats: int) -> np.ndarray:
    times = []
    for _ in range(repeats):
        for scan in scans:
            t0 = time.perf_counter()
            detector.detect(scan)
            times.append(time.perf_counter() - t0)
    return np.array(times) * 1e3


def scans_per_second(detector: CornerDetector, scans: list[LaserScan], repeats: int) -> float:
    best = np.inf
    for _ in range(repeats):
        t0 = time.perf_counter()
        detector.detect_many(scans)
        best = min(best, time.perf_counter() - t0)
    return len(scans) / best


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--sim-scans", type=int, default=400)
    parser.add_argument("--real-scans", type=int, default=1000)
    args = parser.parse_args()

    detector = CornerDetector(DetectorParams())
    sets: list[tuple[str, list[LaserScan] | str]] = [
        (f"simulated UST-10LX, noise {sigma} m", simulated_scans(args.sim_scans, noise_sigma=sigma))
        for sigma in (0.0, 0.01, 0.03)
    ]
    for name, topic in REAL_SETS:
        sets.append((f"{name} {topic}", real_scans(name, topic, args.real_scans)))

    t0 = time.perf_counter()
    detector.detect(sets[0][1][0])  # type: ignore[index]
    first_call = (time.perf_counter() - t0) * 1e3
    t0 = time.perf_counter()
    detector.detect_many(sets[0][1][:2])  # type: ignore[index]
    first_batch = (time.perf_counter() - t0) * 1e3

    print(f"python {platform.python_version()}, numba {numba.__version__}, "
          f"{os.cpu_count()} CPUs, numba threads {numba.get_num_threads()}")  # fmt: skip
    print(f"JIT start-up (first detect call, compile or cache load): {first_call:.0f} ms; "
          f"first detect_many call: {first_batch:.0f} ms\n")  # fmt: skip
    print("| scans | beams | n | kp/scan | median ms/scan | p95 ms/scan | detect_many scans/s |")
    print("|---|---:|---:|---:|---:|---:|---:|")
    affinity = os.sched_getaffinity(0) if hasattr(os, "sched_getaffinity") else None
    for label, scans in sets:
        if isinstance(scans, str):
            print(f"| {label} | | | | {scans} | | |")
            continue
        kp = np.mean([len(k) for k in detector.detect_many(scans)])
        if affinity:
            os.sched_setaffinity(0, {min(affinity)})  # one core for the per-scan timing
        ms = time_per_scan(detector, scans, args.repeats)
        if affinity:
            os.sched_setaffinity(0, affinity)
        rate = scans_per_second(detector, scans, args.repeats)
        print(f"| {label} | {scans[0].n_beams} | {len(scans)} | {kp:.2f} | "
              f"{np.median(ms):.3f} | {np.percentile(ms, 95):.3f} | {rate:,.0f} |")  # fmt: skip
    return 0


if __name__ == "__main__":
    sys.exit(main())
