"""The parameters of the ROS 2 node's slam / localise modes, without ROS: every estimator
option is a parameter by its Python / YAML / ``--set`` name (issue 31 item 2, issue 33)."""

from __future__ import annotations

import pytest

from laser_corners.errors import InvalidParamsError
from laser_corners.localise import LocaliseOptions
from laser_corners.options import Options
from laser_corners.ros.mapping_config import (
    MAPPING_OPTIONS,
    MappingConfig,
    estimator_parameters,
    runtime_change,
)
from laser_corners.slam.options import SlamOptions

MAP = {"mode": "localise", "map": "/maps/office"}


def _other_value(cls: type[Options], name: str, default: object) -> object:
    """A valid value of ``cls.name`` that differs from ``default``."""
    if isinstance(default, bool):
        return not default
    if isinstance(default, str):  # a Literal: another allowed value
        choices = ("paper", "auto", "robust", "scan", "corners", "both")
        candidates = [c for c in choices if c != default]
    elif isinstance(default, int):
        candidates = [default + 1, default - 1]
    else:
        candidates = [round(default * 1.1 + 0.01, 6), round(default * 0.9, 6), 0.5]
    for value in candidates:
        try:
            cls(**{name: value})
        except InvalidParamsError:
            continue
        return value
    raise AssertionError(f"no other valid value for {cls.__name__}.{name}")


def _non_defaults(cls: type[Options], mode: str) -> dict[str, object]:
    """A non-default value for every parameter of ``estimator_parameters(mode)``."""
    values: dict[str, object] = {}
    for name in estimator_parameters(mode):
        head, _, sub = name.partition(".")
        field = cls.model_fields[head]
        if sub:
            nested = field.get_default(call_default_factory=True)
            values[name] = _other_value(type(nested), sub, getattr(nested, sub))
        else:
            values[name] = _other_value(cls, name, field.get_default())
    return values


@pytest.mark.parametrize(("mode", "cls"), [("localise", LocaliseOptions), ("slam", SlamOptions)])
def test_every_estimator_option_is_a_parameter(mode: str, cls: type[Options]) -> None:
    names = estimator_parameters(mode)
    for name, field in cls.model_fields.items():
        nested = field.get_default(call_default_factory=True)
        if isinstance(nested, Options):  # places.matches, ... as --set names them
            assert {f"{name}.{k}" for k in type(nested).model_fields} <= set(names)
        elif name != "mount":  # the node's own mount parameter (base -> laser)
            assert name in names
    assert not set(names) & set(MAPPING_OPTIONS)  # no clash with the node's own names


@pytest.mark.parametrize(("mode", "cls"), [("localise", LocaliseOptions), ("slam", SlamOptions)])
def test_a_non_default_value_of_every_option_is_taken(mode: str, cls: type[Options]) -> None:
    values = _non_defaults(cls, mode)
    config = MappingConfig.from_mapping({**MAP, "mode": mode, **values})
    options = config.localise_options() if mode == "localise" else config.slam_options()
    for name, value in values.items():
        head, _, sub = name.partition(".")
        got = getattr(getattr(options, head), sub) if sub else getattr(options, head)
        assert got == value, name  # and the value differs from the default (_other_value)


@pytest.mark.parametrize("mode", ["slam", "localise"])
def test_the_icp_and_odometry_groups_are_dotted_parameters(mode: str) -> None:
    names = set(estimator_parameters(mode))
    assert {
        "icp.max_distance",
        "icp.iterations",
        "odometry.sigma_xy",
        "odometry.sigma_yaw",
    } <= names
    assert not {"icp_max_distance", "icp_iterations", "odometry_sigma_xy"} & names
    config = MappingConfig.from_mapping(
        {**MAP, "mode": mode, "icp.max_distance": 0.2, "odometry.sigma_yaw": 0.02}
    )
    options = config.localise_options() if mode == "localise" else config.slam_options()
    assert (options.icp.max_distance, options.odometry.sigma_yaw) == (0.2, 0.02)


