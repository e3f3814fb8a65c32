"""Where a dense scan's ``detect`` spends its time, phase by phase (issue 21, scaling).

Usage::

    taskset -c 1 env PYTHONPATH=src .venv/bin/python benchmarks/profile_dense.py [--rounds 5]
        [--span-jitter]

The scans of ``bench_detector.py``'s scaling lines (a 360-degree scan of the demo world,
noise 0.001 m, 100,000 / 400,000 / 1,000,000 beams), paper preset, one numba thread. Each
phase is one of the kernel's own functions called on its own (so its output arrays are
allocated fresh, as in ``detect``), in CPU time of the thread, the sizes alternating in
each round; per phase and size the best and the median over the rounds, in ns per beam:

- ``polar``: ranges -> points (:func:`~laser_corners.kernel.candidates.polar_to_xy`);
- ``prepare``: validity and prefix sums (48 bytes per beam, fresh);
- ``padded``, ``links``, ``points_within``: the walks' small tables and the density test;
- ``boxes``: the oriented block boxes (:func:`~laser_corners.kernel.boxes.block_boxes`,
  a sparse table of 60 bytes per beam, fresh);
- ``sentinel walks``: the dense walk of every point to the sentinel scales, both sides (what
  every point pays), and ``+ screens`` with the sentinel screens;
- ``candidates``: the whole phase 1-5 call (:func:`~laser_corners.kernel.candidates.candidates`);
  ``rest`` is it minus the phases above: the points whose sentinels pass (their other
  scales' walks, screens and exact tests) and the candidate table (56 bytes per beam, fresh);
- ``finish``: merging; ``detect``: the detector's whole call.

``--span-jitter`` (issue 21's control of the walk): the sentinel walks alone, ns per point,
on the 400,000- and 1,000,000-beam scans with the paper's scales and with every scale times
2.5 or 0.4, alternating in each round. The scales set how many beams a neighbourhood spans
(the walk's reach: its jumps' lengths, the reuse distance of the data it reads); the density
sets how many beams the range noise spans (σ / spacing: how far a bound moves from one point
to the next, the miss of the walk's guesses). 400k x2.5 has 1M's span and 400k's jitter,
1M x0.4 400k's span and 1M's jitter.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numba as nb
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from bench_detector import SIZES, dense_scan
from laser_corners import CornerDetector, DetectorParams
from laser_corners.kernel.candidates import (
    NC,
    _limits,
    _sentinels,
    candidates,
    kernel_config,
    polar_to_xy,
    unpack,
)
from laser_corners.kernel.merge import NM, finish
from laser_corners.kernel.neighbourhood import (
    block_boxes,
    links,
    padded,
    points_within,
    prepare,
    walk,
)
from laser_corners.kernel.scale_tests import screen
from laser_corners.params import PAPER_SCALES


@nb.njit(cache=True, nogil=True)
def sentinel_walks(x, y, valid, lk, box, packed, ps, with_screens: bool) -> int:  # type: ignore[no-untyped-def]
    """The sentinel walks of every valid point (as in ``candidates``' dense branch), with
    the sentinel screens when ``with_screens``; returns the number of screens passed."""
    cfg = unpack(packed)
    n = x.shape[0]
    r2 = cfg.scales * cfg.scales
    r2_sent, s_start, s_stop = _sentinels(r2, cfg.min_consecutive_scales, n)[6:]
    loose_mse, max_cos2 = _limits(cfg)[1:3]
    inv = 1.0 / np.arange(n + 2)
    hits = 0
    for j in range(n):
        if not valid[j]:
            continue
        walk(j, -1, x, y, valid, lk, box, r2_sent, 0, s_start)
        walk(j, 1, x, y, valid, lk, box, r2_sent, 0, s_stop)
        if with_screens:
            for i in range(r2_sent.shape[0]):
                s, e = s_start[i], s_stop[i]
                hits += screen(ps, inv, j, s, e, cfg.min_points, loose_mse, max_cos2, False)
    return hits


def phases(scan, packed, detector) -> dict[str, float]:  # type: ignore[no-untyped-def]
    """CPU seconds of each phase on ``scan`` (see the module's docstring)."""
    n = scan.n_beams
    angles = scan.angle_min + scan.angle_increment * np.arange(n)
    cos_a, sin_a = np.cos(angles), np.sin(angles)
    x, y = np.empty(n), np.empty(n)
    clock = time.thread_time
    out: dict[str, float] = {}
    t = clock()
    polar_to_xy(scan.ranges, cos_a, sin_a, scan.range_min, scan.range_max, x, y)
    out["polar"] = clock() - t
    t = clock()
    valid, _, _, ps = prepare(x, y)
    out["prepare"] = clock() - t
    t = clock()
    px, py = padded(x, y, valid)
    out["padded"] = clock() - t
    t = clock()
    next_valid, prev_valid = links(valid)
    out["links"] = clock() - t
    t = clock()
    points_within(x, y, valid, float(unpack(packed).scales[-1]))
    out["points_within"] = clock() - t
    t = clock()
    box = block_boxes(x, y, valid, 0, True)
    out["boxes"] = clock() - t
    lk = (next_valid, prev_valid, px, py)
    t = clock()
    sentinel_walks(x, y, valid, lk, box, packed, ps, False)
    out["sentinel walks"] = clock() - t
    t = clock()
    sentinel_walks(x, y, valid, lk, box, packed, ps, True)
    out["+ screens"] = clock() - t
    cand = np.empty((n, NC))
    t = clock()
    candidates(x, y, packed, cand, np.empty((0, 0, 3)))
    out["candidates"] = clock() - t
    setup = sum(out[k] for k in ("prepare", "padded", "links", "points_within", "boxes"))
    out["rest"] = out["candidates"] - setup - out["+ screens"]
    t = clock()
    finish(x, y, cand, packed, np.empty((n, NM)))
    out["finish"] = clock() - t
    t = clock()
    detector.detect(scan)
    out["detect"] = clock() - t
    return out


def walk_tables(scan) -> tuple:  # type: ignore[no-untyped-def]
    """The arguments of :func:`sentinel_walks` for ``scan`` (points, tables, boxes)."""
    n = scan.n_beams
    angles = scan.angle_min + scan.angle_increment * np.arange(n)
    x, y = np.empty(n), np.empty(n)
    polar_to_xy(scan.ranges, np.cos(angles), np.sin(angles), scan.range_min, scan.range_max, x, y)
    valid, _, _, ps = prepare(x, y)
    lk = (*links(valid), *padded(x, y, valid))
    return x, y, valid, lk, block_boxes(x, y, valid, 0, True), ps


def span_jitter(rounds: int) -> None:
    """The sentinel walks with the scales scaled (see the module's docstring)."""
    tables = {n: walk_tables(dense_scan(n)) for n in (400_000, 1_000_000)}
    cases = [(400_000, 1.0), (400_000, 2.5), (1_000_000, 0.4), (1_000_000, 1.0)]
    packed = {
        f: kernel_config(DetectorParams(scales=tuple(s * f for s in PAPER_SCALES)))
        for _, f in cases
    }
    x, y, valid, lk, box, ps = tables[400_000]
    sentinel_walks(x, y, valid, lk, box, packed[1.0], ps, False)  # compile or load
    times: dict[tuple[int, float, bool], list[float]] = {}
    for _ in range(rounds):
        for n, f in cases:
            x, y, valid, lk, box, ps = tables[n]
            for screens in (False, True):
                t = time.thread_time()
                sentinel_walks(x, y, valid, lk, box, packed[f], ps, screens)
                dt = (time.thread_time() - t) / n * 1e9
                times.setdefault((n, f, screens), []).append(dt)
    print(f"sentinel walks (+ their screens), ns per point, best / median of {rounds} rounds")
    print("| beams | scales | span (x 400k's) | jitter (x 400k's) | walks | + screens |")
    print("|---:|---:|---:|---:|---:|---:|")
    for n, f in cases:
        span, jitter = f * n / 400_000, n / 400_000
        cells = [times[n, f, w] for w in (False, True)]
        cells = [f"{min(c):.0f} / {np.median(c):.0f}" for c in cells]
        print(f"| {n:,} | x{f} | {span:.1f} | {jitter:.1f} | " + " | ".join(cells) + " |")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--span-jitter", action="store_true", help="the walk's control only")
    args = parser.parse_args()
    nb.set_num_threads(1)
    if args.span_jitter:
        span_jitter(args.rounds)
        return 0
    packed = kernel_config(DetectorParams())
    detector = CornerDetector(DetectorParams())
    scans = {n: dense_scan(n) for n in SIZES}
    phases(scans[SIZES[0]], packed, detector)  # compile or load
    runs: dict[int, list[dict[str, float]]] = {n: [] for n in SIZES}
    for _ in range(args.rounds):
        for n, scan in scans.items():
            runs[n].append(phases(scan, packed, detector))
    names = list(runs[SIZES[0]][0])
    print(f"ns per beam, best / median of {args.rounds} rounds (sizes alternating)")
    print("| phase | " + " | ".join(f"{n:,}" for n in SIZES) + " | 1M/400k (best) |")
    print("|---|" + "---:|" * (len(SIZES) + 1))
    for name in names:
        cells, best = [], {}
        for n in SIZES:
            values = np.array([r[name] for r in runs[n]]) / n * 1e9
            best[n] = values.min()
            cells.append(f"{values.min():.0f} / {np.median(values):.0f}")
        ratio = best[1_000_000] / best[400_000] if best[400_000] > 0 else float("nan")
        print(f"| {name} | " + " | ".join(cells) + f" | {ratio:.2f} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
