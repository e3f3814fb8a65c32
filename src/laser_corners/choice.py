"""Which detector parameters: a preset (or fixed parameters) plus ``key=value`` overrides.

:class:`ParamsChoice` is the one form of that idea: the pipeline (``detect``, ``plot``,
``view``, ``batch``), the ROS nodes (:class:`~laser_corners.ros.node_core.NodeConfig`), the
evaluations (:class:`~laser_corners.eval.real_config.RealEvalConfig`, the methods of
:mod:`laser_corners.eval.methods`) and ``CornerDetector("paper")`` all resolve their
parameters through it, against a recording's first scan (:meth:`ParamsChoice.resolve`).
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from pathlib import Path
from typing import Any, ClassVar

import yaml
from pydantic import field_validator, model_validator

from laser_corners.errors import InvalidParamsError
from laser_corners.options import Options
from laser_corners.params import DetectorParams
from laser_corners.presets import PRESETS, get_preset
from laser_corners.scan import LaserScan

__all__ = ["ParamsChoice"]


class ParamsChoice(Options):
    """How a recording gets its :class:`~laser_corners.DetectorParams` (picklable, frozen).

    Parameters
    ----------
    preset : str
        A preset of :data:`laser_corners.presets.PRESETS` (``paper``, ``auto``, ``robust``);
        presets that adapt to the sensor use each recording's first scan. Ignored when
        ``base`` is given. May be given first, positionally: ``ParamsChoice("auto")``.
    base : DetectorParams, optional
        Fixed parameters (for instance loaded from a file) instead of a preset.
    overrides : tuple of str, or a mapping
        ``key=value`` overrides applied last (a mapping of field -> value is turned into
        such strings). They are checked when the choice is made: against the preset's
        parameters, or the paper's for a preset that needs a scan.
    source : str
        Where ``base`` came from (a file name), for summaries; "" for a preset.

    Examples
    --------
    >>> choice = ParamsChoice(preset="paper", overrides=("min_points=6",))
    >>> choice.resolve(None).min_points
    6
    >>> print(choice.describe(), end="")
    preset: paper
    overrides:
    - min_points=6
    """

    title: ClassVar[str] = ""  # messages name the key the user gave, not this class

    preset: str = "paper"
    base: DetectorParams | None = None
    overrides: tuple[str, ...] = ()
    source: str = ""

    def __init__(self, preset: str | None = None, /, **data: Any) -> None:
        if preset is not None:
            data["preset"] = preset
        super().__init__(**data)

    @field_validator("preset")
    @classmethod
    def _known_preset(cls, preset: str) -> str:
        if preset not in PRESETS:
            get_preset(preset)  # raises the error listing the presets
        return preset

    @field_validator("overrides", mode="before")
    @classmethod
    def _as_strings(cls, overrides: Any) -> Any:
        if isinstance(overrides, Mapping):
            return tuple(f"{key}={_as_yaml(value)}" for key, value in overrides.items())
        return tuple(overrides) if isinstance(overrides, list) else overrides

    @model_validator(mode="after")
    def _check_overrides(self) -> ParamsChoice:
        self.start_params()  # an unknown key or a bad value fails now, not per recording
        return self

    @classmethod
    def from_options(
        cls,
        preset: str | None = None,
        params_file: str | Path | None = None,
        overrides: list[str] | tuple[str, ...] | None = None,
    ) -> ParamsChoice:
        """The choice for a preset name *or* a parameter file, plus overrides (the CLI's
        ``--preset``, ``--params`` and ``--set``).

        Raises
        ------
        InvalidParamsError
            Both a preset and a file, an unknown preset, or an override with an unknown key or
            a bad value.
        """
        if preset is not None and params_file is not None:
            raise InvalidParamsError("give a preset or a parameter file, not both")
        overrides = tuple(overrides or ())
        if params_file is not None:
            base = DetectorParams.from_file(Path(params_file))
            return cls(base=base, overrides=overrides, source=Path(params_file).name)
        return cls(preset=preset or "paper", overrides=overrides)

    @property
    def label(self) -> str:
        """A short name: the preset, or the parameter file (``+ overrides`` when any)."""
        name = self.source or ("parameters" if self.base is not None else self.preset)
        return name + (" + overrides" if self.overrides else "")

    @property
    def needs_scan(self) -> bool:
        """Whether the parameters depend on the recording (a preset adapting to the sensor)."""
        if self.base is not None:
            return False
        try:
            get_preset(self.preset, None)
        except InvalidParamsError:
            return True
        return False

    def resolve(self, scan: LaserScan | None) -> DetectorParams:
        """The parameters for a recording whose first scan is ``scan``.

        Raises
        ------
        InvalidParamsError
            A preset that needs a scan without one, or overrides invalid for this preset.
        """
        params = self.base if self.base is not None else get_preset(self.preset, scan)
        return params.with_overrides(list(self.overrides)) if self.overrides else params

    def start_params(self) -> DetectorParams:
        """The parameters known before any scan: :meth:`resolve` without a scan, or, for a
        preset that needs one, the paper's parameters with the overrides."""
        if not self.needs_scan:
            return self.resolve(None)
        return DetectorParams().with_overrides(list(self.overrides))

    def describe(self) -> str:
        """A YAML document naming the choice (what ``batch-params.yaml`` holds)."""
        data: dict[str, Any] = (
            {"params": self.base.model_dump(mode="json")}
            if self.base is not None
            else {"preset": self.preset}
        )
        data["overrides"] = list(self.overrides)
        return yaml.safe_dump(data, sort_keys=False)

    @classmethod
    def of(cls, params: ParamsChoice | DetectorParams | str | None) -> ParamsChoice:
        """``params`` as a choice: a choice as is, fixed parameters as its ``base``, a name
        as its preset, None as the paper's preset."""
        if params is None:
            return cls()
        if isinstance(params, ParamsChoice):
            return params
        if isinstance(params, str):
            return cls(preset=params)
        if isinstance(params, DetectorParams):
            return cls(base=params)
        raise InvalidParamsError(
            f"expected DetectorParams, a preset name or a ParamsChoice, got {type(params).__name__}"
        )


def _as_yaml(value: Any) -> str:
    """A typed value as the text of a ``key=value`` override (JSON is YAML)."""
    if isinstance(value, tuple):
        value = list(value)
    try:
        return json.dumps(value)
    except TypeError:
        return str(value)
