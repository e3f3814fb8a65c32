"""Throughput of ``laser-corners batch`` over ../shared/data/real, and where the time goes.

Usage::

    .venv/bin/python benchmarks/bench_batch.py [--repeats 2] [--dask]

Runs :func:`laser_corners.batch.run_batch` over every recording of the real-data folder (the
ROS 1 bags, each LaserScan topic of the three-topic bag as its own job, and the CARMEN logs)
into a fresh temporary folder, end to end: reading, detection (paper preset) and writing one
Parquet file per job. Configurations:

* 1 worker, 1 numba thread (jobs run in this process, scans one by one through ``detect``),
  without and with the reader thread;
* 1 worker, 2 numba threads (chunks of scans through the parallel ``detect_many``);
* 2 workers (spawned process pool), 1 thread each;
* with ``--dask``: a Dask LocalCluster of 2 worker processes (start-up included).

Reported per configuration (best wall time of ``--repeats``): scans/s for the whole set and
per worker; and per job the split of its time into read (reader: decompression, message
decoding, poses, LaserScan construction), detect (numba kernel) and write (Parquet); the
one-off loading of numba's cached kernels in each worker process is counted apart. The
360-beam recordings (fr079.bag, fr079-corrected.clf.gz) are summarised separately, against
the issue's target of 10,000 scans/s per worker. A warm-up job first loads numba's cache.
The machine is shared: the load average is printed with the numbers.

First, fr079.bag alone (4,934 scans of 360 beams): read alone, and through the pipeline's
detect loop into Parquet, one numba thread, with the ROS 1 bag read by the per-message path
through rosbags (old, ``BagSource.lean = False``) and by the lean path (new,
:mod:`laser_corners.io.ros1.lean`), each with the reader thread off and on (``prefetch``),
alternating in the same process, best of ``--repeats``: wall scans/s, and the CPU time of the
main (detecting and writing) thread and of the reader thread per scan. ``bound`` is
``scans / max(thread CPU times)``: what one worker would reach with a core per thread (an
upper bound: the Python parts of the two threads share the GIL); on a loaded machine the wall
rate is far below it.
"""

from __future__ import annotations

import argparse
import os
import platform
import tempfile
import time
from pathlib import Path

from laser_corners.batch import BatchJob, BatchReport, JobResult, run_batch, run_job
from laser_corners.io import open_scans
from laser_corners.io.rosbag import BagSource
from laser_corners.io.writers import ParquetKeypointWriter
from laser_corners.pipeline import RunSummary, detect_recording, open_recording, set_threads

REAL = Path(__file__).resolve().parents[1] / ".." / "shared" / "data" / "real"
BEAMS_360 = ("fr079.bag", "fr079-corrected.clf.gz")
TARGET_PER_WORKER = 10_000


def recordings() -> list[Path]:
    return sorted(p for p in REAL.iterdir() if p.suffix == ".bag" or p.name.endswith(".clf.gz"))


def run(
    inputs: list[Path],
    workers: int,
    threads: int,
    scheduler: str | None,
    repeats: int,
    prefetch: bool | None = None,
) -> BatchReport:
    best: BatchReport | None = None
    for _ in range(repeats):
        with tempfile.TemporaryDirectory(prefix="bench-batch-") as outdir:
            report = run_batch(
                inputs,
                outdir,
                workers=workers,
                threads=threads,
                scheduler=scheduler,
                prefetch=prefetch,
            )
        failed = report.failed
        if failed:
            raise SystemExit(f"jobs failed: {[(r.input, r.error) for r in failed]}")
        if best is None or report.seconds < best.seconds:
            best = report
    assert best is not None
    return best


