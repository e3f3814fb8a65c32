"""Reproduce the paper's fig. 1 (line-model RMSE and angle error) and fig. 2 (neighbourhoods).

Usage::

    .venv/bin/python benchmarks/paper_figures.py [--output docs] [--samples 1000]

Writes ``fig1_linefit.png``, ``fig1_linefit.csv`` and ``fig2_neighbourhoods.png`` into the
output folder and prints the numbers quoted in ``docs/simulation-and-accuracy.md``.
"""

from __future__ import annotations

import argparse
import csv
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from laser_corners import CornerDetector
from laser_corners.eval.linefit_study import line_fit_study
from laser_corners.sim import UST_10LX, World
from laser_corners.viz.paper_figures import plot_line_fit_study, plot_neighbourhoods


def fig1(output: Path, samples: int) -> None:
    study = line_fit_study(n_points=100, sigma=0.03, n_samples=samples)
    with (output / "fig1_linefit.csv").open("w", newline="") as fh:
        table = study.as_table()
        writer = csv.writer(fh)
        writer.writerow(list(table))
        writer.writerows(np.column_stack(list(table.values())).round(6).tolist())
    fig, (ax1, ax2) = plt.subplots(2, 1, figsize=(8, 7), sharex=True)
    plot_line_fit_study(ax1, ax2, study)
    ax1.set_title(f"Fig. 1: 100-point lines, 1 m long, noise sigma 0.03 m, {samples} samples")
    fig.tight_layout()
    fig.savefig(output / "fig1_linefit.png", dpi=120)
    plt.close(fig)
    best = np.minimum(study.angle_err_yx_deg, study.angle_err_xy_deg)
    print(f"fig. 1: {len(study.angles_deg)} orientations x {samples} samples")
    print(
        f"  mean RMSE selected: {study.rmse_sel.min():.4f}-{study.rmse_sel.max():.4f} m; "
        f"y|x up to {study.rmse_yx.max():.3f} m, x|y up to {study.rmse_xy.max():.3f} m"
    )
    print(
        f"  samples where the selection's RMSE exceeds y|x: {study.sel_worse_than_yx}, "
        f"x|y: {study.sel_worse_than_xy}"
    )
    print(
        f"  mean |angle error| selected: max {study.angle_err_sel_deg.max():.3f} deg "
        f"(better model per orientation: max {best.max():.3f} deg; worst model: "
        f"{np.maximum(study.angle_err_yx_deg, study.angle_err_xy_deg).max():.1f} deg); "
        f"selected - better: max {np.max(study.angle_err_sel_deg - best):.3f} deg"
    )


def fig2(output: Path) -> None:
    world = World(name="fig. 2")
    # a room corner and a pillar in front of a wall, seen by a UST-10LX
    world.add_polygon([[-1.0, -2.0], [2.0, -2.0], [2.0, 1.0], [-1.0, 1.0]])
    world.add_polygon([[0.9, -0.6], [1.3, -0.6], [1.3, -0.2], [0.9, -0.2]])
    pose = (0.0, 0.0, 0.0)
    scan = world.scan(pose, UST_10LX, noise_sigma=0.005, rng=np.random.default_rng(3))
    xy, valid = scan.to_cartesian()
    radius = 0.15
    fig, axes = plt.subplots(1, 3, figsize=(15, 5))
    detector = CornerDetector()
    table = detector.scale_table(scan)
    k = int(np.argmin(np.abs(table.scales - radius)))
    for ax, (target, title) in zip(
        axes,
        (
            ((2.0, 1.0), "concave room corner"),
            ((0.9, -0.2), "convex pillar corner"),
            ((2.0, 0.4), "straight wall"),
        ),
        strict=True,
    ):
        d = np.where(valid, np.hypot(xy[:, 0] - target[0], xy[:, 1] - target[1]), np.inf)
        j = int(np.argmin(d))
        info = plot_neighbourhoods(ax, scan, j, radius)
        verdict = "passes" if table.passed[j, k] else "fails"
        ax.set_title(f"{title}: p_j = beam {j}, scale {verdict}", fontsize=10)
        q = info["intersection"]
        where = "none" if q is None else f"({q[0]:.3f}, {q[1]:.3f})"
        print(
            f"fig. 2 {title}: beam {j}, intersection {where}, opening {info['opening']}, "
            f"kernel {table.intersections[j, k].round(3).tolist()} {verdict}"
        )
    fig.suptitle(
        f"Fig. 2: arrival/departure neighbourhoods at R = {radius} m "
        "(simulated UST-10LX, noise sigma 5 mm)"
    )
    fig.tight_layout()
    fig.savefig(output / "fig2_neighbourhoods.png", dpi=120)
    plt.close(fig)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--output", type=Path, default=Path("docs"))
    parser.add_argument("--samples", type=int, default=1000)
    args = parser.parse_args()
    args.output.mkdir(parents=True, exist_ok=True)
    fig1(args.output, args.samples)
    fig2(args.output)
    print(f"wrote {args.output}/fig1_linefit.png, fig1_linefit.csv, fig2_neighbourhoods.png")


if __name__ == "__main__":
    main()
