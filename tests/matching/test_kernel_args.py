"""A matcher option keeps one name from MatchOptions to the kernels (matching.kernel_args)."""

from __future__ import annotations

import numpy as np

from laser_corners.matching import MatchOptions
from laser_corners.matching.core import VERIFY_CLIQUE
from laser_corners.matching.kernel_args import (
    Bank,
    KernelOptions,
    Offsets,
    ScanArrays,
    Side,
    scan_geometry,
)


def test_kernel_options_carry_the_match_option_names() -> None:
    # every kernel option is a MatchOptions field of the same name; scan_points only sizes
    # the scan arrays (Python side)
    assert set(KernelOptions._fields) == set(MatchOptions.model_fields) - {"scan_points"}
    opt = MatchOptions(scan_tolerance=0.25, verification="clique", k_nearest=5)
    k = opt.kernel_options("bsc")
    assert (k.scan_tolerance, k.k_nearest, k.verification) == (0.25, 5, VERIFY_CLIQUE)
    assert k.max_distance == 0.3  # None -> the descriptor kind's default
    assert MatchOptions(max_distance=0.5).kernel_options("csc").max_distance == 0.5


def test_scan_geometry_names_the_row() -> None:
    g = scan_geometry(np.array([-1.5, 0.01, 0.1, 30.0]))
    assert (g.angle_min, g.angle_increment, g.range_min, g.range_max) == (-1.5, 0.01, 0.1, 30.0)
    # one list of names for a scan's arrays: a side's scan, and a bank's rows (a side of all
    # its scans) with their offsets
    assert Side._fields[-3:] == ScanArrays._fields == ("ranges", "geometry", "points")
    assert Bank._fields == ("rows", "offsets")
    assert Offsets._fields == ("keypoints", "ranges", "points")