def test_the_loop_group_is_dotted_parameters() -> None:
    names = set(estimator_parameters("slam"))
    assert {"loop.enabled", "loop.radius", "loop.every", "loop.sigma_xy"} <= names
    assert {"inlier_distance", "agree_xy", "agree_yaw"} <= names
    assert not {"loop_closure", "loop_radius", "loop_inlier_distance", "loop_agree_xy"} & names
    config = MappingConfig.from_mapping(
        {**MAP, "mode": "slam", "loop.radius": 5.0, "loop.enabled": False, "agree_xy": 0.2}
    )
    options = config.slam_options()
    assert (options.loop.radius, options.loop.enabled, options.agree_xy) == (5.0, False, 0.2)


def test_the_smooth_and_engine_groups_are_dotted_parameters() -> None:
    names = set(estimator_parameters("localise"))
    assert {"smooth.enabled", "smooth.anchor_travel", "smooth.drift", "engine.enabled"} <= names
    assert {"smooth.step_xy", "smooth.step_yaw", "engine.gate_xy", "engine.gate_yaw"} <= names
    assert not {"smooth", "engine", "smooth_drift", "engine_gate_xy"} & names
    config = MappingConfig.from_mapping(
        {**MAP, "smooth.enabled": False, "engine.gate_yaw": 0.1, "smooth.step_xy": 0.003}
    )
    options = config.localise_options()
    assert (options.smooth.enabled, options.smooth.step_xy) == (False, 0.003)
    assert options.engine.gate_yaw == 0.1
    with pytest.raises(InvalidParamsError, match=r"unknown parameter 'engine_gate_xy'"):
        MappingConfig.from_mapping({**MAP, "engine_gate_xy": 0.4})


def test_parameters_override_the_config_file(tmp_path) -> None:
    path = tmp_path / "localise.yaml"
    path.write_text("fix_scans: 9\nlost_scans: 3\nplaces:\n  matches: 5\n")
    config = MappingConfig.from_mapping(
        {**MAP, "localise_config": str(path), "fix_scans": 7, "places.candidates": 4}
    )
    options = config.localise_options()
    assert (options.fix_scans, options.lost_scans) == (7, 3)
    assert (options.places.matches, options.places.candidates) == (5, 4)


def test_a_bad_option_value_is_one_line_naming_it() -> None:
    config = MappingConfig.from_mapping({**MAP, "fix_scans": 0})
    with pytest.raises(InvalidParamsError, match=r"fix_scans") as info:
        config.localise_options()
    assert "\n" not in str(info.value)
    with pytest.raises(InvalidParamsError, match=r"unknown parameter 'places.nope'"):
        MappingConfig.from_mapping({**MAP, "places.nope": 1})
    with pytest.raises(InvalidParamsError, match=r"unknown parameter 'fix_scanz'"):
        MappingConfig.from_mapping({**MAP, "fix_scanz": 7})


def test_amcl_initial_pose_parameters() -> None:
    config = MappingConfig.from_mapping(
        {**MAP, "set_initial_pose": True, "initial_pose.x": 1.5, "initial_pose.yaw": 0.5}
    )
    assert config.pose() == (1.5, 0.0, 0.5)
    assert MappingConfig.from_mapping({**MAP, "initial_pose.x": 1.5}).pose() is None
    with pytest.raises(InvalidParamsError, match="initial_pose"):
        MappingConfig.from_mapping({**MAP, "initial_pose.x": float("nan")})
    assert {"initial_pose.x", "initial_pose.yaw", "set_initial_pose"} <= set(MAPPING_OPTIONS)


def test_runtime_changes_of_localise() -> None:
    """While running, localise takes ``map`` (loaded by deserialize_map) and AMCL's
    initial-pose parameters; every other parameter of ours is read at start only."""
    current = {"map": "/maps/a", "set_initial_pose": False, "initial_pose.x": 0.0}
    assert runtime_change("localise", {"use_sim_time": True}, current) is None  # not ours
    after = runtime_change("localise", {"map": "/maps/b"}, current)
    assert after is not None and after.map == "/maps/b" and after.pose() is None
    after = runtime_change("localise", {"set_initial_pose": True, "initial_pose.yaw": 1.0}, current)
    assert after is not None and after.pose() == (0.0, 0.0, 1.0) and after.map == "/maps/a"
    for mode, name in [("localise", "fix_scans"), ("localise", "queue_size"), ("slam", "map")]:
        with pytest.raises(InvalidParamsError, match=rf"^{name}: read at start only"):
            runtime_change(mode, {name: 3}, current)
    with pytest.raises(InvalidParamsError, match="map: mode localise needs"):
        runtime_change("localise", {"map": ""}, current)
