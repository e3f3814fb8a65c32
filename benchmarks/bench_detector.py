"""Benchmark of the detector kernel against the frozen kernel of main at 91ca792, same process.

Usage::

    PYTHONPATH=src .venv/bin/python benchmarks/bench_detector.py [--repeats 5]

Data sets: simulated Hokuyo UST-10LX scans (1081 beams, 270 deg, 0.25 deg) from random poses
in the demo world (an L-shaped room with a pillar) at range noise 0, 0.01 and 0.03 m; the
first scans of every log in ../shared/data/real (aces.bag, intel.bag: 180 beams; fr079.bag:
360; hokuyo270_rooms.bag /left_scan, /rear_scan, /right_scan: 768) (read once, not timed);
and a mostly-empty 180-beam set: the intel.bag scans with 85 % of their beams (drawn with a
fixed seed) replaced by max-range readings, i.e. no return (what a 180-beam scanner sees in
open space). The paper preset, one ``detect`` call per scan, on one core
(``os.sched_setaffinity``, numba threads 1), after a warm-up; the old and the new kernel
alternate scan by scan. Per data set: the median over the scans of each scan's best time
over the repeats, for the frozen kernel (``benchmarks/frozen_kernel_91ca792.py``) and the new
one, and their ratio new/old. The keypoints of both kernels are compared on every scan
(count and position to 1e-9 m).

``detect`` returns keypoints whose arrays are made on the first access of any of them and
whose covariances on the first access of ``Keypoints.cov``: ``+xy ms`` is ``detect`` then
reading ``.xy`` (what a user of the positions pays), and the covariances are timed apart
(accessing ``.cov`` of freshly detected keypoints, best over the repeats per scan): the
median per scan and the total over the total number of keypoints (us per keypoint).
``many/one`` is ``detect_many`` over ``detect``, time per scan in CPU time of the process
(:func:`batch_ratio`). ``FALKO ms`` is falkolib (the FALKO authors'
C++, ``-O3``, one core, best of 5 per scan), measured earlier on this machine type, not in
this run (issue 21); ``new/FALKO`` compares it with this run's ``new ms``, ``adj new/FALKO``
with this run's new/old times the frozen kernel's ms on the unloaded machine of FALKO's
figures (:data:`OLD_MS_UNLOADED`; a fair yardstick when other processes slow this run).

Then the scaling in beam count: a synthetic 360-degree scan of a polygonal room (the demo
world) with 100,000, 400,000 and 1,000,000 beams at range noise 0.001 m, timed in rounds
(``--scaling-repeats``, default 7, at least 5) in each of which the three sizes alternate,
in CPU time of the thread (these calls take seconds, long enough for other processes on a
shared machine to distort wall-clock times): the best and the median per size, and
time(400k)/time(100k) and time(1M)/time(400k) of the bests and of the medians (a slow spell
of the machine falls on every size alike); ``--scaling-only`` skips the per-scan tables.
Whether the keypoints at each size are those of main at 08b9988, before the jumping walk
(``dense_keypoints_08b9988.json``); then the same scans with 2 % of the beams dropped and
``max_gap_beams=2`` (dropouts bridged), against the keypoints of main at 19fb21a
(``dense_bridging_keypoints_19fb21a.json``).
"""

from __future__ import annotations

import argparse
import importlib.util
import json
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

