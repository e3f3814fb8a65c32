"""How per-point candidates become one keypoint per corner: duplicates and error, measured.

Usage::

    .venv/bin/python benchmarks/merge_study.py [--scans 300]

Simulated UST-10LX scans from random poses in the demo world, for several range-noise levels.
For every visible true corner with at least one candidate within 0.1 m, it counts candidates
and keypoints within 0.1 m (keypoints per corner > 1 means duplicates) and compares the
localisation error of three ways to make one keypoint of a cluster: the lowest-RMSE candidate
(the detector's choice), the mean of the candidates, and no merging (every candidate).
"""

from __future__ import annotations

import argparse

import numpy as np

from laser_corners import CornerDetector, DetectorParams
from laser_corners.demo import demo_world
from laser_corners.sim import UST_10LX


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scans", type=int, default=300)
    args = parser.parse_args()
    world = demo_world()
    detector = CornerDetector(DetectorParams())
    print(
        "| noise sigma m | corners | candidates/corner | keypoints/corner | "
        "median err best-RMSE mm | median err mean mm | median err unmerged mm |"
    )
    print("|---:|---:|---:|---:|---:|---:|---:|")
    for sigma in (0.0, 0.005, 0.01, 0.02):
        rng = np.random.default_rng(1)
        n_corners, n_cand, n_kp = 0, 0, 0
        err_best, err_mean, err_all = [], [], []
        done = 0
        while done < args.scans:
            pose = (rng.uniform(-2.5, 3.5), rng.uniform(-2.0, 2.5), rng.uniform(-np.pi, np.pi))
            if 1.0 < pose[0] < 4.0 and 1.0 < pose[1] < 3.0:
                continue
            done += 1
            scan = world.scan(pose, UST_10LX, noise_sigma=sigma, rng=rng)
            truth = world.visible_corners(pose, UST_10LX)
            kps, cands = detector.detect(scan, return_candidates=True)
            for corner in truth:
                dc = np.hypot(*(cands.xy - corner).T) if len(cands) else np.zeros(0)
                near = dc <= 0.1
                if not near.any():
                    continue
                dk = np.hypot(*(kps.xy - corner).T)
                n_corners += 1
                n_cand += int(near.sum())
                n_kp += int((dk <= 0.1).sum())
                err_best.append(dk.min())
                err_mean.append(np.hypot(*(cands.xy[near].mean(axis=0) - corner)))
                err_all.extend(dc[near])
        print(
            f"| {sigma} | {n_corners} | {n_cand / n_corners:.1f} | {n_kp / n_corners:.3f} | "
            f"{np.median(err_best) * 1e3:.2f} | {np.median(err_mean) * 1e3:.2f} | "
            f"{np.median(err_all) * 1e3:.2f} |"
        )


if __name__ == "__main__":
    main()
