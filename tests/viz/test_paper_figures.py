"""The paper's figure helpers (:mod:`laser_corners.viz.paper_figures`) agree with the detector
kernel."""

from __future__ import annotations

import matplotlib.pyplot as plt
import numpy as np
import pytest

from laser_corners import CornerDetector
from laser_corners.sim import UST_10LX, World
from laser_corners.viz.paper_figures import neighbourhoods, plot_neighbourhoods


def test_fig2_helper_agrees_with_the_kernel() -> None:
    world = World().add_polygon([[-1.0, -2.0], [2.0, -2.0], [2.0, 1.0], [-1.0, 1.0]])
    scan = world.scan((0.0, 0.0, 0.0), UST_10LX, 0.005, np.random.default_rng(3))
    xy, valid = scan.to_cartesian()
    j = int(np.argmin(np.where(valid, np.hypot(xy[:, 0] - 2.0, xy[:, 1] - 1.0), np.inf)))
    table = CornerDetector().scale_table(scan)
    k = int(np.argmin(np.abs(table.scales - 0.15)))
    arrival, departure = neighbourhoods(scan, j, 0.15)
    assert arrival.stop - arrival.start >= 5 and departure.stop - departure.start >= 5
    fig, ax = plt.subplots()
    info = plot_neighbourhoods(ax, scan, j, 0.15)
    plt.close(fig)
    assert table.passed[j, k]
    assert info["intersection"] == pytest.approx(table.intersections[j, k], abs=1e-9)
    assert info["opening"] == pytest.approx(90.0, abs=3.0)
