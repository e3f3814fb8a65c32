"""The localiser's options (:mod:`laser_corners.localise.options`): the smoothing and the
engine as groups (``smooth.*``, ``engine.*``, issue 31 item 1), by the same names in Python,
YAML and ``--set``; the old flat names are one line naming the new one."""

from __future__ import annotations

from pathlib import Path

import pytest

from laser_corners.errors import InvalidParamsError
from laser_corners.localise import LocaliseOptions
from laser_corners.localise.options import EngineOptions, SmoothOptions

OLD_NAMES = {
    "smooth_anchor_travel": "smooth.anchor_travel",
    "smooth_step_xy": "smooth.step_xy",
    "smooth_step_yaw": "smooth.step_yaw",
    "smooth_drift": "smooth.drift",
    "engine_gate_xy": "engine.gate_xy",
    "engine_gate_yaw": "engine.gate_yaw",
}
"""The flat names before the groups -> their dotted names now."""


def test_the_groups_keep_the_old_defaults() -> None:
    options = LocaliseOptions()
    assert options.smooth == SmoothOptions() and options.engine == EngineOptions()
    smooth = options.smooth
    assert smooth.enabled is True
    assert (smooth.anchor_travel, smooth.step_xy, smooth.step_yaw, smooth.drift) == (
        0.4,
        0.002,
        0.001,
        0.01,
    )
    assert (options.engine.enabled, options.engine.gate_xy, options.engine.gate_yaw) == (
        True,
        0.3,
        0.05,
    )


def test_dotted_set_and_python_construction() -> None:
    changed = LocaliseOptions().with_overrides(
        ["smooth.enabled=false", "smooth.drift=0.02", "engine.gate_xy=0.5"]
    )
    assert changed.smooth == SmoothOptions(enabled=False, drift=0.02)
    assert changed.engine == EngineOptions(gate_xy=0.5)
    built = LocaliseOptions(
        smooth=SmoothOptions(enabled=False), engine=EngineOptions(enabled=False)
    )
    assert not built.smooth.enabled and not built.engine.enabled
    assert built.smooth.step_xy == 0.002 and built.engine.gate_yaw == 0.05


def test_a_yaml_table_of_each_group(tmp_path: Path) -> None:
    path = tmp_path / "localise.yaml"
    path.write_text(
        "localise:\n  smooth:\n    anchor_travel: 0.8\n    enabled: false\n"
        "  engine:\n    gate_yaw: 0.1\n"
    )
    options = LocaliseOptions.from_file(path)
    assert options.smooth == SmoothOptions(anchor_travel=0.8, enabled=False)
    assert options.engine == EngineOptions(gate_yaw=0.1)
    assert LocaliseOptions.from_file(path) == LocaliseOptions.from_mapping(
        {"smooth": options.smooth.model_dump(), "engine": {"gate_yaw": 0.1}}
    )
    assert "smooth:\n  enabled: false\n  anchor_travel: 0.8\n" in options.to_yaml()


@pytest.mark.parametrize(
    ("override", "needle"),
    [
        ("smooth.step_xy=0", r"smooth: SmoothOptions\.step_xy: input should be greater"),
        ("smooth.drift=2", r"smooth: SmoothOptions\.drift: input should be less"),
        ("engine.gate_yaw=-1", r"engine: EngineOptions\.gate_yaw: input should be greater"),
        ("engine.enabled=maybe", r"engine: EngineOptions\.enabled: input should be a valid"),
    ],
)
def test_a_bad_value_is_one_line_naming_group_and_field(override: str, needle: str) -> None:
    with pytest.raises(InvalidParamsError, match=needle) as info:
        LocaliseOptions().with_overrides([override])
    assert "\n" not in str(info.value)


@pytest.mark.parametrize(("old", "new"), OLD_NAMES.items())
def test_an_old_flat_name_is_one_line_naming_the_new_one(old: str, new: str, tmp_path) -> None:
    with pytest.raises(InvalidParamsError, match=f"unknown option '{old}' .*'{new}'") as info:
        LocaliseOptions().with_overrides([f"{old}=0.1"])
    assert "\n" not in str(info.value)
    path = tmp_path / "old.yaml"
    path.write_text(f"{old}: 0.1\n")
    with pytest.raises(InvalidParamsError, match=f"old.yaml: unknown option '{old}'") as info:
        LocaliseOptions.from_file(path)
    assert new in str(info.value) and "\n" not in str(info.value)


@pytest.mark.parametrize("group", ["smooth", "engine"])
def test_the_old_switch_is_one_line_naming_the_enabled_field(group: str, tmp_path) -> None:
    """``--set smooth=false`` (documented before the groups) and ``engine: false`` in YAML."""
    with pytest.raises(InvalidParamsError, match=f"{group}: a group .*{group}.enabled") as info:
        LocaliseOptions().with_overrides([f"{group}=false"])
    assert "\n" not in str(info.value)
    path = tmp_path / "old.yaml"
    path.write_text(f"{group}: false\n")
    with pytest.raises(
        InvalidParamsError, match=f"old.yaml: .*{group}: a group .*{group}.enabled"
    ) as info:
        LocaliseOptions.from_file(path)
    assert "\n" not in str(info.value)
