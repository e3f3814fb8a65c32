"""Baseline corner detector: split-and-merge line segments, corners where segments meet.

The classic line-extraction pipeline (adaptive breakpoints, iterative end-point fit "split",
collinear "merge", total-least-squares fits) followed by corners at the intersection of
consecutive segments that meet at an opening angle in [``min_angle_deg``, ``max_angle_deg``].
Its :meth:`SplitAndMergeDetector.detect` returns :class:`~laser_corners.Keypoints` like
:meth:`laser_corners.CornerDetector.detect`, so the evaluations run both the same way.

References
----------
.. [1] Nguyen, V., Martinelli, A., Tomatis, N., Siegwart, R., "A comparison of line extraction
   algorithms using 2D laser rangefinder for indoor mobile robotics", IROS 2005.
.. [2] Borges, G. A., Aldon, M.-J., "Line extraction in 2D range images for mobile robotics",
   J. Intelligent and Robotic Systems 40, 2004 (adaptive breakpoint detector).
"""

from __future__ import annotations

import math
from itertools import pairwise
from typing import ClassVar

import numba as nb
import numpy as np
from numpy.typing import NDArray
from pydantic import Field, model_validator

from laser_corners.errors import InvalidScanError
from laser_corners.keypoints import Keypoints
from laser_corners.noise import estimate_range_noise
from laser_corners.options import Options
from laser_corners.scan import LaserScan

__all__ = ["SplitAndMergeDetector", "SplitAndMergeParams"]


class SplitAndMergeParams(Options):
    """Parameters of :class:`SplitAndMergeDetector`.

    Attributes
    ----------
    split_distance : float or None
        A segment is split where a point lies farther than this from its chord, and two
        neighbouring segments are merged when one line fits both within it, metres. ``None``:
        ``max(0.02, 0.01 + 4 sigma)`` with sigma the range noise estimated from each scan
        (:func:`~laser_corners.noise.estimate_range_noise`).
    min_points : int
        Fewest points of a segment.
    min_length : float
        Shortest segment, metres (drops the facets of legs and other small round things).
    breakpoint_angle_deg : float
        lambda of the adaptive breakpoint detector: consecutive points farther apart than
        ``r sin(dtheta) / sin(lambda - dtheta) + 3 sigma`` belong to different clusters.
    min_angle_deg, max_angle_deg : float
        Accepted opening angle between consecutive segments, degrees.
    max_corner_distance : float
        Largest distance from the lines' intersection to the segments' shared end, metres.
    """

    title: ClassVar[str] = "SplitAndMergeParams"

    split_distance: float | None = Field(None, gt=0.0)
    min_points: int = Field(5, ge=2)
    min_length: float = Field(0.1, ge=0.0)
    breakpoint_angle_deg: float = Field(10.0, gt=0.0, lt=180.0)
    min_angle_deg: float = Field(45.0, ge=0.0, le=180.0)
    max_angle_deg: float = Field(135.0, ge=0.0, le=180.0)
    max_corner_distance: float = Field(0.1, ge=0.0)

    @model_validator(mode="after")
    def _check_angles(self) -> SplitAndMergeParams:
        if self.min_angle_deg > self.max_angle_deg:
            raise ValueError("need min_angle_deg <= max_angle_deg")
        return self


@nb.njit(cache=True)
def _line_fit(points: NDArray[np.float64]) -> tuple[float, float, float, float, float, float]:
    """Total-least-squares line of ``points`` (M, 2), closed form of the 2x2 eigenproblem.

    Returns the centroid ``(cx, cy)``, the unit direction ``(dx, dy)`` (major axis of the
    scatter), the RMS and the largest orthogonal residual.
    """
    m = points.shape[0]
    cx = 0.0
    cy = 0.0
    for i in range(m):
        cx += points[i, 0]
        cy += points[i, 1]
    cx /= m
    cy /= m
    sxx = 0.0
    syy = 0.0
    sxy = 0.0
    for i in range(m):
        qx = points[i, 0] - cx
        qy = points[i, 1] - cy
        sxx += qx * qx
        syy += qy * qy
        sxy += qx * qy
    angle = 0.5 * math.atan2(2.0 * sxy, sxx - syy)  # major axis of the scatter matrix
    dx = math.cos(angle)
    dy = math.sin(angle)
    total = 0.0
    worst = 0.0
    for i in range(m):
        r = abs(-(points[i, 0] - cx) * dy + (points[i, 1] - cy) * dx)
        total += r * r
        worst = max(worst, r)
    return cx, cy, dx, dy, math.sqrt(total / m), worst


