"""The neighbourhood walks agree with each other: :func:`counts` and :func:`extend` (bit
masks, W points at a time) against :func:`reach` and :func:`within` (running maximum, point
by point), on every point of scans with gaps, runs longer than a chunk and radii equal to a
point's distance."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from laser_corners.kernel.neighbourhood import (
    PAD,
    block_boxes,
    counts,
    extend,
    links,
    padded,
    reach,
    walk,
    within,
)
from laser_corners.kernel.simd import W

FAST = settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])


def both_walks(x: np.ndarray, y: np.ndarray, radii: tuple[float, float, float]) -> None:
    """Assert the same three counts from both walks, both sides, for every valid point."""
    valid = np.isfinite(x) & np.isfinite(y)
    px, py = padded(x, y, valid)
    r2_a, r2_b, r2_max = (r * r if r > 0 else -1.0 for r in radii)
    running_max = np.empty(x.shape[0] + PAD)
    far = px.shape[0]
    for j in np.flatnonzero(valid):
        for step in (-1, 1):
            expected = reach(int(j), step, px, py, (r2_max, r2_a, r2_b), running_max, True)
            got = counts(int(j), step, px, py, r2_max, r2_a, r2_b)
            assert got == expected, (int(j), step, got, expected)
            # extend: the count of the middle radius from those of the smaller and larger one
            steps, lo, mid = expected
            assert within(running_max, steps, r2_b) == mid
            for hi in (steps, far):
                assert extend(int(j), step, px, py, lo, hi, r2_b) == mid, (int(j), step, hi)


@FAST
@given(
    n=st.integers(1, 5 * W),
    spacing=st.floats(0.001, 0.05),
    noise=st.floats(0.0, 0.05),
    gap_rate=st.floats(0.0, 0.2),
    radii=st.tuples(st.floats(0.0, 0.1), st.floats(0.0, 0.2), st.floats(0.01, 0.4)),
    seed=st.integers(0, 2**16),
)
def test_counts_equal_reach_on_noisy_lines_with_gaps(n, spacing, noise, gap_rate, radii, seed):
    rng = np.random.default_rng(seed)
    x = spacing * np.arange(n) + rng.normal(0.0, noise, n)
    y = rng.normal(0.0, noise, n)
    x[rng.random(n) < gap_rate] = np.nan
    both_walks(x, y, tuple(sorted(radii)))  # type: ignore[arg-type]


def test_counts_equal_reach_on_ties_and_long_runs() -> None:
    # points exactly at a radius (d2 == r2 is within), and runs of several chunks
    x = np.concatenate([np.arange(4 * W + 3) * 0.25, [np.nan], np.arange(W) * 0.5])
    y = np.zeros_like(x)
    both_walks(x, y, (0.25, 0.5, 2.0))
    both_walks(x, y, (0.0, 0.0, 100.0))  # no smaller sentinels; every point within
    both_walks(np.array([1.0]), np.array([2.0]), (0.1, 0.2, 0.3))  # one point


def plain_walk(x, y, j: int, step: int, r2: np.ndarray, max_gap: int) -> list[int]:
    """The dense walk's bounds point by point, from its definition (no blocks, no guesses)."""
    n = x.shape[0]
    bounds, k, last, i = [], 0, j, j + step
    while k < len(r2) and 0 <= i < n:
        if not np.isfinite(x[i]):
            g = i
            while 0 <= g < n and not np.isfinite(x[g]):
                g += step
            if not 0 <= g < n or abs(g - i) >= max_gap + 1:
                break
            i = g
            continue
        d2 = (x[i] - x[j]) ** 2 + (y[i] - y[j]) ** 2
        while k < len(r2) and d2 > r2[k]:
            bounds.append(last)
            k += 1
        last, i = i, i + step
    return bounds + [last] * (len(r2) - k)


