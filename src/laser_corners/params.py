"""Detector parameters: the paper's defaults, validated, loadable from YAML/TOML.

The field names below are the one parameter vocabulary of the project: they are the YAML/TOML
keys, the CLI's ``--set key=value`` keys, the ROS node's parameter names and what every output
folder records.
"""

from __future__ import annotations

from itertools import pairwise
from typing import ClassVar

from pydantic import Field, field_validator, model_validator

from laser_corners.options import Options

__all__ = ["PAPER_SCALES", "DetectorParams"]

PAPER_SCALES: tuple[float, ...] = tuple(round(0.05 + 0.025 * k, 6) for k in range(9))
"""The paper's neighbourhood radii R_k: 0.05, 0.075, ..., 0.25 m."""


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

    @field_validator("scales")
    @classmethod
    def _check_scales(cls, scales: tuple[float, ...]) -> tuple[float, ...]:
        if len(scales) == 0:
            raise ValueError("scales must not be empty")
        if any(not (s > 0.0) or s == float("inf") for s in scales):
            raise ValueError(f"scales must be positive and finite, got {list(scales)}")
        if any(b <= a for a, b in pairwise(scales)):
            raise ValueError(f"scales must be strictly increasing, got {list(scales)}")
        return tuple(float(s) for s in scales)

    @field_validator("min_points")
    @classmethod
    def _check_min_points(cls, value: int) -> int:
        if value < 2:
            raise ValueError(f"min_points must be >= 2 (a line needs two points), got {value}")
        return value

    @field_validator("min_consecutive_scales")
    @classmethod
    def _check_min_scales(cls, value: int) -> int:
        if value < 1:
            raise ValueError(f"min_consecutive_scales must be >= 1, got {value}")
        return value

    @field_validator(
        "max_fit_rmse",
        "max_point_distance",
        "max_centroid_distance",
        "merge_radius",
        "refine_radius",
        "refine_exclude",
    )
    @classmethod
    def _check_non_negative(cls, value: float) -> float:
        if not (value >= 0.0) or value == float("inf"):
            raise ValueError(f"must be a finite number >= 0, got {value}")
        return value

    @field_validator("max_gap_beams")
    @classmethod
    def _check_max_gap(cls, value: int) -> int:
        if value < 0:
            raise ValueError(f"max_gap_beams must be >= 0, got {value}")
        return value

    @field_validator("min_extent_ratio")
    @classmethod
    def _check_extent(cls, value: float) -> float:
        if not (0.0 <= value <= 1.0):
            raise ValueError(f"must be in [0, 1], got {value}")
        return value

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
