"""What bridging dropouts (``max_gap_beams``) does, on the simulator and on the real logs.

Usage::

    PYTHONPATH=src .venv/bin/python benchmarks/dropout_study.py [--scans 200]

Simulator: UST-10LX scans (1081 beams, noise 0.01 m) from random poses in random worlds
(``laser_corners.sim.random_world``), with no dropouts, 5 % of beams dropped at random, and one
beam in 20 dropped. Per ``max_gap_beams`` and preset: keypoints per scan, recall (visible true
corners with a keypoint within 0.05 m) and false keypoints per scan (farther than 0.1 m from
every true corner, visible or not). Real logs: keypoints per scan on the first scans of
fr079.bag, intel.bag and hokuyo270_rooms.bag /left_scan, without added dropouts.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from laser_corners import CornerDetector, LaserScan
from laser_corners.presets import get_preset
from laser_corners.sim import UST_10LX, random_poses, random_world

REAL = Path(__file__).resolve().parents[1] / ".." / "shared" / "data" / "real"
REAL_SETS = [("fr079.bag", "/scan"), ("intel.bag", "/scan"), ("hokuyo270_rooms.bag", "/left_scan")]
GAPS = (0, 1, 2, 3)


def drop(scan: LaserScan, mode: str, rng: np.random.Generator) -> LaserScan:
    ranges = scan.ranges.copy()
    if mode == "5% random":
        ranges[rng.random(ranges.size) < 0.05] = np.nan
    elif mode == "1 in 20":
        ranges[int(rng.integers(20)) :: 20] = np.nan
    return LaserScan(ranges, scan.angle_min, scan.angle_increment, scan.range_min, scan.range_max)


def simulated(n: int, seed: int = 0) -> list[tuple[LaserScan, np.ndarray, np.ndarray]]:
    """(scan, visible corners, all corners) in the sensor frame."""
    rng = np.random.default_rng(seed)
    out = []
    while len(out) < n:
        world = random_world(rng)
        for pose in random_poses(world, 10, rng):
            pose = tuple(pose)
            scan = world.scan(pose, UST_10LX, noise_sigma=0.01, rng=rng)
            corners = world.to_sensor_frame(world.corners, pose)
            out.append((scan, world.visible_corners(pose, UST_10LX), corners))
    return out[:n]


def score(keypoints: np.ndarray, visible: np.ndarray, corners: np.ndarray) -> tuple:
    if len(visible):
        d = np.linalg.norm(visible[:, None, :] - keypoints[None, :, :], axis=2)
        found = int((d.min(axis=1) <= 0.05).sum()) if len(keypoints) else 0
    else:
        found = 0
    if len(keypoints) and len(corners):
        d = np.linalg.norm(keypoints[:, None, :] - corners[None, :, :], axis=2)
        false = int((d.min(axis=1) > 0.1).sum())
    else:
        false = len(keypoints)
    return found, len(visible), false


def sim_table(n: int) -> None:
    data = simulated(n)
    print(f"Simulator: {n} UST-10LX scans, noise 0.01 m, random worlds\n")
    print("| dropouts | preset | max_gap_beams | kp/scan | recall % | false kp/scan |")
    print("|---|---|---:|---:|---:|---:|")
    for mode in ("none", "5% random", "1 in 20"):
        rng = np.random.default_rng(1)
        scans = [(drop(s, mode, rng), v, c) for s, v, c in data]
        for preset in ("paper", "robust"):
            for gap in GAPS:
                found = total = false = kp = 0
                for scan, visible, corners in scans:
                    params = get_preset(preset, scan).with_overrides({"max_gap_beams": gap})
                    k = CornerDetector(params).detect(scan)
                    f, t, fa = score(k.xy, visible, corners)
                    found, total, false, kp = found + f, total + t, false + fa, kp + len(k)
                print(
                    f"| {mode} | {preset} | {gap} | {kp / n:.2f} | "
                    f"{100 * found / max(total, 1):.1f} | {false / n:.2f} |"
                )


def real_table(limit: int) -> None:
    from laser_corners.io import open_scans

    print(f"\nReal logs: keypoints per scan (first {limit} scans), no added dropouts\n")
    print("| log | gaps % | preset | " + " | ".join(f"gap {g}" for g in GAPS) + " |")
    print("|---|---:|---|" + "---:|" * len(GAPS))
    for name, topic in REAL_SETS:
        path = REAL / name
        if not path.is_file():
            print(f"| {name} | skipped: not found | | |")
            continue
        scans = []
        for scan in open_scans(path, topic=topic):
            scans.append(scan)
            if len(scans) >= limit:
                break
        gaps = 100 * np.mean([s.n_gaps / s.n_beams for s in scans])
        for preset in ("paper", "auto", "robust"):
            cells = []
            for gap in GAPS:
                params = get_preset(preset, scans[0]).with_overrides({"max_gap_beams": gap})
                det = CornerDetector(params)
                cells.append(f"{np.mean([len(k) for k in det.detect_many(scans)]):.2f}")
            print(f"| {name} {topic} | {gaps:.1f} | {preset} | " + " | ".join(cells) + " |")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scans", type=int, default=200)
    parser.add_argument("--real-scans", type=int, default=500)
    args = parser.parse_args()
    sim_table(args.scans)
    real_table(args.real_scans)
    return 0


if __name__ == "__main__":
    sys.exit(main())
