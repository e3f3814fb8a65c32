"""Two kernels' ``candidates`` alternating in one process, on the dense scans (issue 21).

Usage::

    taskset -c 1 env PYTHONPATH=src .venv/bin/python benchmarks/ab_candidates.py \\
        --old ../main/src/laser_corners [--rounds 6] [--detect | --real-bridging N]

``--old`` is another checkout's package folder; it is copied to a temporary folder under the
name ``lc_old`` (its imports rewritten), so both kernels load in one process and alternate round
by round (the order swapping each round): a slow spell of a shared machine falls on both alike,
where separate processes minutes apart differ by 20 % from load alone. Checks that both give the
same candidates at 400,000 and 1,000,000 beams, then prints the best and the median seconds per
size of each and their time(1M)/time(400k). ``--detect`` times the detectors' whole ``detect``
instead (same keypoints checked); ``--real-bridging N`` times ``detect`` with
``max_gap_beams=2`` on the first N scans of every real log, scan by scan. Two identical kernels
(this branch's and main's at a796458) gave best 0.380 / 0.386 s at 400k and 1.303 / 1.257 s at
1M (2026-12-02 08:19 UTC, load 0.9-1.7, ``--rounds 4``): differences under 4 % are noise.
"""

from __future__ import annotations

import argparse
import re
import shutil
import sys
import tempfile
import time
from pathlib import Path

import numba as nb
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from bench_detector import REAL_SETS, dense_scan, real_scans
from laser_corners.kernel import candidates as new_kernel
from laser_corners.params import DetectorParams

SIZES = (400_000, 1_000_000)


def load_old(package: Path, into: Path):  # type: ignore[no-untyped-def]
    """The ``candidates`` module of the package folder ``package``, as ``lc_old``."""
    copy = into / "lc_old"
    shutil.copytree(package, copy, ignore=shutil.ignore_patterns("__pycache__"))
    for path in copy.rglob("*.py"):
        text = path.read_text(encoding="utf-8")
        text = re.sub(r"\blaser_corners\b", "lc_old", text)
        path.write_text(text, encoding="utf-8")
    sys.path.insert(0, str(into))
    from lc_old.kernel import candidates  # type: ignore[import-not-found]

    return candidates


def detect_ab(old_package: Path, rounds: int) -> None:
    """``--detect``: the whole ``detect`` of both packages alternating (paper preset; the
    sizes and the order alternating each round), best and median seconds per size."""
    import lc_old  # type: ignore[import-not-found]  (made importable by load_old)

    from laser_corners import CornerDetector

    new = CornerDetector(DetectorParams())
    old = lc_old.CornerDetector(lc_old.DetectorParams())
    detectors = {"old": old, "new": new}
    scans = {("new", n): dense_scan(n) for n in SIZES}
    for n in SIZES:  # the same scan as each package's own LaserScan
        s = scans["new", n]
        geometry = (s.angle_min, s.angle_increment, s.range_min, s.range_max)
        scans["old", n] = lc_old.LaserScan(s.ranges, *geometry)
    for label, detector in detectors.items():
        detector.detect(scans[label, SIZES[0]])  # compile or load
    for n in SIZES:
        a, b = old.detect(scans["old", n]), new.detect(scans["new", n])
        same = len(a) == len(b) and np.allclose(a.xy, b.xy, atol=1e-9, rtol=0)
        print(f"{n:,} beams: same keypoints {'yes' if same else 'NO'}")
    times: dict[tuple[str, int], list[float]] = {}
    for r in range(rounds):
        order = ("old", "new") if r % 2 == 0 else ("new", "old")
        for n in SIZES:
            for label in order:
                t0 = time.thread_time()
                detectors[label].detect(scans[label, n])
                times.setdefault((label, n), []).append(time.thread_time() - t0)
    report(times, "detect")


