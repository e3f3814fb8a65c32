"""The maximum clique of consistent matches (:mod:`laser_corners.matching.clique`, FALKO's CCDA):
on keypoints related by a known rigid motion, the clique is exactly the true matches, with the
exact search (up to 64 matches) and the greedy one (more)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from laser_corners.matching import MatchOptions
from laser_corners.matching.clique import CLIQUE_EXACT_MAX, max_clique
from laser_corners.matching.kernel_args import Side

OPTIONS = MatchOptions().kernel_options("bsc")
MOTION = (0.7, -1.2, 0.4)


def side(xy: np.ndarray, orientation: np.ndarray) -> Side:
    n = len(xy)
    return Side(
        np.ascontiguousarray(xy),
        np.full((n, 2, 2), np.nan),
        np.ascontiguousarray(orientation),
        np.full(n, math.pi / 2),
        np.zeros((n, 1), dtype=np.uint64),
        np.zeros((n, 1)),
        np.zeros(0),
        np.zeros(4),
        np.zeros((0, 2)),
    )


def scene(n_points: int, outliers: list[tuple[int, int]], seed: int = 0):
    """Keypoints A, the same keypoints B seen after ``MOTION``; matches (i, i) then outliers."""
    rng = np.random.default_rng(seed)
    xa = rng.uniform(-8.0, 8.0, (n_points, 2))
    oa = rng.uniform(-math.pi, math.pi, n_points)
    x, y, th = MOTION
    c, s = math.cos(th), math.sin(th)
    xb = (xa - [x, y]) @ np.array([[c, -s], [s, c]])  # a = R b + t
    ob = oa - th
    m = np.array([(i, i) for i in range(n_points)] + outliers, dtype=np.int64)
    return side(xa, oa), side(xb, ob), m


@pytest.mark.parametrize("n_points", [10, 40])  # 13 and 70 matches: exact, then greedy
def test_the_clique_is_the_true_matches(n_points: int) -> None:
    outliers = [(0, 5), (3, 7), (8, 2)] + [(i, (i * 7 + 3) % n_points) for i in range(10, 37)]
    outliers = [(i, j) for i, j in outliers if i != j and i < n_points]
    a, b, m = scene(n_points, outliers)
    assert (len(m) > CLIQUE_EXACT_MAX) == (n_points == 40)
    members = np.full(len(m), -1, dtype=np.int64)
    size = max_clique(a, b, m, len(m), members, OPTIONS)
    assert size == n_points
    assert sorted(members[:size].tolist()) == list(range(n_points))


def test_a_match_whose_orientation_disagrees_is_left_out() -> None:
    a, b, m = scene(8, [])
    b.orientation[3] += math.pi / 2  # B's keypoint 3 implies another rotation
    members = np.zeros(len(m), dtype=np.int64)
    size = max_clique(a, b, m, len(m), members, OPTIONS)
    assert size == 7 and 3 not in members[:size].tolist()


def test_no_matches_no_clique() -> None:
    a, b, _ = scene(3, [])
    assert max_clique(a, b, np.zeros((0, 2), np.int64), 0, np.zeros(0, np.int64), OPTIONS) == 0