def fr079_loop(prefetch: bool, lean: bool) -> RunSummary:
    """fr079.bag through the detect loop into a Parquet file (reading, detection, writing),
    the ROS 1 bag read by the lean path (``lean``) or by the per-message path."""
    BagSource.lean = lean
    try:
        recording = open_recording(REAL / "fr079.bag")
        with tempfile.TemporaryDirectory(prefix="bench-loop-") as outdir:
            writer = ParquetKeypointWriter(Path(outdir) / "k.parquet", recording.has_poses)
            return detect_recording(recording, writer=writer, threads=1, prefetch=prefetch)
    finally:
        BagSource.lean = True


def read_only(lean: bool) -> tuple[int, float, float]:
    """fr079.bag read alone (no detection): scans, wall s, CPU s of this thread."""
    BagSource.lean = lean
    try:
        wall, cpu = time.perf_counter(), time.thread_time()
        count = sum(1 for _ in open_scans(REAL / "fr079.bag"))
        return count, time.perf_counter() - wall, time.thread_time() - cpu
    finally:
        BagSource.lean = True


def compare_prefetch(repeats: int) -> None:
    """fr079.bag, one worker, one numba thread: per-message vs lean reading path, reader thread
    off / on, alternating in one process (best wall time of ``repeats``)."""
    set_threads(1)
    configs = [(lean, prefetch) for lean in (False, True) for prefetch in (False, True)]
    best: dict[tuple[bool, bool], RunSummary] = {}
    reads: dict[bool, tuple[int, float, float]] = {}
    for _ in range(repeats):
        for lean in (False, True):
            found = read_only(lean)
            if lean not in reads or found[2] < reads[lean][2]:
                reads[lean] = found
        for config in configs:
            summary = fr079_loop(config[1], config[0])
            if config not in best or summary.seconds < best[config].seconds:
                best[config] = summary
    print("## fr079.bag, reading alone (open_scans, no detection)\n")
    print("| reading path | scans | wall [s] | scans/s | CPU us/scan |")
    print("|---|---:|---:|---:|---:|")
    for lean, (n, wall, cpu) in reads.items():
        label = "lean (new)" if lean else "per message (old)"
        print(f"| {label} | {n} | {wall:.3f} | {n / wall:,.0f} | {1e6 * cpu / n:.1f} |")
    print(
        "\n## fr079.bag end to end (read + detect + write Parquet), one worker, one numba thread\n"
    )
    print(
        "| reading path | reader thread | scans | wall [s] | scans/s | main thread CPU "
        "us/scan | reader thread CPU us/scan | bound scans/s |"
    )
    print("|---|---|---:|---:|---:|---:|---:|---:|")
    for (lean, prefetch), s in best.items():
        n = s.n_scans
        main_us = 1e6 * s.cpu_seconds / n
        reader_us = 1e6 * s.reader_cpu_seconds / n
        bound = n / max(s.cpu_seconds, s.reader_cpu_seconds)
        path = "lean (new)" if lean else "per message (old)"
        thread = "on" if prefetch else "off"
        print(
            f"| {path} | {thread} | {n} | {s.seconds:.3f} | {s.scans_per_second:,.0f} | "
            f"{main_us:.1f} | {reader_us:.1f} | {bound:,.0f} |"
        )
    old, new = best[(False, True)], best[(True, True)]
    print(
        f"\nlean / per-message path, reader thread on (wall, same run): "
        f"{old.seconds / new.seconds:.2f}x; per-message path without / with the reader thread: "
        f"{best[(False, False)].seconds / old.seconds:.2f}x; target {TARGET_PER_WORKER:,} "
        f"scans/s; load average now {os.getloadavg()[0]:.2f}\n"
    )


def split(results: list[JobResult]) -> tuple[int, float, float, float, float, float]:
    scans = sum(r.scans for r in results)
    return (
        scans,
        sum(r.seconds for r in results),
        sum(r.read_seconds for r in results),
        sum(r.detect_seconds for r in results),
        sum(r.write_seconds for r in results),
        sum(r.startup_seconds for r in results),
    )


