"""Detector parameters: the paper's defaults, validated, loadable from YAML/TOML.

The field names below are the one parameter vocabulary of the project: they are the YAML/TOML
keys, the CLI's ``--set key=value`` keys, the ROS node's parameter names and what every output
folder records.
"""

from __future__ import annotations

import math
from itertools import pairwise
from typing import Any, ClassVar

from pydantic import Field, ValidationInfo, field_validator, model_validator

from laser_corners.options import Options

__all__ = ["MAX_METRES", "MAX_SCALES", "PAPER_SCALES", "DetectorParams"]

PAPER_SCALES: tuple[float, ...] = tuple(round(0.05 + 0.025 * k, 6) for k in range(9))
"""The paper's neighbourhood radii R_k: 0.05, 0.075, ..., 0.25 m."""

MAX_METRES = 100.0
"""Largest radius or distance a parameter may take, metres (beyond any 2D laser's range)."""
MAX_SCALES = 64
"""Most neighbourhood radii R_k (the paper uses 9)."""

_INT_BOUNDS: dict[str, tuple[int, int, str]] = {
    "min_points": (2, 10_000, "a line needs two points; more than a scan's beams is none"),
    "min_consecutive_scales": (1, MAX_SCALES, "at most the number of scales"),
    "max_gap_beams": (0, 1_000, "dropout beams stepped over"),
}
_FLOAT_BOUNDS: dict[str, tuple[float, float, str]] = {
    "min_angle_deg": (0.0, 180.0, "degrees"),
    "max_angle_deg": (0.0, 180.0, "degrees"),
    "max_fit_rmse": (0.0, MAX_METRES, "metres"),
    "max_point_distance": (0.0, MAX_METRES, "metres"),
    "max_centroid_distance": (0.0, MAX_METRES, "metres"),
    "merge_radius": (0.0, MAX_METRES, "metres"),
    "min_extent_ratio": (0.0, 1.0, "a fraction of R_k"),
    "refine_radius": (0.0, MAX_METRES, "metres"),
    "refine_exclude": (0.0, MAX_METRES, "metres"),
}
_BOUNDS: dict[str, tuple[float, float, str]] = {**_INT_BOUNDS, **_FLOAT_BOUNDS}
"""Every scalar field's allowed range (what the kernels represent and what is physical)."""


class DetectorParams(Options):
    """Parameters of :class:`~laser_corners.CornerDetector` (defaults: the paper's, section III).

    Parameters
    ----------
    scales : tuple of float
        Neighbourhood radii R_k in metres, strictly increasing and positive.
    min_points : int
        Minimum number of points in each of the arrival and departure neighbourhoods
        (the scan point itself included in both).
    min_angle_deg, max_angle_deg : float
        Accepted interval of the corner opening angle between the two fitted lines, degrees.
    max_fit_rmse : float
        Maximum RMSE of each neighbourhood's selected line fit (eqs. 8-9), metres.
    max_point_distance : float
        Maximum distance from the scale's line intersection to the scan point p_j, metres.
    max_centroid_distance : float
        Maximum distance from each accepted scale's intersection to their centroid, metres.
    min_consecutive_scales : int
        Minimum number of consecutive passing scales for a corner-like feature.
    merge_radius : float
        Per-point candidates whose keypoints lie within this distance of each other (single
        linkage) are merged into one keypoint per physical corner; 0 disables merging.
        Not in the paper: see ``docs/method.md``.
    min_extent_ratio : float
        A scale R_k passes only if the far end of each neighbourhood (its first arrival and
        last departure point) lies at least ``min_extent_ratio * R_k`` from p_j, so a run of
        points cut short by a gap, a range jump or the end of the scan does not pass again at
        every larger scale with the same few points. 0 (default, the paper) disables it.
        Not in the paper: see ``docs/simulation-and-accuracy.md``.
    refine_radius : float
        When > 0, each keypoint is re-estimated as the intersection of two lines fitted
        (eqs. 2-9) to the points of each wall within ``refine_radius`` of it, walking out from
        the scan point nearest to it, leaving out the points closer than ``refine_exclude``;
        the new position is kept if it lies within ``merge_radius`` (0.05 m when merging is
        off) of the old one. 0 (default, the paper) disables it.
    refine_exclude : float
        Radius around the keypoint whose points the refinement leaves out, metres.
    max_gap_beams : int
        Runs of at most this many invalid beams (dropouts) inside a neighbourhood are
        stepped over instead of ending it; the next valid point must still lie within R_k.
        0 (default, the paper) ends a neighbourhood at every gap. Not in the paper: see
        ``docs/method.md``.

    Examples
    --------
    >>> DetectorParams().scales[:3]
    (0.05, 0.075, 0.1)
    >>> DetectorParams().with_overrides(["min_points=6"]).min_points
    6
    """

    section: ClassVar[str] = "detector"
    tuple_hints: ClassVar[dict[str, str]] = {"scales": "comma-separated metres like 0.05,0.075,0.1"}

    scales: tuple[float, ...] = Field(default=PAPER_SCALES)
    min_points: int = 5
    min_angle_deg: float = 45.0
    max_angle_deg: float = 135.0
    max_fit_rmse: float = 0.025
    max_point_distance: float = 0.05
    max_centroid_distance: float = 0.025
    min_consecutive_scales: int = 3
    merge_radius: float = 0.05
    min_extent_ratio: float = 0.0
    refine_radius: float = 0.0
    refine_exclude: float = 0.03
    max_gap_beams: int = 0

    @field_validator(*_INT_BOUNDS, mode="before")
    @classmethod
    def _integral(cls, value: Any) -> Any:
        """``1e3`` (a string in YAML 1.1) or ``1000.0`` as the integer it names."""
        try:
            number = float(value) if isinstance(value, str | float) else None
        except ValueError:
            return value
        if number is not None and math.isfinite(number) and number.is_integer():
            return int(number)
        return value

    @field_validator(*_INT_BOUNDS, *_FLOAT_BOUNDS)
    @classmethod
    def _check_range(cls, value: float, info: ValidationInfo) -> float:
        low, high, why = _BOUNDS[info.field_name]  # type: ignore[index]
        if not (low <= value <= high):  # NaN fails too
            raise ValueError(f"must be in [{low:g}, {high:g}] ({why}), got {value}")
        return value

    @field_validator("scales")
    @classmethod
    def _check_scales(cls, scales: tuple[float, ...]) -> tuple[float, ...]:
        if len(scales) == 0:
            raise ValueError("scales must not be empty")
        if len(scales) > MAX_SCALES:
            raise ValueError(f"at most {MAX_SCALES} scales, got {len(scales)}")
        if any(not (0.0 < s <= MAX_METRES) for s in scales):
            raise ValueError(
                f"each scale must be in (0, {MAX_METRES:g}] metres, got {list(scales)}"
            )
        if any(b <= a for a, b in pairwise(scales)):
            raise ValueError(f"scales must be strictly increasing, got {list(scales)}")
        return tuple(float(s) for s in scales)

    @model_validator(mode="after")
    def _check_consistency(self) -> DetectorParams:
        if not (0.0 <= self.min_angle_deg <= self.max_angle_deg <= 180.0):
            raise ValueError(
                "need 0 <= min_angle_deg <= max_angle_deg <= 180, got "
                f"{self.min_angle_deg}, {self.max_angle_deg}"
            )
        if self.min_consecutive_scales > len(self.scales):
            raise ValueError(
                f"min_consecutive_scales ({self.min_consecutive_scales}) exceeds the number "
                f"of scales ({len(self.scales)})"
            )
        return self