@pytest.mark.parametrize("max_gap", [0, 2])
def test_dense_walk_bounds_do_not_depend_on_its_guesses(max_gap: int) -> None:
    """:func:`walk` with the previous point's bounds as guesses (its jumps), with wrong and
    absurd guesses, equals the plain point-by-point walk: on a noisy polyline with a corner,
    a loop back, gaps and thousands of points within the largest radius."""
    rng = np.random.default_rng(7)
    t = np.arange(6000) * 0.0004
    x = np.where(t < 1.2, t, 1.2 - 0.3 * (t - 1.2)) + rng.normal(0.0, 0.001, t.size)
    y = np.where(t < 1.2, 0.0, t - 1.2) + rng.normal(0.0, 0.001, t.size)
    x[rng.random(t.size) < 0.002] = np.nan  # dropouts: bridged with max_gap > 0, else ends
    x[3000:3004] = np.nan
    y[np.isnan(x)] = np.nan
    valid = np.isfinite(x)
    lk = (*links(valid), *padded(x, y, valid))
    box = block_boxes(x, y, valid, max_gap)
    r2 = np.array([0.05, 0.2, 0.21, 0.5, 0.9]) ** 2
    guesses = {step: np.full(r2.size, -1, dtype=np.int64) for step in (-1, 1)}
    for j in np.flatnonzero(valid)[::7]:
        for step in (-1, 1):
            expected = plain_walk(x, y, int(j), step, r2, max_gap)
            bound = guesses[step]  # the previous point's bounds, as in the kernel
            walk(int(j), step, x, y, valid, lk, box, r2, max_gap, bound)
            assert bound.tolist() == expected, (int(j), step)
            for wrong in (bound + rng.integers(-50, 50, r2.size), np.full(r2.size, 10**9)):
                bad = wrong.astype(np.int64)
                walk(int(j), step, x, y, valid, lk, box, r2, max_gap, bad)
                assert bad.tolist() == expected, (int(j), step, wrong.tolist())


def test_dense_walk_where_the_noise_spans_many_beams() -> None:
    """:func:`walk` equals the plain point-by-point walk on a wall 50 times denser than its
    range noise (1 mm at 20 µm spacing, as a 1,000,000-beam scan): the band of beams near
    each bound, checked W at a time in steps of up to _CHUNKS · W beams, spans a hundred
    beams; the scan's ends lie within the radii (the steps stop at the padding)."""
    rng = np.random.default_rng(21)
    t = np.arange(20000) * 0.00002
    x = t + rng.normal(0.0, 0.0002, t.size)
    y = 0.3 * t + rng.normal(0.0, 0.001, t.size)
    valid = np.isfinite(x)
    lk = (*links(valid), *padded(x, y, valid))
    box = block_boxes(x, y, valid, 0)
    r2 = np.array([0.01, 0.03, 0.05, 0.2]) ** 2
    guesses = {step: np.full(r2.size, -1, dtype=np.int64) for step in (-1, 1)}
    for j in range(0, t.size, 97):
        for step in (-1, 1):
            expected = plain_walk(x, y, j, step, r2, 0)
            bound = guesses[step]
            walk(j, step, x, y, valid, lk, box, r2, 0, bound)
            assert bound.tolist() == expected, (j, step)
            bad = (bound + rng.integers(-300, 300, r2.size)).astype(np.int64)
            walk(j, step, x, y, valid, lk, box, r2, 0, bad)
            assert bad.tolist() == expected, (j, step)


@pytest.mark.parametrize("oriented", [True, False])
@pytest.mark.parametrize("max_gap", [1, 2, 3])
def test_dense_walk_bridges_frequent_dropouts(max_gap: int, oriented: bool) -> None:
    """The dense walk with 3 % dropouts in runs of 1 to 4 beams (blocks whose boxes leave the
    bridged gaps out) equals the plain point-by-point walk, with the previous point's bounds
    and absurd ones as guesses."""
    rng = np.random.default_rng(11 + max_gap)
    t = np.arange(8000) * 0.0003
    x = np.where(t < 1.2, t, 1.2 - 0.5 * (t - 1.2)) + rng.normal(0.0, 0.001, t.size)
    y = np.where(t < 1.2, 0.0, t - 1.2) + rng.normal(0.0, 0.001, t.size)
    for s in np.flatnonzero(rng.random(t.size) < 0.03):
        x[s : s + rng.integers(1, 5)] = np.nan
    y[np.isnan(x)] = np.nan
    valid = np.isfinite(x)
    lk = (*links(valid), *padded(x, y, valid))
    box = block_boxes(x, y, valid, max_gap, oriented)
    r2 = np.array([0.05, 0.125, 0.2, 0.25]) ** 2
    guesses = {step: np.full(r2.size, -1, dtype=np.int64) for step in (-1, 1)}
    for j in np.flatnonzero(valid)[::5]:
        for step in (-1, 1):
            expected = plain_walk(x, y, int(j), step, r2, max_gap)
            bound = guesses[step]
            walk(int(j), step, x, y, valid, lk, box, r2, max_gap, bound)
            assert bound.tolist() == expected, (int(j), step)
            bad = np.full(r2.size, 10**9, dtype=np.int64)
            walk(int(j), step, x, y, valid, lk, box, r2, max_gap, bad)
            assert bad.tolist() == expected, (int(j), step)
