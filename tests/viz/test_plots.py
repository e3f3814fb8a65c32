"""The scan figure (:mod:`laser_corners.viz.plots`): draws into the ``ax`` it is given, the
scan's valid points, the keypoints with their bisectors, candidates and true corners."""

from __future__ import annotations

import math

import numpy as np
from matplotlib.figure import Figure

from laser_corners import CornerDetector, LaserScan
from laser_corners.sim import corner_scan
from laser_corners.viz.plots import plot_scan


def test_plot_scan_draws_every_layer_into_the_given_ax() -> None:
    scan = corner_scan()
    keypoints, candidates = CornerDetector().detect(scan, return_candidates=True)
    fig = Figure()
    ax = fig.subplots()
    assert plot_scan(ax, scan, keypoints, candidates, truth=[2.0, 1.0]) is ax
    lines = {line.get_label(): line for line in ax.get_lines()}
    assert set(lines) == {"scan points", "sensor", "true corners", "candidates", "keypoints"}
    xy, valid = scan.to_cartesian()
    np.testing.assert_allclose(lines["scan points"].get_xydata(), xy[valid])
    np.testing.assert_allclose(lines["keypoints"].get_xydata(), keypoints.xy)
    np.testing.assert_allclose(lines["true corners"].get_xydata(), [[2.0, 1.0]])
    assert len(lines["candidates"].get_xydata()) == len(candidates) > len(keypoints)
    (arrows,) = ax.collections  # one bisector arrow per keypoint, 0.2 m long
    np.testing.assert_allclose(arrows.U, 0.2 * np.cos(keypoints.orientation))
    assert ax.get_aspect() == 1.0 and ax.get_legend() is not None
    assert len(fig.axes) == 1  # no figure of its own


def test_plot_scan_without_keypoints_or_valid_points() -> None:
    ranges = np.full(50, np.nan)
    ranges[:10] = 2.0
    scan = LaserScan(ranges, -math.pi / 4, math.pi / 100, 0.05, 10.0)
    ax = Figure().subplots()
    plot_scan(ax, scan, keypoints=CornerDetector().detect(scan))
    labels = [line.get_label() for line in ax.get_lines()]
    assert labels == ["scan points", "sensor"] and not ax.collections
    assert len(ax.get_lines()[0].get_xydata()) == 10
