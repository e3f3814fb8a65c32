"""The vector primitive of the neighbourhood walk (:mod:`laser_corners.kernel.simd`): every mask
bit equals the scalar test ``(x - xj)² + (y - yj)² > r²``, NaN points never farther."""

from __future__ import annotations

import numba as nb
import numpy as np
import pytest

from laser_corners.kernel.simd import W, far_masks


@nb.njit(cache=False)
def _masks(px, py, base, xj, yj, r2_a, r2_b, r2_c):  # type: ignore[no-untyped-def]
    return far_masks(px, py, base, xj, yj, r2_a, r2_b, r2_c)


def _bits(mask: int) -> list[bool]:
    return [bool(mask >> t & 1) for t in range(W)]


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_each_bit_is_the_scalar_comparison(seed: int) -> None:
    rng = np.random.default_rng(seed)
    px, py = rng.uniform(-1.0, 1.0, (2, 3 * W))
    base, (xj, yj) = W // 2, rng.uniform(-0.5, 0.5, 2)
    px[base + 5] = np.nan  # no return: never farther
    radii2 = (0.3, 0.8, 1.6)
    masks = _masks(px, py, base, xj, yj, *radii2)
    window = slice(base, base + W)
    d2 = (px[window] - xj) * (px[window] - xj) + (py[window] - yj) * (py[window] - yj)
    for mask, r2 in zip(masks, radii2, strict=True):
        assert _bits(mask) == (d2 > r2).tolist()
        assert 0 <= mask < 2**W
    assert len(set(masks)) == 3  # the radii split the points differently: a real test
    assert not _bits(masks[0])[5]  # the NaN point


def test_a_point_at_exactly_the_radius_is_not_farther() -> None:
    px = np.zeros(W)
    py = np.zeros(W)
    px[3] = 0.5  # d² = 0.25 exactly
    px[4] = 0.5000001
    ma, mb, mc = _masks(px, py, 0, 0.0, 0.0, 0.25, 0.0, 1.0)
    assert _bits(ma)[3] is False and _bits(ma)[4] is True
    assert mb == 0b11000 and mc == 0  # only the two points beyond radius 0 are farther
