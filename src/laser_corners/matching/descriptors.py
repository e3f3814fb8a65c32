"""Rotation-invariant descriptors of the scan around a keypoint (numba).

Both descriptors live on a polar grid centred on the keypoint whose angular origin is the
keypoint's ``orientation`` (the bisector of its opening), so a rotation of the scan leaves
them unchanged (up to the sampling of the walls by the beams).

``bsc`` -- binary shape context, FALKO's family (Kallasi, Rizzini, Caselli, "Fast Keypoint
    Features from Laser Scanner for Robot Localization and Mapping", IEEE RA-L 2016): the disc
    of radius ``radius`` is split into ``n_sectors`` angular sectors (measured from the
    orientation) and ``n_rings`` rings of equal width; a cell's bit is 1 when at least one
    scan point falls in it. Distance: Hamming, divided by the number of bits (in [0, 1]).
    Bits are packed in uint64 words, the distance is an XOR and a popcount per word.
    Defaults as FALKO's (16 sectors, 8 rings); FALKO takes the keypoint's neighbourhood
    radius as the disc's radius, we use a fixed ``radius`` (2 m) for discrimination.

``csc`` -- corner context (ours): a shape-context histogram in the bisector-aligned frame,
    with ``n_sectors`` sectors (the two halves are the two wall sides of the corner) and
    ``n_rings`` log-spaced rings from ``inner`` to ``radius``; each scan point adds the length
    of surface it stands for (its distance to the next valid point, capped at ``max_step``),
    so the histogram measures wall length per cell and depends little on the viewpoint's
    range. The histogram is normalised to sum 1/2; one more entry holds the opening angle
    ``opening_weight * opening_deg / 180``. Distance: L1 (histogram part in [0, 1]), so two
    corners with different opening angles are far apart even when their surroundings agree.

The per-keypoint covariance is used by the registration (weighted least squares), not by the
descriptors.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, ClassVar, Literal

import numba as nb
import numpy as np
from numpy.typing import NDArray
from pydantic import Field

from laser_corners.keypoints import Keypoints
from laser_corners.options import Options
from laser_corners.scan import LaserScan

__all__ = ["DESCRIPTORS", "DescriptorParams", "Descriptors", "describe", "describe_points"]

DESCRIPTORS = ("bsc", "csc")
"""Descriptor kinds: ``bsc`` (FALKO's binary shape context) and ``csc`` (corner context)."""
KIND_BSC = 0
KIND_CSC = 1


class DescriptorParams(Options):
    """Parameters of a descriptor (see the module docstring).

    Attributes
    ----------
    kind : {"bsc", "csc"}
        Descriptor kind.
    radius : float
        Outer radius of the polar grid, metres (default 2.0 for bsc, 3.0 for csc).
    n_sectors : int
        Angular sectors, counted from the keypoint's orientation (default 16 bsc, 12 csc).
    n_rings : int
        Rings (default 8 equal-width rings for bsc, 5 log-spaced rings for csc).
    inner : float
        csc: inner radius of the first ring (points closer count in ring 0), metres.
    max_step : float
        csc: largest surface length one point stands for, metres.
    opening_weight : float
        csc: weight of the opening angle difference (per 180 degrees) in the distance.
    """

    title: ClassVar[str] = "DescriptorParams"

    kind: Literal["bsc", "csc"] = "csc"
    radius: float = Field(0.0, ge=0.0, allow_inf_nan=False)
    n_sectors: int = Field(0, ge=0)
    n_rings: int = Field(0, ge=0)
    inner: float = Field(0.1, gt=0.0, allow_inf_nan=False)
    max_step: float = Field(0.1, gt=0.0, allow_inf_nan=False)
    opening_weight: float = Field(0.5, ge=0.0, allow_inf_nan=False)

    def __init__(self, kind: str | None = None, /, **data: Any) -> None:
        if kind is not None:  # DescriptorParams("bsc", ...): the kind may come first
            data["kind"] = kind
        super().__init__(**data)

    def resolved(self) -> DescriptorParams:
        """A copy with the kind's defaults filled in (0 means default)."""
        bsc = self.kind == "bsc"
        return self.with_overrides(
            {
                "radius": self.radius or (2.0 if bsc else 3.0),
                "n_sectors": self.n_sectors or (16 if bsc else 12),
                "n_rings": self.n_rings or (8 if bsc else 5),
            }
        )


@dataclass(frozen=True)
class Descriptors:
    """Descriptors of the keypoints of one scan.

    Attributes
    ----------
    kind : str
        ``bsc`` or ``csc``.
    bits : ndarray, shape (M, W), uint64
        bsc: packed bits (W words); csc: shape (M, 0).
    values : ndarray, shape (M, D), float64
        csc: histogram and opening entry; bsc: shape (M, 0).
    n_bits : int
        bsc: number of cells (the Hamming distance is divided by it).
    """

    kind: str
    bits: NDArray[np.uint64]
    values: NDArray[np.float64]
    n_bits: int

    def __len__(self) -> int:
        return int(max(self.bits.shape[0], self.values.shape[0]))

    @property
    def kind_code(self) -> int:
        """0 for bsc, 1 for csc (the matcher's kernels take the code)."""
        return KIND_BSC if self.kind == "bsc" else KIND_CSC


@nb.njit(cache=True, nogil=True, error_model="numpy")
def _bsc(
    x: NDArray[np.float64],
    y: NDArray[np.float64],
    kxy: NDArray[np.float64],
    orient: NDArray[np.float64],
    radius: float,
    n_sectors: int,
    n_rings: int,
    out: NDArray[np.uint64],
) -> None:
    r2 = radius * radius
    two_pi = 2.0 * math.pi
    for m in range(kxy.shape[0]):
        for w in range(out.shape[1]):
            out[m, w] = np.uint64(0)
        cx = kxy[m, 0]
        cy = kxy[m, 1]
        th = orient[m]
        if not (math.isfinite(cx) and math.isfinite(cy) and math.isfinite(th)):
            continue  # no position or orientation: an empty descriptor
        for i in range(x.shape[0]):
            dx = x[i] - cx
            dy = y[i] - cy
            d2 = dx * dx + dy * dy
            if not d2 < r2:  # also skips gaps (NaN)
                continue
            a = (math.atan2(dy, dx) - th) % two_pi
            sector = max(0, min(int(a / two_pi * n_sectors), n_sectors - 1))
            ring = min(int(math.sqrt(d2) / radius * n_rings), n_rings - 1)
            cell = ring * n_sectors + sector
            out[m, cell >> 6] |= np.uint64(1) << np.uint64(cell & 63)


@nb.njit(cache=True, nogil=True, error_model="numpy")
def _csc(
    x: NDArray[np.float64],
    y: NDArray[np.float64],
    kxy: NDArray[np.float64],
    orient: NDArray[np.float64],
    opening: NDArray[np.float64],
    radius: float,
    n_sectors: int,
    n_rings: int,
    inner: float,
    max_step: float,
    opening_weight: float,
    out: NDArray[np.float64],
) -> None:
    n = x.shape[0]
    # surface length each point stands for: distance to the next valid neighbour, capped
    step = np.zeros(n)
    for i in range(n):
        if not math.isfinite(x[i]):
            continue
        s = max_step
        if i + 1 < n and math.isfinite(x[i + 1]):
            s = min(s, math.sqrt((x[i + 1] - x[i]) ** 2 + (y[i + 1] - y[i]) ** 2))
        elif i > 0 and math.isfinite(x[i - 1]):
            s = min(s, math.sqrt((x[i - 1] - x[i]) ** 2 + (y[i - 1] - y[i]) ** 2))
        step[i] = s
    r2 = radius * radius
    two_pi = 2.0 * math.pi
    log_span = math.log(radius / inner)
    n_hist = n_sectors * n_rings
    for m in range(kxy.shape[0]):
        for c in range(out.shape[1]):
            out[m, c] = 0.0
        cx = kxy[m, 0]
        cy = kxy[m, 1]
        th = orient[m]
        total = 0.0
        out[m, n_hist] = opening_weight * opening[m] / 180.0 if math.isfinite(opening[m]) else 0.0
        if not (math.isfinite(cx) and math.isfinite(cy) and math.isfinite(th)):
            continue  # no position or orientation: an empty histogram
        for i in range(n):
            dx = x[i] - cx
            dy = y[i] - cy
            d2 = dx * dx + dy * dy
            if not d2 < r2:
                continue
            a = (math.atan2(dy, dx) - th) % two_pi
            sector = max(0, min(int(a / two_pi * n_sectors), n_sectors - 1))
            d = math.sqrt(d2)
            ring = (
                0 if d <= inner else min(int(math.log(d / inner) / log_span * n_rings), n_rings - 1)
            )
            out[m, ring * n_sectors + sector] += step[i]
            total += step[i]
        if total > 0.0:
            for c in range(n_hist):
                out[m, c] *= 0.5 / total


def describe_points(
    xy: NDArray[np.float64], keypoints: Keypoints, params: DescriptorParams | None = None
) -> Descriptors:
    """Descriptors of ``keypoints`` from scan points ``xy`` (N, 2) in beam order (NaN: gap).

    Parameters
    ----------
    xy : ndarray, shape (N, 2)
        Scan points in the keypoints' frame.
    keypoints : Keypoints
        The keypoints (``xy``, ``orientation``, ``opening_angle_deg`` are used).
    params : DescriptorParams, optional
        Kind and grid; default: ``csc`` with its defaults.
    """
    p = (params or DescriptorParams()).resolved()
    pts = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
    x = np.ascontiguousarray(pts[:, 0])
    y = np.ascontiguousarray(pts[:, 1])
    m = len(keypoints)
    kxy = np.ascontiguousarray(keypoints.xy)
    orient = np.ascontiguousarray(keypoints.orientation, dtype=np.float64)
    if p.kind == "bsc":
        n_bits = p.n_sectors * p.n_rings
        bits = np.zeros((m, (n_bits + 63) // 64), dtype=np.uint64)
        _bsc(x, y, kxy, orient, p.radius, p.n_sectors, p.n_rings, bits)
        return Descriptors("bsc", bits, np.zeros((m, 0)), n_bits)
    values = np.zeros((m, p.n_sectors * p.n_rings + 1))
    opening = np.ascontiguousarray(keypoints.opening_angle_deg, dtype=np.float64)
    _csc(
        x,
        y,
        kxy,
        orient,
        opening,
        p.radius,
        p.n_sectors,
        p.n_rings,
        p.inner,
        p.max_step,
        p.opening_weight,
        values,
    )
    return Descriptors("csc", np.zeros((m, 0), dtype=np.uint64), values, 0)


def describe(
    scan: LaserScan,
    keypoints: Keypoints,
    descriptor: str | DescriptorParams = "csc",
) -> Descriptors:
    """Descriptors of the keypoints of ``scan`` (sensor frame).

    Parameters
    ----------
    scan : LaserScan
        The scan the keypoints were detected in.
    keypoints : Keypoints
        Its keypoints, in the sensor frame.
    descriptor : {"csc", "bsc"} or DescriptorParams
        Kind (with its defaults) or full parameters.

    Examples
    --------
    >>> from laser_corners import CornerDetector
    >>> from laser_corners.sim import corner_scan
    >>> scan = corner_scan()
    >>> d = describe(scan, CornerDetector().detect(scan), "bsc")
    >>> d.kind, d.bits.shape
    ('bsc', (1, 2))
    """
    params = (
        descriptor if isinstance(descriptor, DescriptorParams) else DescriptorParams(descriptor)
    )  # type: ignore[arg-type]
    xy, _ = scan.to_cartesian()
    return describe_points(xy, keypoints, params)
