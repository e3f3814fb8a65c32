"""Options of :mod:`laser_corners.slam`: one validated, frozen object, one set of defaults.

The field names are the vocabulary of the Python API, of YAML files and of the CLI's
``--set key=value``. The defaults were chosen from the sensors and the robots (range noise
of a few centimetres, walking-speed platforms, indoor rooms of a few metres), not from the
relation errors of any log; see ``docs/slam.md``.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from typing import Any

import yaml
from pydantic import BaseModel, ConfigDict, Field, ValidationError

from laser_corners.errors import InvalidParamsError

__all__ = ["SlamOptions"]


class SlamOptions(BaseModel):
    """Options of :class:`~laser_corners.slam.Slam` and :func:`~laser_corners.slam.run_slam`."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    keyframe_distance: float = Field(0.4, ge=0.01, le=10.0)
    """Travelled distance (m) after which the next scan becomes a keyframe (a graph node)."""
    keyframe_angle: float = Field(0.3, ge=0.01, le=3.2)
    """Turn (rad) after which the next scan becomes a keyframe."""
    keyframe_max_interval: float = Field(10.0, ge=0.1, le=1e6)
    """Time (s) after which the next scan becomes a keyframe even when standing still."""
    local_map_keyframes: int = Field(20, ge=1, le=500)
    """Recent keyframes whose points form the local map each scan is aligned to."""
    scan_alignment: bool = True
    """Align every scan to the local map (point-to-line ICP); off: odometry prediction only
    (the corners-only front end, corner registration, is not implemented yet)."""
    landmarks: bool = False
    """Corner keypoints of keyframes as landmarks in the graph. Not implemented yet: True is
    refused with an :class:`~laser_corners.errors.InvalidParamsError`."""
    loop_closure: bool = True
    """Search and verify loop closures against older keyframes."""
    final_optimisation: bool = True
    """Run a batch Levenberg-Marquardt optimisation of the whole graph at the end."""
    mount: tuple[float, float, float] | None = None
    """Base -> laser transform ``(x, y, yaw)``, overriding the recording's (``/tf_static``)."""
    detector_preset: str = "paper"
    """Corner detector preset for keypoints (landmarks, corners-only front end)."""
    max_range: float = Field(30.0, ge=0.5, le=1000.0)
    """Beams longer than this (m) are not used for alignment (long beams: large angular error)."""
    min_range: float = Field(0.1, ge=0.0, le=10.0)
    """Beams shorter than this (m) are not used (the robot itself)."""
    point_spacing: float = Field(0.05, ge=0.0, le=1.0)
    """Minimum spacing (m) between the points kept from one scan (voxel thinning)."""
    icp_max_distance: float = Field(0.3, ge=0.01, le=5.0)
    """Largest point-to-map distance (m) of a correspondence in the last ICP iterations."""
    icp_iterations: int = Field(20, ge=1, le=200)
    """Maximum point-to-line ICP iterations per alignment."""
    min_overlap: float = Field(0.4, ge=0.0, le=1.0)
    """Share of a scan's points that must match the map for an alignment to be trusted."""
    odometry_sigma_xy: float = Field(0.05, ge=1e-4, le=10.0)
    """Odometry noise (m per metre travelled, on 0.1 m more) weighing predictions and factors."""
    odometry_sigma_yaw: float = Field(0.05, ge=1e-4, le=10.0)
    """Odometry noise (rad per radian turned, plus the same per metre travelled)."""
    match_sigma_xy: float = Field(0.02, ge=1e-4, le=10.0)
    """Noise (m) of a keyframe-to-keyframe relative pose from scan alignment."""
    match_sigma_yaw: float = Field(0.005, ge=1e-5, le=1.0)
    """Noise (rad) of a keyframe-to-keyframe relative pose from scan alignment."""
    loop_radius: float = Field(4.0, ge=0.1, le=100.0)
    """Keyframes within this distance (m) of the current estimate are loop candidates."""
    loop_recent_distance: float = Field(10.0, ge=0.0, le=1000.0)
    """Keyframes reached less than this travelled distance (m) ago are not loop candidates."""
    loop_search_xy: float = Field(1.0, ge=0.0, le=10.0)
    """Half-width (m) of the correlative search window of a loop closure at least."""
    loop_search_yaw: float = Field(0.25, ge=0.0, le=3.2)
    """Half-width (rad) of the correlative search window of a loop closure at least."""
    loop_drift: float = Field(0.03, ge=0.0, le=1.0)
    """Expected drift per metre since the last closure, widening the loop search window."""
    loop_min_score: float = Field(0.55, ge=0.0, le=1.0)
    """Share of points within ``loop_inlier_distance`` of the submap to accept a closure."""
    loop_inlier_distance: float = Field(0.1, ge=0.01, le=1.0)
    """Distance (m) within which a point counts as explained by the submap."""
    loop_submap_keyframes: int = Field(10, ge=1, le=200)
    """Keyframes on each side of a candidate that form its submap."""
    loop_query_keyframes: int = Field(1, ge=1, le=100)
    """Keyframes (the current one and its predecessors) whose points form a loop query."""
    loop_every: int = Field(5, ge=1, le=1000)
    """Loop search on every n-th keyframe."""
    loop_candidates: int = Field(2, ge=1, le=20)
    """Candidates verified per loop search (nearest first, from different submaps)."""
    loop_agree_xy: float = Field(0.15, ge=0.0, le=10.0)
    """A verified closure moving the map by less than this (m) is accepted at once; a larger
    correction needs a second closure implying the same correction within this distance."""
    loop_agree_yaw: float = Field(0.035, ge=0.0, le=3.2)
    """As ``loop_agree_xy``, for the rotation (rad, 2 degrees)."""
    loop_sigma_xy: float = Field(0.05, ge=1e-4, le=10.0)
    """Noise (m) of a loop closure factor (under a Cauchy kernel)."""
    loop_sigma_yaw: float = Field(0.01, ge=1e-5, le=1.0)
    """Noise (rad) of a loop closure factor (under a Cauchy kernel)."""
    time_jump: float = Field(5.0, ge=0.1, le=1e6)
    """A gap (s) between scan stamps (either way) longer than this is a time jump: the scan
    becomes a keyframe, its alignment gets a weak odometry prior, and when it does not align
    the graph is cut there (a new segment under a weak prior)."""

    def __init__(self, **data: Any) -> None:
        try:
            super().__init__(**data)
        except ValidationError as exc:
            raise InvalidParamsError(_one_line(exc)) from None

    @classmethod
    def from_mapping(cls, data: Mapping[str, Any], source: str = "options") -> SlamOptions:
        """Options from a mapping such as parsed YAML (a top-level ``slam`` table is used)."""
        if not isinstance(data, Mapping):
            raise InvalidParamsError(f"{source}: expected a mapping of option names to values")
        if "slam" in data and isinstance(data["slam"], Mapping):
            data = data["slam"]
        try:
            return cls(**dict(data))
        except InvalidParamsError as exc:
            raise InvalidParamsError(f"{source}: {exc}") from None

    @classmethod
    def with_overrides(
        cls, assignments: Iterable[str] | Mapping[str, Any], base: SlamOptions | None = None
    ) -> SlamOptions:
        """Options with fields replaced from ``"key=value"`` strings (values parsed as YAML).

        Examples
        --------
        >>> SlamOptions.with_overrides(["keyframe_distance=0.5", "mount=-0.04,0,0"]).mount
        (-0.04, 0.0, 0.0)
        """
        updates: dict[str, Any] = {}
        if isinstance(assignments, Mapping):
            updates.update(assignments)
        else:
            for item in assignments:
                key, sep, raw = item.partition("=")
                key = key.strip()
                if not sep or not key:
                    raise InvalidParamsError(f"override {item!r} is not of the form key=value")
                try:
                    updates[key] = yaml.safe_load(raw)
                except yaml.YAMLError:
                    raise InvalidParamsError(f"override {item!r}: value is not valid") from None
        unknown = set(updates) - set(cls.model_fields)
        if unknown:
            known = ", ".join(cls.model_fields)
            raise InvalidParamsError(
                f"unknown option(s) {', '.join(sorted(unknown))}; known: {known}"
            )
        if isinstance(updates.get("mount"), str):
            try:
                updates["mount"] = tuple(
                    float(v) for v in updates["mount"].strip("[]() ").split(",")
                )
            except ValueError:
                raise InvalidParamsError(
                    f"mount: expected x,y,yaw, got {updates['mount']!r}"
                ) from None
        merged = (base or cls()).model_dump()
        merged.update(updates)
        return cls(**merged)

    def __setattr__(self, name: str, value: Any) -> None:
        raise InvalidParamsError(
            f"SlamOptions is frozen: cannot set {name!r}; make a changed copy with "
            f"SlamOptions.with_overrides({{{name!r}: ...}}, base=options)"
        )

    def to_yaml(self) -> str:
        """The options as a YAML document (``slam:`` table)."""
        data = self.model_dump()
        if data["mount"] is not None:
            data["mount"] = list(data["mount"])
        return yaml.safe_dump({"slam": data}, sort_keys=False)


def _one_line(exc: ValidationError) -> str:
    parts = []
    for error in exc.errors():
        where = ".".join(str(p) for p in error.get("loc", ())) or "options"
        message = str(error.get("msg", "invalid")).removeprefix("Value error, ")
        parts.append(f"{where}: {message}")
    return "; ".join(dict.fromkeys(parts))
