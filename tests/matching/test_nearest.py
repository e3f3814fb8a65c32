"""Candidate matches by nearest neighbours in descriptor space (:mod:`laser_corners.matching.
nearest`) against a brute-force search over every pair, done here with numpy."""

from __future__ import annotations

import math

import numpy as np
import pytest

from laser_corners.matching import MatchOptions
from laser_corners.matching.kernel_args import Side
from laser_corners.matching.nearest import candidate_matches

CSC = 1


def side(values: np.ndarray, opening: np.ndarray | None = None) -> Side:
    n = len(values)
    return Side(
        np.zeros((n, 2)),
        np.full((n, 2, 2), np.nan),
        np.zeros(n),
        np.full(n, np.nan) if opening is None else opening,
        np.zeros((0, 1), dtype=np.uint64),
        np.ascontiguousarray(values),
        np.zeros(0),
        np.zeros(4),
        np.zeros((0, 2)),
    )


def matches(a: Side, b: Side, **options) -> set[tuple[int, int]]:
    kernel = MatchOptions(**options).kernel_options("csc")
    out = np.full((len(a.values) * kernel.k_nearest, 2), -1, dtype=np.int64)
    n = candidate_matches(CSC, 1.0, a, b, kernel, out)
    found = {tuple(pair) for pair in out[:n].tolist()}
    assert len(found) == n  # no pair twice
    return found


@pytest.fixture(scope="module")
def descriptors() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    rng = np.random.default_rng(4)
    va = rng.uniform(0.0, 1.0, (30, 12)) / 12
    vb = np.concatenate(
        [va[:20] + rng.normal(0.0, 0.004, (20, 12)), rng.uniform(0, 1, (15, 12)) / 12]
    )
    distance = np.abs(va[:, None, :] - vb[None, :, :]).sum(axis=2)  # L1, (30, 35)
    return va, vb, distance


@pytest.mark.parametrize("k", [1, 3])
def test_k_nearest_within_the_distance_are_the_brute_force_ones(descriptors, k: int) -> None:
    va, vb, distance = descriptors
    limit = float(np.quantile(distance, 0.05))
    expected = {
        (i, int(j))
        for i in range(len(va))
        for j in np.argsort(distance[i])[:k]
        if distance[i, j] <= limit
    }
    assert 20 <= len(expected) < len(va) * k  # the limit cuts some: a real test
    assert matches(side(va), side(vb), k_nearest=k, max_distance=limit) == expected


def test_mutual_keeps_pairs_that_are_each_others_nearest(descriptors) -> None:
    va, vb, distance = descriptors
    nearest_b, nearest_a = distance.argmin(axis=1), distance.argmin(axis=0)
    expected = {(i, int(j)) for i, j in enumerate(nearest_b) if nearest_a[j] == i}
    assert 20 <= len(expected) < len(va)
    found = matches(side(va), side(vb), k_nearest=1, mutual=True, max_distance=10.0)
    assert found == expected


def test_the_ratio_test_keeps_only_clear_nearest_neighbours(descriptors) -> None:
    va, vb, distance = descriptors
    ordered = np.sort(distance, axis=1)
    clear = ordered[:, 0] <= 0.5 * ordered[:, 1]
    expected = {(i, int(distance[i].argmin())) for i in np.flatnonzero(clear)}
    assert 0 < len(expected) < len(va)
    found = matches(side(va), side(vb), k_nearest=1, ratio=0.5, max_distance=10.0)
    assert found == expected


def test_openings_too_different_never_match() -> None:
    values = np.eye(4)[:, :3] / 3  # four distinct descriptors
    opening_a = np.array([90.0, 90.0, math.nan, 45.0])
    opening_b = np.array([90.0, 150.0, 30.0, 46.0])
    found = matches(
        side(values, opening_a),
        side(values, opening_b),
        k_nearest=4,
        max_distance=10.0,
        max_opening_difference=20.0,
    )
    allowed = {
        (i, j)
        for i in range(4)
        for j in range(4)
        if math.isnan(opening_a[i]) or abs(opening_a[i] - opening_b[j]) <= 20.0
    }
    assert {(2, j) for j in range(4)} <= allowed  # an unknown (NaN) opening passes
    assert len(allowed) == 8 and found == allowed


def test_no_keypoints_no_matches() -> None:
    empty = side(np.zeros((0, 12)))
    assert matches(empty, side(np.ones((3, 12))), max_distance=1.0) == set()
    assert matches(side(np.ones((3, 12))), empty, max_distance=1.0) == set()