def rate(scans: int, seconds: float) -> str:
    return f"{scans / seconds:,.0f}" if seconds > 0 else "-"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=2)
    parser.add_argument("--dask", action="store_true", help="Also time a Dask LocalCluster.")
    parser.add_argument(
        "--loop-only", action="store_true", help="Only the fr079.bag reader-thread comparison."
    )
    args = parser.parse_args()
    if not REAL.is_dir():
        print(f"skipped: real data folder not found: {REAL.resolve()}")
        return
    inputs = recordings()
    print(f"# batch throughput over {REAL.resolve()}\n")
    machine = platform.processor() or platform.machine()
    load = os.getloadavg()[0]
    print(
        f"{machine}, {os.cpu_count()} cores, Python {platform.python_version()}; "
        f"load average before: {load:.2f}\n"
    )
    with tempfile.TemporaryDirectory() as warm:  # numba cache load / compile, not timed
        run_job(BatchJob(str(REAL / "fr079-corrected.clf.gz"), None, "w.parquet"), warm)

    compare_prefetch(max(args.repeats, 3))
    if args.loop_only:
        return
    configs: list[tuple[str, int, int, str | None, bool | None]] = [
        ("1 worker x 1 thread (in process, no reader thread)", 1, 1, None, False),
        ("1 worker x 1 thread + reader thread (in process)", 1, 1, None, True),
        ("1 worker x 2 threads (in process, detect_many)", 1, 2, None, None),
        ("2 workers x 1 thread (process pool)", 2, 1, None, None),
    ]
    if args.dask:
        configs.append(("2 workers x 1 thread (Dask LocalCluster)", 2, 1, "local", None))
    reports = []
    print("| configuration | jobs | scans | wall [s] | scans/s | scans/s per worker |")
    print("|---|---:|---:|---:|---:|---:|")
    for label, workers, threads, scheduler, prefetch in configs:
        report = run(inputs, workers, threads, scheduler, args.repeats, prefetch)
        reports.append((label, report))
        print(
            f"| {label} | {len(report.results)} | {report.n_scans} | {report.seconds:.2f} | "
            f"{report.scans_per_second:,.0f} | "
            f"{report.scans_per_second / report.workers:,.0f} |"
        )

    print("\n## where the time goes (sum over jobs, seconds inside the workers)\n")
    print(
        "| configuration | recordings | scans | job s | read s | detect s | write s | "
        "kernel load s | end-to-end scans/s | read scans/s | detect scans/s | "
        "write scans/s |"
    )
    print("|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    for label, report in reports:
        groups = {
            "all": report.results,
            "360-beam": [r for r in report.results if Path(r.input).name in BEAMS_360],
        }
        for group, results in groups.items():
            scans, total, read, detect, write, startup = split(results)
            print(
                f"| {label} | {group} | {scans} | {total:.2f} | {read:.2f} | {detect:.2f} | "
                f"{write:.2f} | {startup:.2f} | {rate(scans, total)} | {rate(scans, read)} | "
                f"{rate(scans, detect)} | {rate(scans, write)} |"
            )

    print("\n## per job (first configuration)\n")
    print("| job | scans | beams | s | read s | detect s | write s | scans/s |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|")
    for r in sorted(reports[0][1].results, key=lambda r: r.key):
        first = open_scans(r.input, r.topic).first_scan()
        beams = first.n_beams if first is not None else 0
        print(
            f"| {Path(r.input).name}{' ' + r.topic if r.topic else ''} | {r.scans} | {beams} | "
            f"{r.seconds:.2f} | {r.read_seconds:.2f} | {r.detect_seconds:.2f} | "
            f"{r.write_seconds:.2f} | {r.scans_per_second:,.0f} |"
        )
    print(f"\ntarget: >= {TARGET_PER_WORKER:,} scans/s per worker for 360-beam scans, end to end")
    print(f"load average after: {os.getloadavg()[0]:.2f}; started {time.strftime('%H:%M:%S')}")


if __name__ == "__main__":
    main()
