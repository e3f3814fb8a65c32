"""Range-noise estimation from a scan itself (no ground truth needed)."""

from __future__ import annotations

import math

import numba as nb
import numpy as np
from numpy.typing import NDArray

from laser_corners.scan import LaserScan

__all__ = ["estimate_range_noise", "second_difference_sigma"]

_MAD_TO_SIGMA = 1.482602218505602  # 1 / Phi^-1(3/4): MAD of a Gaussian -> its sigma


def estimate_range_noise(scan: LaserScan, max_jump: float = 0.2) -> float:
    """Robust estimate of the range noise sigma of a scan, metres.

    On a smooth surface sampled at a fine angular step, the second difference of the ranges
    ``r[i-1] - 2 r[i] + r[i+1]`` is almost pure noise with variance ``6 sigma^2``; corners,
    edges and curved objects are a minority of the triples, so the median absolute second
    difference, scaled by ``1.4826 / sqrt(6)``, estimates sigma. Triples with a gap or a
    jump larger than ``max_jump`` metres are left out.

    Parameters
    ----------
    scan : LaserScan
        The scan.
    max_jump : float
        Largest first difference (metres) of a triple that is used.

    Returns
    -------
    float
        The estimated sigma (0.0 when fewer than 10 triples are usable).

    Examples
    --------
    >>> import numpy as np
    >>> from laser_corners.sim import rectangular_room
    >>> scan = rectangular_room().scan((0.0, 0.0, 0.0), noise_sigma=0.02,
    ...                                rng=np.random.default_rng(0))
    >>> round(estimate_range_noise(scan), 2)
    0.02
    """
    return float(second_difference_sigma(np.where(scan.valid, scan.ranges, np.nan), max_jump))


@nb.njit(cache=True, nogil=True, error_model="numpy")
def second_difference_sigma(r: NDArray[np.float64], max_jump: float) -> float:
    """The estimator of :func:`estimate_range_noise` on ranges in beam order (NaN: a gap).

    Also called from numba code (:mod:`laser_corners.kernel.covariance`, on the ranges of the scan's
    points).
    """
    n = r.shape[0]
    vals = np.empty(max(n - 2, 0))
    m = 0
    for i in range(1, n - 1):
        back = r[i] - r[i - 1]
        ahead = r[i + 1] - r[i]
        d2 = ahead - back
        if math.isfinite(d2) and abs(ahead) < max_jump and abs(back) < max_jump:
            vals[m] = abs(d2)
            m += 1
    if m < 10:
        return 0.0
    return _MAD_TO_SIGMA * np.median(vals[:m]) / math.sqrt(6.0)
