"""The matcher's kernel arguments, by name: options, one scan (a side), many scans (a bank).

numba takes named tuples as arguments and reads their fields by name, so a matcher option
keeps one name from :class:`~laser_corners.matching.MatchOptions` (``scan_tolerance``) to the
innermost kernel (``options.scan_tolerance``). :meth:`MatchOptions.kernel_options
<laser_corners.matching.MatchOptions.kernel_options>` is the one conversion into
:class:`KernelOptions`; :func:`~laser_corners.matching.registration.side_arrays` and
:meth:`KeypointBank.arrays <laser_corners.matching.KeypointBank.arrays>` build the
:class:`Side` and :class:`Bank` tuples (a bank's arrays are a :class:`Side` of all its scans
with :class:`Offsets`, so the arrays of a scan have one list of names).
"""

from __future__ import annotations

from typing import NamedTuple

import numba as nb
import numpy as np
from numpy.typing import NDArray

__all__ = [
    "Bank",
    "KernelOptions",
    "Offsets",
    "ScanArrays",
    "ScanGeometry",
    "Side",
    "scan_geometry",
    "side_scan",
]


class KernelOptions(NamedTuple):
    """:class:`~laser_corners.matching.MatchOptions` as the kernels read it (same names).

    ``verification`` is :data:`~laser_corners.matching.core.VERIFY_RANSAC` or
    :data:`~laser_corners.matching.core.VERIFY_CLIQUE`; ``max_distance`` is resolved for the
    descriptor kind. Every other field is the option of the same name.
    """

    min_inliers: int
    tolerance: float
    k_nearest: int
    ratio: float
    mutual: bool
    max_distance: float
    verification: int
    iterations: int
    min_separation: float
    seed: int
    default_sigma: float
    angle_tolerance: float
    max_opening_difference: float
    single_point: bool
    max_hypotheses: int
    verify_scan: bool
    scan_tolerance: float
    min_scan_agreement: float
    max_scan_conflict: float
    min_scan_points: int
    align_iterations: int


class ScanArrays(NamedTuple):
    """One scan as the scan check reads it (:func:`~laser_corners.matching.verify.scan_arrays`):
    ``ranges`` (NaN where a beam has no valid return), ``geometry`` ``(angle_min,
    angle_increment, range_min, range_max)`` and ``points``, the valid points evenly thinned
    (sensor frame). Empty arrays without a scan (the check must then be off)."""

    ranges: NDArray[np.float64]
    geometry: NDArray[np.float64]
    points: NDArray[np.float64]


class Side(NamedTuple):
    """One scan's keypoints, descriptors and (for the scan check) its :class:`ScanArrays`
    fields, flat (numba's parallel loops take tuples of arrays, not tuples of tuples);
    :func:`side_scan` gives the scan part."""

    xy: NDArray[np.float64]
    cov: NDArray[np.float64]
    orientation: NDArray[np.float64]
    opening: NDArray[np.float64]
    bits: NDArray[np.uint64]
    values: NDArray[np.float64]
    ranges: NDArray[np.float64]
    geometry: NDArray[np.float64]
    points: NDArray[np.float64]


class Offsets(NamedTuple):
    """Where each scan's rows start in a :class:`Bank`: scan ``s`` owns keypoint rows
    ``keypoints[s]:keypoints[s+1]``, ranges ``ranges[s]:...`` and check points
    ``points[s]:...`` (its geometry is row ``s``)."""

    keypoints: NDArray[np.int64]
    ranges: NDArray[np.int64]
    points: NDArray[np.int64]


class Bank(NamedTuple):
    """Many scans in flat arrays (:class:`~laser_corners.matching.KeypointBank`): ``rows``
    is a :class:`Side` of every scan's arrays one after the other (geometry one row per
    scan), ``offsets`` says where each scan's rows are. A parallel kernel takes the two
    as separate arguments (numba's parallel loops take flat tuples only)."""

    rows: Side
    offsets: Offsets


@nb.njit(cache=True, nogil=True, inline="always")
def side_scan(side: Side) -> ScanArrays:
    """The scan check's arrays of a side."""
    return ScanArrays(side.ranges, side.geometry, side.points)


class ScanGeometry(NamedTuple):
    """A scan's beam geometry as the kernels read it (:func:`scan_geometry`)."""

    angle_min: float
    angle_increment: float
    range_min: float
    range_max: float


@nb.njit(cache=True, nogil=True, inline="always")
def scan_geometry(geometry: NDArray[np.float64]) -> ScanGeometry:
    """The :class:`ScanGeometry` of a geometry row ``(angle_min, angle_increment, range_min,
    range_max)`` (:func:`~laser_corners.matching.verify.scan_arrays`): the one place that
    reads the row by position."""
    return ScanGeometry(geometry[0], geometry[1], geometry[2], geometry[3])
