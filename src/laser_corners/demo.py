"""The embedded demo: a simulated UST-10LX scan of a room with known corners."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from laser_corners.detector import CornerDetector
from laser_corners.keypoints import Keypoints
from laser_corners.params import DetectorParams
from laser_corners.sim import UST_10LX, World
from laser_corners.viz.plots import plot_scan

__all__ = ["demo_world", "run_demo"]

DEMO_POSE = (0.4, -0.3, 0.25)


def demo_world() -> World:
    """An L-shaped room with a square pillar: 10 corners, convex and concave."""
    world = World()
    world.add_polygon([[-3.0, -2.5], [4.0, -2.5], [4.0, 1.0], [1.5, 1.0], [1.5, 3.0], [-3.0, 3.0]])
    world.add_polygon([[1.8, -1.2], [2.4, -1.2], [2.4, -0.6], [1.8, -0.6]])
    return world


def run_demo(output: Path | None = Path("demo.png"), noise_sigma: float = 0.005) -> int:
    """Simulate, detect, print keypoints against the true corners, write a PNG.

    The PNG's folder is created when missing. Returns the number of visible true corners
    without a keypoint within 0.1 m.
    """
    world = demo_world()
    rng = np.random.default_rng(7)
    scan = world.scan(DEMO_POSE, UST_10LX, noise_sigma=noise_sigma, rng=rng)
    detector = CornerDetector(DetectorParams())
    keypoints = detector.detect(scan)
    truth = world.visible_corners(DEMO_POSE, UST_10LX)
    print(
        f"Simulated {UST_10LX.name} scan: {scan.n_beams} beams, {scan.n_gaps} gaps, "
        f"range noise sigma {noise_sigma} m"
    )
    print(f"{len(keypoints)} keypoints, {len(truth)} true corners in view\n")
    print(f"{'true x':>8} {'true y':>8} | {'kp x':>8} {'kp y':>8} {'error mm':>9} {'angle':>6}")
    missed = 0
    for tx, ty in truth:
        if len(keypoints):
            d = np.hypot(keypoints.xy[:, 0] - tx, keypoints.xy[:, 1] - ty)
            i = int(np.argmin(d))
        if len(keypoints) and d[i] <= 0.1:
            kx, ky = keypoints.xy[i]
            print(
                f"{tx:8.3f} {ty:8.3f} | {kx:8.3f} {ky:8.3f} {d[i] * 1e3:9.1f} "
                f"{keypoints.opening_angle_deg[i]:6.1f}"
            )
        else:
            missed += 1
            print(f"{tx:8.3f} {ty:8.3f} |   (missed)")
    false = _unmatched(keypoints, truth)
    print(f"\nfound {len(truth) - missed}/{len(truth)} visible corners, {false} false keypoints")
    if output is not None:
        import matplotlib

        Path(output).parent.mkdir(parents=True, exist_ok=True)

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        fig, ax = plt.subplots(figsize=(7, 7))
        plot_scan(ax, scan, keypoints, truth=truth)
        ax.set_title("laser-corners demo: simulated UST-10LX scan")
        kind = Path(output).suffix[1:].lower() or "png"  # exactly ``output``, no suffix added
        fig.savefig(output, format=kind, dpi=120, bbox_inches="tight")
        plt.close(fig)
        print(f"wrote {output}")
    return missed


def _unmatched(keypoints: Keypoints, truth: NDArray[np.float64], radius: float = 0.1) -> int:
    if len(keypoints) == 0:
        return 0
    if len(truth) == 0:
        return len(keypoints)
    d = np.hypot(
        keypoints.xy[:, None, 0] - truth[None, :, 0], keypoints.xy[:, None, 1] - truth[None, :, 1]
    )
    return int(np.count_nonzero(d.min(axis=1) > radius))
