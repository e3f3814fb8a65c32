"""How far the odometry drifts from the full-log SLAM, against the localiser's window model.

Usage::

    PYTHONPATH=src python benchmarks/odometry_drift.py [LOG ...] [--cache DIR] [--every 25]

For every ``--every``-th scan of each log (``../shared/data/real/LOG.bag``), the odometry is
chained from the full-log SLAM pose of that scan (the map of ``bench_localise.py``, built there
and cached under ``--cache``) and compared with the SLAM pose after 1, 2, 3, 5 and 10 m of
travel: position and heading error (median, 95th percentile), and the share of stretches
whose two errors are within the 3σ of :class:`laser_corners.localise.window.Window` grown with
the default ``odometry.sigma_xy`` / ``odometry.sigma_yaw`` (the window of a lost track,
issue 20). A check of the model, not a fit: nothing here sets a default.
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

import numpy as np

from bench_localise import REAL, cached_map, read_log
from laser_corners.io.trajectory import read_tum
from laser_corners.localise import LocaliseOptions
from laser_corners.localise.window import Window
from laser_corners.pose import between_many

LENGTHS = (1.0, 2.0, 3.0, 5.0, 10.0)


def stretches(odo: np.ndarray, ref: np.ndarray, every: int) -> dict[float, np.ndarray]:
    """Per travel length: rows (position error, heading error, 3σ position, 3σ heading)."""
    opt = LocaliseOptions()
    steps = between_many(odo[:-1], odo[1:])
    out: dict[float, list] = {length: [] for length in LENGTHS}
    for start in range(0, len(odo) - 1, every):
        window = Window(ref[start].copy(), 0.0, 0.0)
        travel, todo = 0.0, list(LENGTHS)
        for j in range(start, len(steps)):
            window.move(steps[j], opt.odometry)
            travel += math.hypot(steps[j, 0], steps[j, 1])
            while todo and travel >= todo[0]:
                err = between_many(ref[j + 1], window.pose)
                out[todo.pop(0)].append(
                    (
                        math.hypot(err[0], err[1]),
                        abs(err[2]),
                        3 * window.sigma_xy,
                        3 * window.sigma_yaw,
                    )
                )
            if not todo:
                break
    return {length: np.array(rows).reshape(-1, 4) for length, rows in out.items()}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("logs", nargs="*", default=["fr079", "aces", "intel"])
    parser.add_argument("--cache", type=Path, required=True)
    parser.add_argument("--every", type=int, default=25)
    args = parser.parse_args()
    print(
        "| log | travel m | stretches | position error median / p95 m "
        "| heading error median / p95 deg | within the window's 3σ |"
    )
    print("|---|---|---|---|---|---|")
    for name in args.logs:
        path = REAL / f"{name}.bag"
        _, odo, stamps = read_log(path)
        t, p = read_tum(cached_map(path, args.cache / f"{name}-full", None) / "trajectory.tum")
        ref = p[np.clip(np.searchsorted(t, stamps - 1e-4), 0, len(t) - 1)]
        for length, v in stretches(odo, ref, args.every).items():
            if len(v) == 0:
                continue
            inside = np.mean((v[:, 0] <= v[:, 2]) & (v[:, 1] <= v[:, 3]))
            pos = np.percentile(v[:, 0], [50, 95])
            yaw = np.degrees(np.percentile(v[:, 1], [50, 95]))
            print(
                f"| {name} | {length:g} | {len(v)} | {pos[0]:.2f} / {pos[1]:.2f} "
                f"| {yaw[0]:.1f} / {yaw[1]:.1f} | {inside:.3f} |"
            )


if __name__ == "__main__":
    main()
