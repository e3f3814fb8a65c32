"""Parameters of the ROS 2 node's ``slam`` and ``localise`` modes (ROS-free).

:class:`MappingConfig` checks them (one line naming the parameter when invalid). Besides
the node's own parameters it takes every field of the mode's estimator options by the name
it has in Python, in YAML files and in ``--set`` (:class:`~laser_corners.slam.SlamOptions`
in slam mode, :class:`~laser_corners.localise.LocaliseOptions` in localise mode; a nested
field with a dotted name, ``places.matches``), over the ``slam_config`` /
``localise_config`` file, and AMCL's ``set_initial_pose`` / ``initial_pose.{x,y,z,yaw}``.
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any, ClassVar, Literal

from pydantic import Field, ValidationInfo, field_validator

from laser_corners.errors import InvalidParamsError, OutputError
from laser_corners.localise import LocaliseOptions
from laser_corners.options import Options, unknown_keys
from laser_corners.slam.options import SlamOptions

__all__ = [
    "MAPPING_OPTIONS",
    "RUNTIME",
    "InitialPose",
    "MappingConfig",
    "check_output",
    "estimator_parameters",
    "runtime_change",
]


def check_output(folder: Path) -> None:
    """Create ``folder`` and check a file can be written there.

    Raises
    ------
    OutputError
        One line naming the folder and the reason.
    """
    probe = folder / f".laser-corners-check-{os.getpid()}"
    try:
        folder.mkdir(parents=True, exist_ok=True)
        probe.write_bytes(b"")
        probe.unlink()
    except OSError as exc:
        raise OutputError(f"output {folder}: not writable ({exc.strerror or exc})") from None


class InitialPose(Options):
    """AMCL's ``initial_pose`` parameters: the base pose in the map (``z`` is ignored: the
    node is planar)."""

    title: ClassVar[str] = "initial_pose"

    x: float = Field(0.0, allow_inf_nan=False)
    y: float = Field(0.0, allow_inf_nan=False)
    z: float = Field(0.0, allow_inf_nan=False)
    yaw: float = Field(0.0, allow_inf_nan=False)


class MappingConfig(Options):
    """Validated parameters of the ``slam`` / ``localise`` node modes.

    Attributes
    ----------
    mode : {"slam", "localise"}
    map : str
        ``localise``: the map folder ``laser-corners slam`` wrote, or a ``map_server`` YAML
        (a map made by another package: virtual keyframes,
        :mod:`laser_corners.registration.gridmap`) (required).
    output : str
        Folder for the map ("" = none): slam writes the map folder there at shutdown and on
        ``serialize_map``; ``save_map`` writes map.yaml + map.pgm there. Created and checked
        for writing at start.
    mount : list of float
        Base -> laser ``[x, y, yaw]``; empty: from ``/tf_static`` (identity without it).
    odom_topic : str
        A ``nav_msgs/Odometry`` topic to take odometry from; empty (or ``tf``, the value
        ``--odom-topic`` takes for it): ``/tf``.
    map_frame, odom_frame, base_frame : str
        Frame names; ``odom_frame`` / ``base_frame`` empty: taken from the first odometry.
    map_period : float
        Seconds between republications of the SLAM grid on ``map``.
    resolution : float
        Grid cell size, metres (slam mode).
    slam_config : str
        A YAML file of :class:`~laser_corners.slam.SlamOptions` ("" = defaults).
    localise_config : str
        A YAML file of :class:`~laser_corners.localise.LocaliseOptions` ("" = defaults).
    set_initial_pose : bool
        localise: start from ``initial_pose`` (AMCL's parameter); set at run time, it (and
        a change of ``initial_pose``) sets the pose then.
    initial_pose : InitialPose
        ``initial_pose.x``, ``.y``, ``.z``, ``.yaw`` (AMCL's names).
    overrides : dict
        The estimator options given one by one (``fix_scans``, ``places.matches``, ...: any
        field of the mode's options class), over ``slam_config`` / ``localise_config``.
    queue_size : int
        Subscriber depth; also the most scans kept waiting for odometry.
    tf_wait : float
        Seconds (wall clock) a scan may wait for odometry after its stamp once it arrived:
        a lagging odometry callback (several odometry messages per scan) is not a missing
        odometry.
    transform_tolerance : float
        Seconds ``map -> odom`` is future-dated by (its stamp is the scan's plus this), so
        that tf lookups up to then succeed until the next scan (AMCL's parameter, same
        default).
    odom_timeout : float
        Seconds (wall clock) without odometry while scans arrive before a warning.
    max_odom_jump : float
        slam: metres the odometry may move between consecutive scans before a warning.
    """

    what: ClassVar[str] = "parameter"

    mode: Literal["slam", "localise"] = "slam"
    map: str = ""
    output: str = ""
    mount: list[float] = Field(default_factory=list)
    odom_topic: str = ""
    map_frame: str = Field("map", min_length=1)
    odom_frame: str = ""
    base_frame: str = ""
    map_period: float = Field(5.0, gt=0.0, le=3600.0)
    resolution: float = Field(0.05, ge=0.001, le=10.0)
    slam_config: str = ""
    localise_config: str = ""
    set_initial_pose: bool = False
    initial_pose: InitialPose = Field(default_factory=InitialPose)
    overrides: dict[str, Any] = Field(default_factory=dict)
    queue_size: int = Field(50, ge=1, le=100_000)
    tf_wait: float = Field(1.0, gt=0.0, le=60.0)
    transform_tolerance: float = Field(0.1, ge=0.0, le=10.0)
    odom_timeout: float = Field(2.0, gt=0.0, le=3600.0)
    max_odom_jump: float = Field(1.0, gt=0.0, le=1e6)

    @field_validator("mount")
    @classmethod
    def _mount(cls, mount: list[float]) -> list[float]:
        if mount and (len(mount) != 3 or not all(math.isfinite(v) for v in mount)):
            raise ValueError(f"expected [x, y, yaw], got {mount}")
        return mount

    @field_validator("odom_topic")
    @classmethod
    def _odom_topic(cls, topic: str) -> str:
        return "" if topic in ("tf", "/tf") else topic  # the odometry on /tf, as the CLI's

    @field_validator("map")
    @classmethod
    def _map(cls, folder: str, info: ValidationInfo) -> str:
        if info.data.get("mode") == "localise" and not folder:
            raise ValueError("mode localise needs -p map:=DIR (or a map_server .yaml)")
        return folder

    @classmethod
    def from_mapping(
        cls, data: Mapping[str, Any], source: str = "ROS 2 parameters"
    ) -> MappingConfig:
        """Check parameter name -> value; one :class:`InvalidParamsError` line when invalid
        (``ROS 2 parameters: map_period: ...``, ``ROS 2 parameters: unknown parameter 'x';
        known: ...``, as every :class:`~laser_corners.options.Options` says it).

        A name of the mode's estimator options (:func:`estimator_parameters`) goes into
        ``overrides``; ``initial_pose.x`` and the like into ``initial_pose``."""
        if not isinstance(data, Mapping):
            return super().from_mapping(data, source)
        estimator = set(estimator_parameters(str(data.get("mode", "slam"))))
        own: dict[str, Any] = {}
        overrides: dict[str, Any] = {}
        for key, value in data.items():
            name, _, sub = str(key).partition(".")
            if key in estimator:
                overrides[key] = value
            elif sub and name in cls.model_fields and name != "overrides":
                own.setdefault(name, {})[sub] = value
            else:
                own[key] = value
        if "overrides" in own:  # filled from the estimator's names, not a parameter
            raise InvalidParamsError(f"{source}: {unknown_keys(cls, ['overrides'])}")
        return super().from_mapping({**own, "overrides": overrides}, source)

    def slam_options(self) -> SlamOptions:
        """The SLAM options (``slam_config`` YAML or the defaults, with ``overrides``)."""
        base = SlamOptions.from_file(self.slam_config) if self.slam_config else SlamOptions()
        return base.with_overrides(self.overrides) if self.overrides else base

    def localise_options(self) -> LocaliseOptions:
        """The localiser's options (``localise_config`` YAML or the defaults, with
        ``overrides``)."""
        base = LocaliseOptions()
        if self.localise_config:
            base = LocaliseOptions.from_file(self.localise_config)
        return base.with_overrides(self.overrides) if self.overrides else base

    def pose(self) -> tuple[float, float, float] | None:
        """``initial_pose`` as ``(x, y, yaw)`` when ``set_initial_pose``, else None."""
        if not self.set_initial_pose:
            return None
        return (self.initial_pose.x, self.initial_pose.y, self.initial_pose.yaw)


def _flat_defaults() -> dict[str, Any]:
    flat: dict[str, Any] = {}
    for name, field in MappingConfig.model_fields.items():
        value = field.get_default(call_default_factory=True)
        if isinstance(value, Options):  # initial_pose: initial_pose.x, ... as AMCL names them
            flat.update({f"{name}.{k}": v for k, v in value.model_dump().items()})
        elif name != "overrides":
            flat[name] = value
    return flat


MAPPING_OPTIONS: dict[str, Any] = _flat_defaults()
"""Parameters of the ``slam`` and ``localise`` modes, with their defaults (see docs/ros.md;
the estimator options are :func:`estimator_parameters`)."""


def estimator_parameters(mode: str) -> list[str]:
    """The names of the estimator options taken as parameters in ``mode`` (every field of
    ``SlamOptions`` or ``LocaliseOptions``, nested ones dotted: ``places.matches``), except
    ``mount`` (the node's own ``mount`` parameter)."""
    cls = LocaliseOptions if mode == "localise" else SlamOptions
    names = []
    for name, field in cls.model_fields.items():
        nested = field.get_default(call_default_factory=True)
        if isinstance(nested, Options):
            names += [f"{name}.{k}" for k in type(nested).model_fields]
        elif name != "mount":
            names.append(name)
    return names


RUNTIME = ("map", "set_initial_pose", "initial_pose.x", "initial_pose.y", "initial_pose.z")
RUNTIME += ("initial_pose.yaw",)
"""The parameters localise mode takes while it runs (the others are read at start)."""


def runtime_change(
    mode: str, changes: Mapping[str, Any], current: Mapping[str, Any]
) -> MappingConfig | None:
    """Check a run-time change of parameters ``changes`` (name -> value).

    Parameters
    ----------
    mode : str
        The node's mode.
    changes : mapping
        The parameters being set (others, e.g. ``use_sim_time``, pass).
    current : mapping
        The current values of :data:`RUNTIME`.

    Returns
    -------
    MappingConfig or None
        None when the change touches none of :data:`RUNTIME`; else a config holding the
        :data:`RUNTIME` values after it (``map``, ``pose()``).

    Raises
    ------
    InvalidParamsError
        One line: a parameter that is read at start only, or an invalid value.
    """
    ours = [n for n in changes if n in MAPPING_OPTIONS or n in estimator_parameters(mode)]
    fixed = [n for n in ours if n not in RUNTIME or mode != "localise"]
    if fixed:
        raise InvalidParamsError(f"{', '.join(fixed)}: read at start only in mode {mode}")
    if not ours:
        return None
    values = {**{n: current[n] for n in RUNTIME if n in current}, **changes}
    return MappingConfig.from_mapping(
        {"mode": "localise", **{n: values[n] for n in RUNTIME if n in values}}
    )