HERE = Path(__file__).resolve().parent
REAL = HERE.parent / ".." / "shared" / "data" / "real"
DENSE_REFERENCE = HERE / "dense_keypoints_08b9988.json"  # see same_as_stored
# the dense scans with 2 % dropouts bridged (max_gap_beams=2), by main at 19fb21a, whose walk
# took 5.1 s at 400,000 beams and 31 s at 1,000,000 (blocks holding a gap were never skipped)
BRIDGING_REFERENCE = HERE / "dense_bridging_keypoints_19fb21a.json"
REAL_SETS = [
    ("aces.bag", "/scan"),
    ("intel.bag", "/scan"),
    ("fr079.bag", "/scan"),
    ("hokuyo270_rooms.bag", "/left_scan"),
    ("hokuyo270_rooms.bag", "/rear_scan"),
    ("hokuyo270_rooms.bag", "/right_scan"),
]
EMPTY_LABEL = "intel.bag, 85 % of beams no return"
# the frozen kernel's ms per scan on an unloaded machine (README's run of 2026-12-01 17:24 UTC,
# load average below 0.5, the conditions of FALKO_MS): on a loaded machine, FALKO's time is
# compared with new/old of this run times these (``adj new/FALKO``)
OLD_MS_UNLOADED = {
    "simulated UST-10LX, noise 0.01 m": 0.2609,
    "intel.bag /scan": 0.0284,
    "fr079.bag /scan": 0.0683,
    "hokuyo270_rooms.bag /left_scan": 0.1027,
}
# falkolib ms per scan (C++ -O3, one core, best of 5 per scan), measured side by side with
# this project's detector on this machine type before this release (issue 21), not in this run
FALKO_MS = {
    "simulated UST-10LX, noise 0.01 m": 0.133,
    "aces.bag /scan": 0.013,
    "intel.bag /scan": 0.012,
    "fr079.bag /scan": 0.041,
    "hokuyo270_rooms.bag /left_scan": 0.059,
    EMPTY_LABEL: 0.008,
}


def frozen_detector_class() -> type:
    """``CornerDetector`` of the frozen kernel (its own module, hence its own numba cache)."""
    path = HERE / "frozen_kernel_91ca792.py"
    spec = importlib.util.spec_from_file_location("frozen_kernel_91ca792", path)
    module = importlib.util.module_from_spec(spec)  # type: ignore[arg-type]
    sys.modules[spec.name] = module  # numba's cache re-imports the module by name
    spec.loader.exec_module(module)  # type: ignore[union-attr]
    return module.CornerDetector


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
    from laser_corners.io import open_scans

    scans = []
    for scan in open_scans(path, topic=topic):
        scans.append(scan)
        if len(scans) >= limit:
            break
    return scans


def mostly_empty(scans: list[LaserScan], fraction: float = 0.85, seed: int = 0) -> list[LaserScan]:
    """The scans with ``fraction`` of their beams (drawn with ``seed``) replaced by max-range
    readings: no return, as a scanner sees in open space."""
    rng = np.random.default_rng(seed)
    out = []
    for scan in scans:
        ranges = np.array(scan.ranges)
        ranges[rng.random(ranges.shape[0]) < fraction] = scan.range_max
        geometry = (scan.angle_min, scan.angle_increment, scan.range_min, scan.range_max)
        out.append(LaserScan(ranges, *geometry, scan.stamp, scan.frame_id))
    return out


def dense_scan(
    n_beams: int, noise_sigma: float = 0.001, seed: int = 0, dropouts: float = 0.0
) -> LaserScan:
    """A 360-degree scan of the demo world with ``n_beams`` beams; ``dropouts``: the fraction
    of beams (drawn with ``seed + 1``) that return nothing (NaN)."""
    inc = 2 * np.pi / n_beams
    angles = -np.pi + inc * np.arange(n_beams)
    ranges = demo_world().cast((0.4, -0.3, 0.25), angles)
    ranges = ranges + np.random.default_rng(seed).normal(0.0, noise_sigma, n_beams)
    if dropouts > 0.0:
        ranges[np.random.default_rng(seed + 1).random(n_beams) < dropouts] = np.nan
    return LaserScan(ranges, -np.pi, inc, 0.02, 30.0)


def same_keypoints(a: object, b: object) -> bool:
    return len(a) == len(b) and bool(np.allclose(a.xy, b.xy, atol=1e-9, rtol=0))  # type: ignore[arg-type, attr-defined]


