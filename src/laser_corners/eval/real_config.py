"""Settings of :func:`laser_corners.eval.real.evaluate_real`."""

from __future__ import annotations

import math
from dataclasses import dataclass

from laser_corners.errors import InvalidParamsError
from laser_corners.eval.methods import canonical_name
from laser_corners.scan import Pose2D

__all__ = ["RealEvalConfig"]


@dataclass(frozen=True)
class RealEvalConfig:
    """Settings of :func:`evaluate_real`.

    Attributes
    ----------
    preset : str
        Detector preset for the maps and the association distance.
    overrides : tuple of str
        ``key=value`` overrides of that preset.
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

    preset: str = "paper"
    overrides: tuple[str, ...] = ()
    resolution: float = 0.03
    association_radius: float = 0.06
    std_threshold: float = 0.03
    min_ratio: float = 0.25
    min_views: int = 20
    nms_radius: float = 0.2
    radii: tuple[float, ...] = (0.05, 0.1)
    occlusion: bool = True
    view_tolerance: float = 0.06
    max_range: float | None = None
    max_scans: int | None = None
    pair_min_motion: float = 0.5
    pair_min_turn_deg: float = 15.0
    max_pairs: int = 1000
    relations_mount: Pose2D = (0.0, 0.0, 0.0)
    methods: tuple[str, ...] = ("paper", "auto", "split-and-merge", "falko-like")
    max_cells: int = 2_000_000
    max_features: int = 400
    min_pairs: int = 20
    min_visible: int = 5

    def __post_init__(self) -> None:
        object.__setattr__(self, "methods", tuple(canonical_name(m) for m in self.methods))
        for name in ("resolution", "association_radius", "std_threshold", "view_tolerance"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0.0):
                raise InvalidParamsError(f"{name} must be a finite number > 0, got {value}")
        if self.max_range is not None and not self.max_range > 0.0:
            raise InvalidParamsError(f"max_range must be > 0, got {self.max_range}")
        if self.max_cells < 1 or self.max_features < 1 or self.max_pairs < 1:
            raise InvalidParamsError("max_cells, max_features and max_pairs must be >= 1")
