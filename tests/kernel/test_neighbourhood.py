"""The neighbourhood walks agree with each other: :func:`counts` and :func:`extend` (bit
masks, W points at a time) against :func:`reach` and :func:`within` (running maximum, point
by point), on every point of scans with gaps, runs longer than a chunk and radii equal to a
point's distance."""

from __future__ import annotations

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from laser_corners.kernel.neighbourhood import PAD, counts, extend, padded, reach, within
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
            expected = reach(int(j), step, px, py, r2_max, r2_a, r2_b, running_max, True)
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