def compare(old: object, new: CornerDetector, scans: list[LaserScan], repeats: int) -> tuple:
    """Per-scan best times (ms) of both detectors, alternating, of ``detect`` then ``.xy``,
    and whether they agree."""
    best_old = np.full(len(scans), np.inf)
    best_new = np.full(len(scans), np.inf)
    best_xy = np.full(len(scans), np.inf)
    agree = True
    for scan in scans[:20]:  # warm-up
        old.detect(scan)  # type: ignore[attr-defined]
        new.detect(scan)
    for _ in range(repeats):
        for i, scan in enumerate(scans):
            t0 = time.perf_counter()
            a = old.detect(scan)  # type: ignore[attr-defined]
            t1 = time.perf_counter()
            b = new.detect(scan)
            t2 = time.perf_counter()
            new.detect(scan).xy  # noqa: B018  (the first access makes the arrays)
            t3 = time.perf_counter()
            best_old[i] = min(best_old[i], t1 - t0)
            best_new[i] = min(best_new[i], t2 - t1)
            best_xy[i] = min(best_xy[i], t3 - t2)
            agree &= same_keypoints(a, b)
    return best_old * 1e3, best_new * 1e3, best_xy * 1e3, agree


def batch_ratio(new: CornerDetector, scans: list[LaserScan], repeats: int, size: int = 10):
    """``detect_many`` over ``detect``, time per scan: CPU time of the process (robust to
    other processes, and it counts numba's worker threads), batches of 10 interleaved with
    ``detect`` of the same 10 scans, timed as a whole too (the best of a sum is not the sum of
    the bests), each first on alternate repeats, best over the repeats, median over scans."""
    new.detect_many(scans[:size])  # warm-up
    many = np.full(len(scans), np.inf)
    one = np.full(len(scans), np.inf)
    clock = time.process_time_ns

    def time_many(b: int, batch: list[LaserScan]) -> None:
        t0 = clock()
        new.detect_many(batch)
        many[b : b + len(batch)] = np.minimum(many[b : b + len(batch)], (clock() - t0) / len(batch))

    def time_one(b: int, batch: list[LaserScan]) -> None:  # the batch as a whole, like many
        t0 = clock()
        for scan in batch:
            new.detect(scan)
        one[b : b + len(batch)] = np.minimum(one[b : b + len(batch)], (clock() - t0) / len(batch))

    for r in range(repeats):  # which goes first (warm caches) alternates over the repeats
        for b in range(0, len(scans), size):
            for timer in (time_many, time_one) if r % 2 == 0 else (time_one, time_many):
                timer(b, scans[b : b + size])
    return float(np.median(many) / np.median(one))


def covariance_cost(new: CornerDetector, scans: list[LaserScan], repeats: int) -> tuple:
    """Cost of the lazy covariance: median us per scan and us per keypoint."""
    best = np.full(len(scans), np.inf)
    n_kp = np.zeros(len(scans))
    for _ in range(repeats):
        for i, scan in enumerate(scans):
            kps = new.detect(scan)
            t0 = time.perf_counter()
            _ = kps.cov
            best[i] = min(best[i], time.perf_counter() - t0)
            n_kp[i] = len(kps)
    return float(np.median(best)) * 1e6, float(best.sum() / max(n_kp.sum(), 1)) * 1e6


def same_as_stored(keypoints: object, n_beams: int, reference: Path = DENSE_REFERENCE) -> str:
    """Whether ``keypoints`` of :func:`dense_scan` are those stored in ``reference`` (count,
    beam index, position to 1e-9 m): the kernel at 08b9988 (:data:`DENSE_REFERENCE`; its
    1,000,000-beam scan takes the frozen kernel minutes) or, with dropouts bridged, at 19fb21a
    (:data:`BRIDGING_REFERENCE`)."""
    stored = json.loads(reference.read_text(encoding="utf-8"))["keypoints"].get(str(n_beams))
    if stored is None:
        return "-"
    xy = np.asarray(stored["xy"], dtype=np.float64).reshape(-1, 2)
    same = len(keypoints) == xy.shape[0] and bool(  # type: ignore[arg-type]
        np.array_equal(keypoints.beam_index, stored["beam_index"])  # type: ignore[attr-defined]
        and np.allclose(keypoints.xy, xy, atol=1e-9, rtol=0)  # type: ignore[attr-defined]
    )
    return "yes" if same else "NO"


