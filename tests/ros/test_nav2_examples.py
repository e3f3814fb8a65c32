"""The nav2 examples in ros2/: their parameter files name only parameters the node knows,
with valid values, and the launch files load them (issue 33 item 6)."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest
import yaml

from laser_corners.ros.slam_core import MappingConfig

ROS2 = Path(__file__).resolve().parents[2] / "ros2"


@pytest.mark.parametrize(("name", "mode"), [("localise.yaml", "localise"), ("slam.yaml", "slam")])
def test_parameter_files_are_valid_node_parameters(name: str, mode: str) -> None:
    params = yaml.safe_load((ROS2 / "config" / name).read_text())["laser_corners"]
    values = dict(params["ros__parameters"])
    assert values["mode"] == mode
    assert values.pop("lifecycle") is False  # the node's own (rclpy LifecycleNode) switch
    if mode == "localise":  # the launch file's map:= argument fills it
        assert values["map"] == ""
        values = {**values, "map": "/maps/office/map.yaml"}
    config = MappingConfig.from_mapping(values)  # unknown or invalid: one-line error, raised
    assert (config.map_frame, config.odom_frame) == ("map", "odom")
    assert config.overrides  # estimator options by name, checked here
    options = config.localise_options() if mode == "localise" else config.slam_options()
    assert all(getattr(options, k) == v for k, v in config.overrides.items())


@pytest.mark.parametrize("name", ["localisation.launch.py", "slam.launch.py"])
def test_launch_files_load_their_parameter_file(name: str) -> None:
    source = (ROS2 / "launch" / name).read_text()
    ast.parse(source)
    config = "localise.yaml" if name.startswith("localisation") else "slam.yaml"
    assert f'"config" / "{config}"' in source and "laser_corners_node" in source
