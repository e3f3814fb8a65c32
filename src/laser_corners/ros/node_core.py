"""The ROS-independent part of the corner nodes: parameters and per-scan processing.

The ROS 1 (:mod:`laser_corners.ros.ros1_node`) and ROS 2 (:mod:`laser_corners.ros.ros2_node`)
nodes are thin adapters: they hand their private parameters to :meth:`NodeConfig.from_mapping`
and every incoming ``sensor_msgs/LaserScan`` to :meth:`CornerNodeCore.process`, then publish
what :mod:`laser_corners.ros.convert` builds.

Node parameters use the one vocabulary of the project: every
:class:`~laser_corners.DetectorParams` field name, plus ``preset`` (a name of
:data:`~laser_corners.presets.PRESETS`; the fields given override it) and the node options of
:data:`NODE_OPTIONS`.
"""

from __future__ import annotations

import time
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from laser_corners.choice import ParamsChoice
from laser_corners.detector import CornerDetector
from laser_corners.errors import InvalidParamsError
from laser_corners.keypoints import Keypoints
from laser_corners.options import parse_assignments
from laser_corners.params import DetectorParams
from laser_corners.presets import PRESETS
from laser_corners.ros.convert import scan_from_msg
from laser_corners.scan import LaserScan

__all__ = ["NODE_OPTIONS", "CornerNodeCore", "NodeConfig", "parameter_names"]

NODE_OPTIONS: dict[str, Any] = {
    "marker_lifetime": 0.0,
    "marker_ns": "corners",
    "queue_size": 5,
}
"""Node options that are not detector parameters, with their defaults.

``marker_lifetime`` (s, 0 = until replaced), ``marker_ns`` (marker namespace),
``queue_size`` (subscriber queue length).
"""


def parameter_names() -> list[str]:
    """Every parameter name a node accepts: ``preset``, detector fields, node options."""
    return ["preset", *DetectorParams.model_fields, *NODE_OPTIONS]


@dataclass(frozen=True)
class NodeConfig:
    """Validated node parameters.

    Attributes
    ----------
    params : ParamsChoice
        The detector parameters: the ``preset`` (``paper`` when not given) with the detector
        fields given explicitly as overrides.
    options : dict
        Node options (:data:`NODE_OPTIONS` with the given values).
    """

    params: ParamsChoice = field(default_factory=ParamsChoice)
    options: dict[str, Any] = field(default_factory=lambda: dict(NODE_OPTIONS))

    @classmethod
    def from_mapping(
        cls, values: Mapping[str, Any], source: str = "ROS parameter", prefix: str = "~"
    ) -> NodeConfig:
        """Validate a mapping of parameter name -> value (e.g. ``rospy.get_param("~")``).

        Parameters
        ----------
        values : mapping
            Parameter name -> value.
        source, prefix : str
            How messages name a parameter: ``"ROS parameter ~min_points"`` (ROS 1, the
            default) or ``"ROS 2 parameter min_points"`` (``source="ROS 2 parameter"``,
            ``prefix=""``).

        Raises
        ------
        InvalidParamsError
            One line naming the parameter, for unknown names, an unknown preset, invalid
            detector values (checked against the preset) or invalid node options.
        """
        if not isinstance(values, Mapping):
            raise InvalidParamsError(f"{source}s: expected a mapping, got {type(values).__name__}")
        known = set(parameter_names())
        unknown = sorted(str(k) for k in values if k not in known)
        if unknown:
            names = ", ".join(repr(prefix + k) for k in unknown)
            raise InvalidParamsError(
                f"{source}s: unknown parameter {names}; known: {', '.join(parameter_names())}"
            )
        preset = values.get("preset", "paper")
        if not isinstance(preset, str) or preset not in PRESETS:
            raise InvalidParamsError(
                f"{source} {prefix}preset: unknown preset {preset!r}; "
                f"choose one of: {', '.join(PRESETS)}"
            )
        overrides = {k: v for k, v in values.items() if k in DetectorParams.model_fields}
        options = dict(NODE_OPTIONS)
        for name in NODE_OPTIONS:
            if name in values:
                options[name] = _check_option(name, values[name], f"{source} {prefix}{name}")
        try:  # the overrides are checked now, not at the first scan
            params = ParamsChoice(preset=preset, overrides=overrides)
        except InvalidParamsError as exc:
            raise InvalidParamsError(f"{source}s: {exc}") from None
        return cls(params=params, options=options)

    @property
    def preset(self) -> str:
        """The preset name."""
        return self.params.preset

    @property
    def overrides(self) -> dict[str, Any]:
        """The detector fields given explicitly (they override the preset)."""
        return parse_assignments(DetectorParams, self.params.overrides)

    @property
    def needs_scan(self) -> bool:
        """Whether the preset adapts to the sensor, so it is resolved at the first scan."""
        return self.params.needs_scan

    def start_params(self) -> DetectorParams:
        """The parameters known before any scan arrives.

        For a preset that needs a scan (``auto``), the overrides are checked against the
        paper's parameters; the preset is resolved at the first scan.
        """
        return self.params.start_params()

    def updated(self, changes: Mapping[str, Any]) -> NodeConfig:
        """A new config with ``changes`` applied (for ROS 2 on-set-parameters callbacks).

        Raises
        ------
        InvalidParamsError
            If the result is invalid; ``self`` is unchanged.
        """
        merged: dict[str, Any] = {"preset": self.preset, **self.overrides}
        merged.update({k: v for k, v in self.options.items() if v != NODE_OPTIONS[k]})
        merged.update(changes)
        return NodeConfig.from_mapping(merged)

    def detector_params(self, scan: LaserScan | None) -> DetectorParams:
        """The preset (adapted to ``scan`` where it applies) with the overrides applied."""
        try:
            return self.params.resolve(scan)
        except InvalidParamsError as exc:
            raise InvalidParamsError(f"ROS parameters: {exc}") from None