SIZES = (100_000, 400_000, 1_000_000)


def alternating_times(detector: CornerDetector, scans: dict[int, LaserScan], repeats: int):
    """CPU times of the calling thread (``time.thread_time``: robust to other processes) of
    ``detect`` on each scan, the sizes alternating within each of ``repeats`` rounds (a slow
    spell of the machine then falls on every size alike); returns the times per size and the
    keypoints of the last round."""
    times: dict[int, list[float]] = {n: [] for n in scans}
    keypoints = {}
    for _ in range(repeats):
        for n, scan in scans.items():
            t0 = time.thread_time()
            keypoints[n] = detector.detect(scan)
            times[n].append(time.thread_time() - t0)
    return times, keypoints


def ratio_line(times: dict[int, list[float]]) -> str:
    """time(400k)/time(100k) and time(1M)/time(400k), of the minima (best per size) and of
    the medians."""
    lo, mid, hi = (times[n] for n in SIZES)
    best = f"{min(mid) / min(lo):.1f}, {min(hi) / min(mid):.2f}"
    median = f"{np.median(mid) / np.median(lo):.1f}, {np.median(hi) / np.median(mid):.2f}"
    return (
        f"time(400k)/time(100k), time(1M)/time(400k): best of {len(lo)} per size {best}; "
        f"median {median}"
    )


def scaling(old: object, new: CornerDetector, with_old: bool, repeats: int) -> None:
    print("\nScaling, synthetic 360-degree scan of the demo world, noise 0.001 m, CPU time of")
    print(f"the calling thread, the sizes alternating in each of {repeats} rounds: best and")
    print("median per size; the frozen kernel once at 100,000 and 400,000 beams only (it")
    print(f"takes minutes at 1,000,000); same kp 08b9988: those of {DENSE_REFERENCE.name}")
    print("| beams | keypoints | new s (best) | new s (median) | old s | same kp 08b9988 |")
    print("|---:|---:|---:|---:|---:|---|")
    scans = {n: dense_scan(n) for n in SIZES}
    new.detect(scans[SIZES[0]])  # warm-up
    times, kp = alternating_times(new, scans, repeats)
    old_times = {}
    for n in SIZES:
        old_s = "-"
        if with_old and n <= 400_000:
            t0 = time.thread_time()
            old_kp = old.detect(scans[n])  # type: ignore[attr-defined]
            old_times[n] = time.thread_time() - t0
            old_s = f"{old_times[n]:.3f}"
            if not same_keypoints(old_kp, kp[n]):
                print(f"  WARNING: keypoints differ from the frozen kernel's at {n} beams")
        same = same_as_stored(kp[n], n)
        best, median = min(times[n]), float(np.median(times[n]))
        print(f"| {n:,} | {len(kp[n])} | {best:.3f} | {median:.3f} | {old_s} | {same} |")
    print(f"\n{ratio_line(times)}")
    if old_times:
        print(f"old: time(400k)/time(100k) {old_times[400_000] / old_times[100_000]:.1f}")


def bridging_scaling(repeats: int) -> None:
    """The dense scans with 2 % of the beams dropped (NaN) and ``max_gap_beams=2``: the
    walk bridges the dropouts."""
    print("\nBridging, the same scans with 2 % of the beams dropped (NaN), max_gap_beams=2,")
    print(f"sizes alternating in {repeats} rounds, CPU time; same kp 19fb21a: the keypoints of")
    print(f"main at 19fb21a ({BRIDGING_REFERENCE.name})")
    print("| beams | keypoints | new s (best) | new s (median) | same kp 19fb21a |")
    print("|---:|---:|---:|---:|---|")
    detector = CornerDetector(DetectorParams(max_gap_beams=2))
    scans = {n: dense_scan(n, dropouts=0.02) for n in SIZES}
    detector.detect(scans[SIZES[0]])  # warm-up
    times, kp = alternating_times(detector, scans, repeats)
    for n in SIZES:
        same = same_as_stored(kp[n], n, BRIDGING_REFERENCE)
        best, median = min(times[n]), float(np.median(times[n]))
        print(f"| {n:,} | {len(kp[n])} | {best:.3f} | {median:.3f} | {same} |")
    print(f"\n{ratio_line(times)}")


