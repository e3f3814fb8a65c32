"""Monte Carlo consistency of ``Keypoints.cov`` (the study behind ``docs/matching.md``).

Usage::

    PYTHONPATH=src python benchmarks/covariance_study.py [--trials 3000] [--seed 0]

For the ``robust`` and ``paper`` presets: simulated concave corners (UST-10LX, noise uniform in
[0, 0.03] m, ranges 0.5-8 m, see ``benchmarks/covariance_consistency.py``); prints, overall and
per noise band and range band, the keypoints scored, the fraction of true corners inside the
keypoint's 95 % ellipse (target 0.95; accepted 0.92-0.98) and the median NEES (1.39 for a
consistent covariance; accepted 0.7-2), as a Markdown table.
"""

from __future__ import annotations

import argparse

import numpy as np

from covariance_consistency import CHI2_2_95, covariance_consistency
from laser_corners.params import DetectorParams


def _row(label: str, nees: np.ndarray) -> str:
    if nees.size == 0:
        return f"| {label} | 0 | - | - |"
    inside = float(np.mean(nees <= CHI2_2_95))
    return f"| {label} | {nees.size} | {inside:.3f} | {float(np.median(nees)):.2f} |"


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--trials", type=int, default=3000)
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args()
    presets = {"robust": None, "paper": lambda scan, noise: DetectorParams()}
    for name, params in presets.items():
        res = covariance_consistency(
            args.trials, noises=(0.0, 0.03), continuous=True, params=params, seed=args.seed
        )
        print(f"\npreset {name}: {res.nees.size} keypoints scored of {res.n_trials} corners\n")
        print("| subset | keypoints | inside 95 % ellipse | median NEES |")
        print("|---|---|---|---|")
        print(_row("all", res.nees))
        for lo, hi in ((0.0, 0.005), (0.005, 0.015), (0.015, 0.025), (0.025, 0.03)):
            sel = (res.noise >= lo) & (res.noise < hi + (hi == 0.03))
            print(_row(f"noise {lo:.3f}-{hi:.3f} m", res.nees[sel]))
        for lo, hi in ((0.5, 2.0), (2.0, 4.0), (4.0, 8.0)):
            sel = (res.rng_m >= lo) & (res.rng_m < hi)
            print(_row(f"range {lo:g}-{hi:g} m", res.nees[sel]))


if __name__ == "__main__":
    main()