def _tls(points: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64], float]:
    """Total-least-squares line: centroid, unit direction, RMS orthogonal residual."""
    cx, cy, dx, dy, rms, _ = _line_fit(np.ascontiguousarray(points, dtype=np.float64))
    return np.array([cx, cy]), np.array([dx, dy]), rms


def _max_line_distance(points: NDArray[np.float64]) -> float:
    return _line_fit(np.ascontiguousarray(points, dtype=np.float64))[5]


class SplitAndMergeDetector:
    """Corners from split-and-merge line segments (the line-intersection baseline).

    Parameters
    ----------
    params : SplitAndMergeParams, optional
        Parameters; defaults when omitted.

    Examples
    --------
    >>> from laser_corners.sim import corner_scan
    >>> kps = SplitAndMergeDetector().detect(corner_scan())
    >>> len(kps), np.round(kps.xy, 2).tolist()
    (1, [[2.0, 1.0]])
    """

    def __init__(self, params: SplitAndMergeParams | None = None) -> None:
        self.params = params if params is not None else SplitAndMergeParams()

    def __repr__(self) -> str:
        return f"SplitAndMergeDetector({self.params!r})"

    def segments(self, scan: LaserScan) -> list[tuple[int, int]]:
        """Beam-index ranges ``(first, last)`` of the extracted line segments, in beam order."""
        if not isinstance(scan, LaserScan):
            raise InvalidScanError(f"expected a LaserScan, got {type(scan).__name__}")
        p = self.params
        sigma = estimate_range_noise(scan)
        split = p.split_distance if p.split_distance is not None else max(0.02, 0.01 + 4 * sigma)
        xy, valid = scan.to_cartesian()
        out: list[tuple[int, int]] = []
        for first, last in self._clusters(scan, valid, xy, sigma):
            pieces = self._split(xy, first, last, split)
            pieces = self._merge(xy, pieces, split)
            out += [(s, e) for s, e in pieces if self._long_enough(xy, s, e)]
        return out

    def _long_enough(self, xy: NDArray[np.float64], s: int, e: int) -> bool:
        return e - s + 1 >= self.params.min_points and bool(
            np.hypot(*(xy[e] - xy[s])) >= self.params.min_length
        )

    def _clusters(
        self, scan: LaserScan, valid: NDArray[np.bool_], xy: NDArray[np.float64], sigma: float
    ) -> list[tuple[int, int]]:
        dtheta = abs(scan.angle_increment)
        lam = math.radians(self.params.breakpoint_angle_deg)
        r = np.where(valid, scan.ranges, np.nan)
        step = np.hypot(*(xy[1:] - xy[:-1]).T)
        limit = r[:-1] * math.sin(dtheta) / math.sin(max(lam - dtheta, 1e-3)) + 3 * sigma + 0.01
        joined = np.zeros(len(r), dtype=bool)  # joined[i]: point i continues the cluster of i-1
        with np.errstate(invalid="ignore"):
            joined[1:] = valid[1:] & valid[:-1] & (step <= limit)
        # a cluster starts at a valid point not joined to the previous one and runs until the
        # next point that is not joined (joined implies valid)
        starts = np.flatnonzero(valid & ~joined)
        breaks = np.flatnonzero(~joined)
        nxt = np.searchsorted(breaks, starts, side="right")
        ends = np.where(nxt < len(breaks), breaks[np.minimum(nxt, len(breaks) - 1)] - 1, len(r) - 1)
        keep = ends - starts + 1 >= self.params.min_points
        clusters = [(int(a), int(b)) for a, b in zip(starts[keep], ends[keep], strict=True)]
        return clusters

    def _split(
        self, xy: NDArray[np.float64], first: int, last: int, split: float
    ) -> list[tuple[int, int]]:
        stack = [(first, last)]
        done = []
        while stack:
            s, e = stack.pop()
            if e - s < 2:
                done.append((s, e))
                continue
            a, b = xy[s], xy[e]
            chord = b - a
            length = math.hypot(chord[0], chord[1])
            q = xy[s + 1 : e] - a
            if length > 0.0:
                dist = np.abs(q[:, 0] * chord[1] - q[:, 1] * chord[0]) / length
            else:
                dist = np.hypot(q[:, 0], q[:, 1])
            k = int(np.argmax(dist))
            if dist[k] > split:
                k += s + 1
                stack.append((k, e))
                stack.append((s, k))
            else:
                done.append((s, e))
        done.sort()
        return done

    def _merge(
        self, xy: NDArray[np.float64], pieces: list[tuple[int, int]], split: float
    ) -> list[tuple[int, int]]:
        merged = list(pieces)
        changed = True
        while changed and len(merged) > 1:
            changed = False
            for i in range(len(merged) - 1):
                s, _ = merged[i]
                _, e = merged[i + 1]
                if e - s + 1 >= 3 and _max_line_distance(xy[s : e + 1]) <= split:
                    merged[i : i + 2] = [(s, e)]
                    changed = True
                    break
        return merged

    def detect(self, scan: LaserScan) -> Keypoints:
        """Corner keypoints of one scan (sensor frame), like ``CornerDetector.detect``.

        ``n_scales`` is 1, ``rmse`` the worse of the two segments' TLS residuals,
        ``n_merged`` 1.
        """
        p = self.params
        segs = self.segments(scan)  # validates scan
        xy, _ = scan.to_cartesian()
        rows = []
        cos_min = math.cos(math.radians(p.min_angle_deg))
        cos_max = math.cos(math.radians(p.max_angle_deg))
        for (s1, e1), (s2, e2) in pairwise(segs):
            if s2 != e1:  # only segments that share their end point (split there)
                continue
            pts_a = xy[s1:e1]  # the shared point belongs to neither fit
            pts_b = xy[s2 + 1 : e2 + 1]
            if len(pts_a) < 2 or len(pts_b) < 2:
                continue
            ca, da, rms_a = _tls(pts_a)
            cb, db, rms_b = _tls(pts_b)
            det = da[0] * (-db[1]) - da[1] * (-db[0])
            if abs(det) < 1e-12:
                continue
            w = cb - ca
            t = (w[0] * (-db[1]) - w[1] * (-db[0])) / det
            corner = ca + t * da
            if np.hypot(*(corner - xy[e1])) > p.max_corner_distance:
                continue
            ua = da if np.dot(xy[s1] - corner, da) >= 0 else -da
            ub = db if np.dot(xy[e2] - corner, db) >= 0 else -db
            cos_open = float(np.clip(np.dot(ua, ub), -1.0, 1.0))
            if cos_open > cos_min or cos_open < cos_max:
                continue
            bis = ua + ub
            rows.append(
                (
                    corner[0],
                    corner[1],
                    e1,
                    math.degrees(math.acos(cos_open)),
                    math.atan2(bis[1], bis[0]),
                    max(rms_a, rms_b),
                )
            )
        if not rows:
            return Keypoints.empty(stamp=scan.stamp, frame_id=scan.frame_id)
        a = np.array(rows)
        ones = np.ones(len(rows), dtype=np.int64)
        return Keypoints(
            xy=a[:, :2],
            beam_index=a[:, 2].astype(np.int64),
            opening_angle_deg=a[:, 3],
            orientation=a[:, 4],
            n_scales=ones,
            rmse=a[:, 5],
            n_merged=ones,
            stamp=scan.stamp,
            frame_id=scan.frame_id,
        )

    def detect_many(self, scans: list[LaserScan]) -> list[Keypoints]:
        """:meth:`detect` over a list of scans."""
        return [self.detect(scan) for scan in scans]