CONTROL_DENSITIES = (400_000, 1_000_000)  # beams per 360 degrees
CONTROL_WINDOWS = (100_000, 200_000, 400_000, 0)  # beams per detect call (0: the whole scan)


def windows(scan: LaserScan, size: int) -> list[LaserScan]:
    """``scan`` cut into consecutive scans of ``size`` beams (the last one shorter; ``size``
    0: the whole scan), each with its own ``angle_min``: the same points, the same noise."""
    if size <= 0 or size >= scan.n_beams:
        return [scan]
    geometry = (scan.angle_increment, scan.range_min, scan.range_max)
    return [
        LaserScan(scan.ranges[s : s + size], scan.angle_min + s * scan.angle_increment, *geometry)
        for s in range(0, scan.n_beams, size)
    ]


def scaling_control(repeats: int) -> None:
    """Density or size (issue 21): ns per beam of ``detect`` on the dense scan of each
    density in :data:`CONTROL_DENSITIES`, cut into windows of each size in
    :data:`CONTROL_WINDOWS` (one ``detect`` per window, the times summed over the windows
    that cover the 360 degrees); the configurations alternate in each round, CPU time of
    the thread. Along a row the density is fixed and the size per call grows; down a
    column the size is fixed and the density grows."""
    detector = CornerDetector(DetectorParams())
    cases = {
        (d, w): windows(dense_scan(d), w)
        for d in CONTROL_DENSITIES
        for w in CONTROL_WINDOWS
        if w < d
    }
    detector.detect(cases[(CONTROL_DENSITIES[0], CONTROL_WINDOWS[0])][0])  # warm-up
    times: dict[tuple[int, int], list[float]] = {c: [] for c in cases}
    for _ in range(repeats):
        for case, scans in cases.items():
            total = 0.0
            for scan in scans:
                t0 = time.thread_time()
                detector.detect(scan)
                total += time.thread_time() - t0
            times[case].append(total / case[0] * 1e9)
    print("\nScaling control (density or size?): the dense scan of each density (beams per")
    print("360 degrees, noise 0.001 m) cut into windows of w beams, one detect per window,")
    print(f"ns per beam over the whole scan, best / median of {repeats} rounds (alternating)")
    head = [f"w = {w:,}" if w else "w = whole scan" for w in CONTROL_WINDOWS]
    print("| beams per 360 deg | " + " | ".join(head) + " |")
    print("|---:|" + "---:|" * len(CONTROL_WINDOWS))
    for d in CONTROL_DENSITIES:
        cells = [
            f"{min(times[(d, w)]):.0f} / {np.median(times[(d, w)]):.0f}" if (d, w) in times else "-"
            for w in CONTROL_WINDOWS
        ]
        print(f"| {d:,} | " + " | ".join(cells) + " |")
    lo, hi = CONTROL_DENSITIES
    small, whole = CONTROL_WINDOWS[0], CONTROL_WINDOWS[-1]
    density = min(times[(hi, small)]) / min(times[(lo, small)])
    size = min(times[(hi, whole)]) / min(times[(hi, small)])
    print(
        f"\nbest ns/beam, density x{hi / lo:.1f} at w = {small:,}: x{density:.2f}; "
        f"size x{hi / small:.0f} at {hi:,} beams per 360 deg: x{size:.2f}"
    )


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--sim-scans", type=int, default=400)
    parser.add_argument("--real-scans", type=int, default=1000)
    parser.add_argument(
        "--scaling-repeats",
        type=int,
        default=7,
        help="rounds of the scaling and bridging lines (sizes alternating; at least 5)",
    )
    parser.add_argument("--scaling-only", action="store_true", help="only the dense scans")
    parser.add_argument(
        "--skip-old-scaling",
        action="store_true",
        help="do not time the frozen kernel on the dense scans (slow)",
    )
    parser.add_argument(
        "--scaling-control",
        action="store_true",
        help="only the control of the scaling: density or size (windows of the dense scans)",
    )
    args = parser.parse_args()
    if args.scaling_repeats < 5:
        parser.error("--scaling-repeats: at least 5 (min and median of fewer mislead)")

    numba.set_num_threads(1)
    if hasattr(os, "sched_setaffinity"):
        os.sched_setaffinity(0, {min(os.sched_getaffinity(0))})
    old = frozen_detector_class()(DetectorParams())
    new = CornerDetector(DetectorParams())
    print(
        f"python {platform.python_version()}, numba {numba.__version__}, pinned to one core, "
        f"numba threads {numba.get_num_threads()}, paper preset, best of {args.repeats} "
        "per scan, median over scans\n"
    )
    if args.scaling_control:
        scaling_control(args.scaling_repeats)
        return 0
    if not args.scaling_only:
        scan_tables(old, new, args)
    scaling(old, new, not args.skip_old_scaling, args.scaling_repeats)
    bridging_scaling(args.scaling_repeats)
    return 0