def _check_option(name: str, value: Any, what: str) -> Any:
    if name == "marker_ns":
        if not isinstance(value, str):
            raise InvalidParamsError(f"{what} must be a string, got {value!r}")
        return value
    if name == "queue_size":
        if isinstance(value, bool) or not isinstance(value, int) or value < 1:
            raise InvalidParamsError(f"{what} must be an integer >= 1, got {value!r}")
        return value
    # marker_lifetime
    if isinstance(value, bool) or not isinstance(value, int | float) or not (value >= 0.0):
        raise InvalidParamsError(f"{what} must be a number >= 0, got {value!r}")
    return float(value)


class CornerNodeCore:
    """Per-scan work of a corner node: message -> scan -> keypoints, with timing.

    The detector parameters are resolved from the preset for the first scan's geometry and
    again whenever the geometry (beam count, angles, range limits) changes. The constructor
    runs the detector once on a synthetic scan, so loading the compiled kernels does not
    delay (and, with a short subscriber queue, drop) the first real scans.

    Parameters
    ----------
    config : NodeConfig
        Validated parameters.
    """

    def __init__(self, config: NodeConfig) -> None:
        self.config = config
        self._geometry: tuple[int, float, float, float, float] | None = None
        self.detector = CornerDetector(config.start_params())
        warm_up = LaserScan(
            np.full(64, 2.0), angle_min=-0.5, angle_increment=0.01, range_min=0.01, range_max=30.0
        )
        CornerDetector(self.detector.params).detect(warm_up)

    def reconfigure(self, config: NodeConfig) -> None:
        """Use ``config`` from the next scan on."""
        self.config = config
        self._geometry = None
        self.detector = CornerDetector(config.start_params())

    def process(self, msg: Any) -> tuple[Keypoints, float]:
        """Detect keypoints in one ``sensor_msgs/LaserScan`` message.

        Returns
        -------
        keypoints : Keypoints
            With the message's stamp (seconds) and frame.
        seconds : float
            Processing time (conversion + detection).

        Raises
        ------
        InvalidScanError
            For a malformed message; the node logs it and skips the message.
        InvalidParamsError
            When the preset adapted to this scan's geometry plus the overrides is invalid.
        """
        start = time.perf_counter()
        scan = scan_from_msg(msg)
        geometry = scan.geometry
        if geometry != self._geometry:
            params = self.config.detector_params(scan)
            if params != self.detector.params:
                self.detector = CornerDetector(params)
            self._geometry = geometry
        keypoints = self.detector.detect(scan)
        return keypoints, time.perf_counter() - start
