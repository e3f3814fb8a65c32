"""Settings of :func:`laser_corners.eval.real.evaluate_real`."""

from __future__ import annotations

from typing import Annotated, Any, ClassVar

from pydantic import Field, field_validator, model_validator

from laser_corners.choice import ParamsChoice
from laser_corners.eval.methods import DEFAULT_METHODS, canonical_name
from laser_corners.options import Options

__all__ = ["RealEvalConfig"]


class RealEvalConfig(Options):
    """Settings of :func:`evaluate_real`.

    Attributes
    ----------
    detector : ParamsChoice
        Detector parameters for the maps and the association distance (a preset plus
        overrides; ``preset=`` and ``overrides=`` keywords are still accepted and read).
    resolution : float
        Observability grid cell, metres (0.03 in the paper).
    association_radius : float
        Keypoint-feature association radius, metres (0.06 in the paper).
    std_threshold : float
        Pair-distance std threshold reported as a share, metres (0.03 in the paper).
    min_ratio, min_views, nms_radius : float, int, float
        Persistent feature selection, see
        :func:`~laser_corners.eval.persistent.persistent_features`.
    radii : tuple of float
        Repeatability radii, metres.
    occlusion : bool
        Ray-cast against the scan in the visibility tests.
    view_tolerance : float
        How far beyond the measured range a point still counts as seen, metres.
    max_range : float or None
        Ignore cells/keypoints farther than this from the sensor (default: sensor range).
    max_scans : int or None
        Read at most this many scans.
    pair_min_motion, pair_min_turn_deg : float
        Without relations: scan A is paired with the first later scan whose pose moved at
        least this far or turned at least this much.
    max_pairs : int
        At most this many pairs (evenly subsampled).
    relations_mount : (x, y, theta)
        Sensor pose in the frame of the relations (robot base); the relative poses are
        converted to sensor-to-sensor ones with it.
    methods : tuple of str
        Repeatability table rows: names of :mod:`laser_corners.eval.methods` (``paper``,
        ``auto``, ``robust``, ``split-and-merge``, ``falko-like``); an unknown name raises
        :class:`~laser_corners.errors.InvalidParamsError`.
    max_cells : int
        Largest observability grid; beyond it the cells are made coarser (memory stays bounded).
    max_features : int
        At most this many persistent features (the best ones) enter the association distance,
        whose cost grows with their square.
    min_pairs, min_visible : int
        Evidence needed before a number is stated without a warning: feature pairs with a
        std (association) and scan pairs (repeatability); visible keypoints (repeatability).
    """

    title: ClassVar[str] = "RealEvalConfig"

    detector: ParamsChoice = ParamsChoice()
    resolution: float = Field(0.03, gt=0.0, allow_inf_nan=False)
    association_radius: float = Field(0.06, gt=0.0, allow_inf_nan=False)
    std_threshold: float = Field(0.03, gt=0.0, allow_inf_nan=False)
    min_ratio: float = Field(0.25, ge=0.0, le=1.0)
    min_views: int = Field(20, ge=1)
    nms_radius: float = Field(0.2, ge=0.0)
    radii: tuple[Annotated[float, Field(gt=0.0)], ...] = Field((0.05, 0.1), min_length=1)
    occlusion: bool = True
    view_tolerance: float = Field(0.06, gt=0.0, allow_inf_nan=False)
    max_range: float | None = Field(None, gt=0.0)
    max_scans: int | None = Field(None, ge=1)
    pair_min_motion: float = Field(0.5, ge=0.0)
    pair_min_turn_deg: float = Field(15.0, ge=0.0)
    max_pairs: int = Field(1000, ge=1)
    relations_mount: tuple[float, float, float] = (0.0, 0.0, 0.0)
    methods: tuple[str, ...] = Field(DEFAULT_METHODS, min_length=1)
    max_cells: int = Field(2_000_000, ge=1)
    max_features: int = Field(400, ge=1)
    min_pairs: int = Field(20, ge=0)
    min_visible: int = Field(5, ge=0)

    @model_validator(mode="before")
    @classmethod
    def _legacy_preset(cls, data: Any) -> Any:
        """``preset=`` and ``overrides=`` (the fields before ``detector``) still work."""
        if isinstance(data, dict) and ("preset" in data or "overrides" in data):
            data = dict(data)
            if "detector" in data:
                raise ValueError("give detector or preset/overrides, not both")
            preset = data.pop("preset", "paper")
            data["detector"] = ParamsChoice(preset=preset, overrides=data.pop("overrides", ()))
        return data

    @field_validator("methods")
    @classmethod
    def _canonical(cls, methods: tuple[str, ...]) -> tuple[str, ...]:
        return tuple(canonical_name(m) for m in methods)

    @property
    def preset(self) -> str:
        """The detector preset (``detector.preset``)."""
        return self.detector.preset

    @property
    def overrides(self) -> tuple[str, ...]:
        """The detector overrides (``detector.overrides``)."""
        return self.detector.overrides