def scan_tables(old: object, new: CornerDetector, args: argparse.Namespace) -> None:
    """The per-scan table of every data set (see the module's docstring)."""
    sets: list[tuple[str, list[LaserScan] | str]] = [
        (f"simulated UST-10LX, noise {sigma} m", simulated_scans(args.sim_scans, noise_sigma=sigma))
        for sigma in (0.0, 0.01, 0.03)
    ]
    for name, topic in REAL_SETS:
        sets.append((f"{name} {topic}", real_scans(name, topic, args.real_scans)))
    intel = dict(sets).get("intel.bag /scan")
    empty = mostly_empty(intel) if isinstance(intel, list) else "skipped: intel.bag not found"
    sets.append((EMPTY_LABEL, empty))

    columns = ["data set", "beams", "scans", "kp/scan", "old ms", "new ms", "new/old", "same kp"]
    columns += ["+xy ms", "many/one", "FALKO ms", "new/FALKO", "adj new/FALKO", "cov us/scan"]
    columns += ["cov us/kp"]
    print("| " + " | ".join(columns) + " |")
    print("|---|" + "---:|" * 6 + "---|" + "---:|" * 7)
    for label, scans in sets:
        if isinstance(scans, str):
            print(f"| {label} | | | | {scans} |" + " |" * 10)
            continue
        ms_old, ms_new, ms_xy, agree = compare(old, new, scans, args.repeats)
        kp = np.mean([len(new.detect(s)) for s in scans])
        m_old, m_new, m_xy = np.median(ms_old), np.median(ms_new), np.median(ms_xy)
        many = batch_ratio(new, scans, args.repeats)
        falko = FALKO_MS.get(label)
        falko_s = f"{falko:.3f} | {m_new / falko:.2f}" if falko else "- | -"
        unloaded = OLD_MS_UNLOADED.get(label)
        adjusted = f"{m_new / m_old * unloaded / falko:.2f}" if falko and unloaded else "-"
        cov_scan, cov_kp = covariance_cost(new, scans, args.repeats)
        cells = [label, scans[0].n_beams, len(scans), f"{kp:.2f}", f"{m_old:.4f}", f"{m_new:.4f}"]
        cells += [f"{m_new / m_old:.2f}", "yes" if agree else "NO", f"{m_xy:.4f}", f"{many:.2f}"]
        cells += [falko_s, adjusted, f"{cov_scan:.1f}", f"{cov_kp:.2f}"]
        print("| " + " | ".join(str(c) for c in cells) + " |")


if __name__ == "__main__":
    sys.exit(main())