def bridging_ab(rounds: int, limit: int) -> None:
    """``--real-bridging N``: ``detect`` with ``max_gap_beams=2`` (the ``auto`` / ``robust``
    setting, which always takes the dense walk) on the first N scans of every real log, both
    packages alternating scan by scan; the median over scans of each scan's best time (ms)."""
    import lc_old  # type: ignore[import-not-found]  (made importable by load_old)

    from laser_corners import CornerDetector

    detectors = {
        "old": lc_old.CornerDetector(lc_old.DetectorParams(max_gap_beams=2)),
        "new": CornerDetector(DetectorParams(max_gap_beams=2)),
    }
    print("| log | scans | old ms | new ms | new/old | same kp |")
    print("|---|---:|---:|---:|---:|---|")
    for name, topic in REAL_SETS:
        scans = real_scans(name, topic, limit)
        if isinstance(scans, str):
            print(f"| {name} {topic} | {scans} | | | | |")
            continue
        olds = [
            lc_old.LaserScan(s.ranges, s.angle_min, s.angle_increment, s.range_min, s.range_max)
            for s in scans
        ]
        pairs = {"old": olds, "new": scans}
        best = {label: np.full(len(scans), np.inf) for label in detectors}
        same = True
        for r in range(rounds):
            order = ("old", "new") if r % 2 == 0 else ("new", "old")
            for i in range(len(scans)):
                found = {}
                for label in order:
                    t0 = time.perf_counter()
                    found[label] = detectors[label].detect(pairs[label][i])
                    best[label][i] = min(best[label][i], time.perf_counter() - t0)
                a, b = found["old"], found["new"]
                same &= len(a) == len(b) and bool(np.allclose(a.xy, b.xy, atol=1e-9, rtol=0))
        old_ms, new_ms = (float(np.median(best[k])) * 1e3 for k in ("old", "new"))
        cells = f"{old_ms:.4f} | {new_ms:.4f} | {new_ms / old_ms:.2f} | {'yes' if same else 'NO'}"
        print(f"| {name} {topic} | {len(scans)} | {cells} |")


def report(times: dict[tuple[str, int], list[float]], what: str) -> None:
    """Best and median per kernel and size, and their time(1M)/time(400k)."""
    for label in ("old", "new"):
        lo, hi = times[label, SIZES[0]], times[label, SIZES[1]]
        print(
            f"{label} {what}: 400k best {min(lo):.3f} median {np.median(lo):.3f} s; 1M best "
            f"{min(hi):.3f} median {np.median(hi):.3f} s; 1M/400k best "
            f"{min(hi) / min(lo):.2f} median {np.median(hi) / np.median(lo):.2f}"
        )


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--old", type=Path, required=True, help="another laser_corners folder")
    parser.add_argument("--rounds", type=int, default=6)
    parser.add_argument("--detect", action="store_true", help="time detect, not candidates")
    parser.add_argument(
        "--real-bridging", type=int, default=0, help="N: detect with bridging on real logs"
    )
    args = parser.parse_args()
    nb.set_num_threads(1)
    with tempfile.TemporaryDirectory() as tmp:
        if args.real_bridging > 0:
            load_old(args.old.resolve(), Path(tmp))
            bridging_ab(args.rounds, args.real_bridging)
            return 0
        if args.detect:
            load_old(args.old.resolve(), Path(tmp))
            detect_ab(args.old, args.rounds)
            return 0
        kernels = {"old": load_old(args.old.resolve(), Path(tmp)), "new": new_kernel}
        packed = new_kernel.kernel_config(DetectorParams())
        points = {}
        for n in SIZES:
            scan = dense_scan(n)
            angles = scan.angle_min + scan.angle_increment * np.arange(n)
            x, y = np.empty(n), np.empty(n)
            lo, hi = scan.range_min, scan.range_max
            new_kernel.polar_to_xy(scan.ranges, np.cos(angles), np.sin(angles), lo, hi, x, y)
            points[n] = (x, y)
        cands = {}
        for label, kernel in kernels.items():
            for n in SIZES:
                cands[label, n] = np.empty((n, new_kernel.NC))
                kernel.candidates(*points[n], packed, cands[label, n], np.empty((0, 0, 3)))
        for n in SIZES:
            a, b = cands["old", n], cands["new", n]
            same = np.array_equal(a[:, 2] > 0, b[:, 2] > 0)
            same = same and np.allclose(a[a[:, 2] > 0], b[b[:, 2] > 0], equal_nan=True)
            print(f"{n:,} beams: same candidates {'yes' if same else 'NO'}")
        times: dict[tuple[str, int], list[float]] = {}
        for r in range(args.rounds):
            order = ("old", "new") if r % 2 == 0 else ("new", "old")
            for n in SIZES:
                for label in order:
                    t0 = time.thread_time()
                    kernels[label].candidates(
                        *points[n], packed, cands[label, n], np.empty((0, 0, 3))
                    )
                    times.setdefault((label, n), []).append(time.thread_time() - t0)
        report(times, "candidates")
    return 0


if __name__ == "__main__":
    sys.exit(main())
