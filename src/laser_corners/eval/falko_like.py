"""``falko-like``: our reading of the FALKO paper's keypoint score (detection only), NOT FALKO.

FALKO (Kallasi, Lodi Rizzini, Caselli, RA-L 2016) looks at each scan point p_i with a
neighbourhood whose radius grows with the range, ``r_i = a exp(b rho_i)``, split by beam order
into a left and a right part. p_i is a corner candidate when both parts hold enough points and
the triangle (p_L, p_i, p_R) of the farthest points of each part is a proper corner: both
sides long enough compared with r_i and an apex angle clearly below a straight line. Each
candidate gets a cornerness score from a polar grid of angular sectors centred on p_i: the
points of a straight side fall in one sector, so the score (the sum, over each side, of the
sector distances between its points) is lowest at the true apex. Non-maximum suppression keeps
the best-scoring candidate within a radius. The keypoint is the scan point itself.

This is a *comparison* detector for :mod:`laser_corners.eval`, written from the paper's text; it
is not falkolib (the authors' C++ library) and does not behave like it. Measured side by side
with falkolib (commit 836b412, the parameters of its ``testKeypointFalko.cpp``) on the scan
pairs of ``evaluate real``, repeatability at r = 0.05 / 0.1 m, falkolib vs falko-like: fr079.bag
36.4 / 46.9 % vs 43.7 / 66.3 %; aces.bag 10.0 / 17.2 % vs 22.1 / 51.4 %; intel-corrected
32.7 / 38.8 % vs 45.2 / 70.4 %; falko-like finds 2x (fr079) to 7x (aces) as many keypoints. No
descriptors, no sub-beam refinement. See ``docs/real-evaluation.md``.

References
----------
.. [1] Kallasi, F., Lodi Rizzini, D., Caselli, S., "Fast Keypoint Features From Laser Scanner
   for Robot Localization and Mapping", IEEE Robotics and Automation Letters 1(1), 2016.
   doi:10.1109/LRA.2016.2517210
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from typing import ClassVar

import numba as nb
import numpy as np
from numpy.typing import NDArray
from pydantic import Field, model_validator

from laser_corners.errors import InvalidScanError
from laser_corners.keypoints import Keypoints
from laser_corners.options import Options
from laser_corners.scan import LaserScan

__all__ = ["FalkoLikeDetector", "FalkoLikeParams"]


class FalkoLikeParams(Options):
    """Parameters of :class:`FalkoLikeDetector`.

    Attributes
    ----------
    neigh_a, neigh_b : float
        Neighbourhood radius ``r = neigh_a * exp(neigh_b * range)``, metres.
    min_neighbours : int
        Fewest points in each of the left and right neighbourhoods (p_i excluded).
    side_ratio : float
        Each triangle side |p_i p_L|, |p_i p_R| must be at least ``r / side_ratio``.
    min_apex_deg, max_apex_deg : float
        Accepted apex angle of the triangle at p_i, degrees.
    sectors : int
        Angular sectors of the polar grid used by the score.
    max_mean_sector_distance : float
        Largest mean sector distance between points of the same side (0: perfectly straight
        sides); larger values reject rounded or cluttered neighbourhoods.
    nms_radius : float
        Non-maximum suppression radius, metres.
    min_range, max_range : float
        Only points with a range in this interval are considered, metres.
    """

    title: ClassVar[str] = "FalkoLikeParams"

    neigh_a: float = Field(0.1, gt=0.0, allow_inf_nan=False)
    neigh_b: float = Field(0.07, allow_inf_nan=False)
    min_neighbours: int = Field(2, ge=1)
    side_ratio: float = Field(2.0, ge=1.0)
    min_apex_deg: float = Field(30.0, ge=0.0, le=180.0)
    max_apex_deg: float = Field(150.0, ge=0.0, le=180.0)
    sectors: int = Field(16, ge=4)
    max_mean_sector_distance: float = Field(1.0, ge=0.0)
    nms_radius: float = Field(0.1, ge=0.0)
    min_range: float = Field(0.1, ge=0.0)
    max_range: float = Field(30.0, gt=0.0)

    @model_validator(mode="after")
    def _check_apex(self) -> FalkoLikeParams:
        if not self.min_apex_deg < self.max_apex_deg:
            raise ValueError("need min_apex_deg < max_apex_deg")
        return self


@nb.njit(cache=True)
def _sector_dispersion(
    x: NDArray[np.float64], y: NDArray[np.float64], i: int, lo: int, hi: int, sectors: int
) -> tuple[float, int]:
    """Sum of circular sector distances over all point pairs of ``[lo, hi]`` seen from p_i."""
    width = 2.0 * math.pi / sectors
    m = hi - lo + 1
    q = np.empty(m, dtype=np.int64)
    for k in range(m):
        a = math.atan2(y[lo + k] - y[i], x[lo + k] - x[i])
        if a < 0.0:
            a += 2.0 * math.pi
        q[k] = min(int(a / width), sectors - 1)
    total = 0.0
    for u in range(m):
        for v in range(u + 1, m):
            d = abs(q[u] - q[v])
            total += min(d, sectors - d)
    return total, m * (m - 1) // 2


@nb.njit(cache=True)
def _falko_candidates(
    x: NDArray[np.float64],
    y: NDArray[np.float64],
    rho: NDArray[np.float64],
    neigh_a: float,
    neigh_b: float,
    min_neighbours: int,
    side_ratio: float,
    cos_min_apex: float,
    cos_max_apex: float,
    sectors: int,
    max_mean_sector_distance: float,
    min_range: float,
    max_range: float,
    out: NDArray[np.float64],
) -> int:
    """Rows of ``out``: beam, score, height, apex deg, bisector angle. Returns the count."""
    n = x.shape[0]
    m = 0
    for i in range(n):
        if not math.isfinite(x[i]) or rho[i] < min_range or rho[i] > max_range:
            continue
        r = neigh_a * math.exp(neigh_b * rho[i])
        r2 = r * r
        lo = i
        while lo - 1 >= 0 and math.isfinite(x[lo - 1]):
            if (x[lo - 1] - x[i]) ** 2 + (y[lo - 1] - y[i]) ** 2 > r2:
                break
            lo -= 1
        hi = i
        while hi + 1 < n and math.isfinite(x[hi + 1]):
            if (x[hi + 1] - x[i]) ** 2 + (y[hi + 1] - y[i]) ** 2 > r2:
                break
            hi += 1
        if i - lo < min_neighbours or hi - i < min_neighbours:
            continue
        lx = x[lo] - x[i]
        ly = y[lo] - y[i]
        rx = x[hi] - x[i]
        ry = y[hi] - y[i]
        side_l = math.sqrt(lx * lx + ly * ly)
        side_r = math.sqrt(rx * rx + ry * ry)
        if side_l < r / side_ratio or side_r < r / side_ratio:
            continue
        cos_apex = (lx * rx + ly * ry) / (side_l * side_r)
        if cos_apex > cos_min_apex or cos_apex < cos_max_apex:
            continue
        disp_l, pairs_l = _sector_dispersion(x, y, i, lo, i - 1, sectors)
        disp_r, pairs_r = _sector_dispersion(x, y, i, i + 1, hi, sectors)
        if (disp_l + disp_r) > max_mean_sector_distance * (pairs_l + pairs_r):
            continue
        # triangle height over the base p_L p_R: larger is a more distinct corner
        bx = x[hi] - x[lo]
        by = y[hi] - y[lo]
        base = math.sqrt(bx * bx + by * by)
        height = abs(bx * ly - by * lx) / base if base > 0.0 else 0.0
        ux = lx / side_l + rx / side_r
        uy = ly / side_l + ry / side_r
        out[m, 0] = i
        out[m, 1] = (disp_l + disp_r) / max(pairs_l + pairs_r, 1)
        out[m, 2] = height
        out[m, 3] = math.degrees(math.acos(min(1.0, max(-1.0, cos_apex))))
        out[m, 4] = math.atan2(uy, ux)
        m += 1
    return m


class FalkoLikeDetector:
    """``falko-like``: our reading of FALKO's keypoint detection (Kallasi et al., RA-L 2016).

    Not falkolib: see the module docstring for how the two differ on real data.

    Parameters
    ----------
    params : FalkoLikeParams, optional
        Detector parameters.

    References
    ----------
    .. [1] Kallasi, F., Lodi Rizzini, D., Caselli, S., "Fast Keypoint Features From Laser
       Scanner for Robot Localization and Mapping", IEEE RA-L 1(1), 2016.

    Examples
    --------
    >>> import numpy as np
    >>> from laser_corners.sim import corner_scan
    >>> kps = FalkoLikeDetector().detect(corner_scan())
    >>> len(kps), np.round(kps.xy, 1).tolist()
    (1, [[2.0, 1.0]])
    """

    def __init__(self, params: FalkoLikeParams | None = None) -> None:
        self.params = params if params is not None else FalkoLikeParams()

    def __repr__(self) -> str:
        return f"FalkoLikeDetector({self.params!r})"

    def detect(self, scan: LaserScan) -> Keypoints:
        """Detect keypoints in one scan (sensor frame; each keypoint is a scan point)."""
        if not isinstance(scan, LaserScan):
            raise InvalidScanError(f"expected a LaserScan, got {type(scan).__name__}")
        p = self.params
        xy, valid = scan.to_cartesian()
        x = np.ascontiguousarray(xy[:, 0])
        y = np.ascontiguousarray(xy[:, 1])
        rho = np.where(valid, scan.ranges, np.nan)
        rows = np.empty((scan.n_beams, 5))
        m = _falko_candidates(
            x,
            y,
            rho,
            p.neigh_a,
            p.neigh_b,
            p.min_neighbours,
            p.side_ratio,
            math.cos(math.radians(p.min_apex_deg)),
            math.cos(math.radians(p.max_apex_deg)),
            p.sectors,
            p.max_mean_sector_distance,
            p.min_range,
            p.max_range,
            rows,
        )
        rows = rows[:m]
        beams = rows[:, 0].astype(np.int64)
        # non-maximum suppression: lowest score first, then the larger triangle height
        order = np.lexsort((-rows[:, 2], rows[:, 1]))
        kept: list[int] = []
        for k in order:
            pk = xy[beams[k]]
            if all(np.hypot(*(pk - xy[beams[j]])) > p.nms_radius for j in kept):
                kept.append(int(k))
        kept.sort(key=lambda k: beams[k])
        sel = np.asarray(kept, dtype=np.int64)
        n_kept = sel.shape[0]
        return Keypoints(
            xy=xy[beams[sel]] if n_kept else np.zeros((0, 2)),
            beam_index=beams[sel],
            opening_angle_deg=rows[sel, 3],
            orientation=rows[sel, 4],
            n_scales=np.ones(n_kept, dtype=np.int64),
            rmse=np.full(n_kept, np.nan),
            n_merged=np.ones(n_kept, dtype=np.int64),
            stamp=scan.stamp,
            frame_id=scan.frame_id,
        )

    def detect_many(self, scans: Iterable[LaserScan]) -> list[Keypoints]:
        """:meth:`detect` on each scan."""
        return [self.detect(scan) for scan in scans]
