"""The ROS-free core of the detector nodes (:mod:`laser_corners.ros.node_core`): parameters are
the detector's vocabulary, invalid values are one line, the core matches the library."""

from __future__ import annotations

from types import SimpleNamespace
from typing import Any

import numpy as np
import pytest
from ros_helpers import scan_msg, stamped_corner_scan

from laser_corners import CornerDetector, DetectorParams, LaserScan
from laser_corners.errors import InvalidParamsError, InvalidScanError
from laser_corners.presets import PRESETS
from laser_corners.ros.node_core import NODE_OPTIONS, CornerNodeCore, NodeConfig, parameter_names


@pytest.fixture(scope="module")
def sim_scan() -> LaserScan:
    return stamped_corner_scan()


def test_parameter_names_are_the_detector_vocabulary() -> None:
    names = parameter_names()
    assert names[0] == "preset"
    assert set(DetectorParams.model_fields) <= set(names)
    assert set(NODE_OPTIONS) <= set(names)


def test_node_config_defaults_and_overrides() -> None:
    assert NodeConfig.from_mapping({}).start_params() == DetectorParams()
    config = NodeConfig.from_mapping(
        {"preset": "paper", "min_points": 6, "scales": [0.1, 0.2, 0.3], "marker_lifetime": 1}
    )
    params = config.start_params()
    assert params.min_points == 6 and params.scales == (0.1, 0.2, 0.3)
    assert config.options["marker_lifetime"] == 1.0
    assert config.options["queue_size"] == NODE_OPTIONS["queue_size"]


@pytest.mark.parametrize(
    ("values", "match"),
    [
        ({"min_pionts": 6}, "~min_pionts"),
        ({"preset": "nope"}, "unknown preset 'nope'"),
        ({"min_points": 1}, "min_points"),
        ({"scales": [0.2, 0.1]}, "scales"),
        ({"queue_size": 0}, "queue_size"),
        ({"marker_lifetime": -1.0}, "marker_lifetime"),
        ({"marker_ns": 3}, "marker_ns"),
    ],
)
def test_node_config_rejects_invalid_values_in_one_line(values: dict[str, Any], match: str) -> None:
    with pytest.raises(InvalidParamsError, match=match) as info:
        NodeConfig.from_mapping(values)
    assert "\n" not in str(info.value)


def test_node_config_update_keeps_old_values_on_error() -> None:
    config = NodeConfig.from_mapping({"min_points": 6, "marker_ns": "x"})
    updated = config.updated({"max_fit_rmse": 0.01})
    assert updated.start_params().min_points == 6
    assert updated.start_params().max_fit_rmse == 0.01
    assert updated.options["marker_ns"] == "x"
    with pytest.raises(InvalidParamsError, match="min_points"):
        config.updated({"min_points": 0})
    assert config.start_params().min_points == 6


@pytest.mark.parametrize("ros2", [False, True])
def test_core_matches_the_library(sim_scan: LaserScan, ros2: bool) -> None:
    core = CornerNodeCore(NodeConfig.from_mapping({"min_points": 4}))
    keypoints, seconds = core.process(scan_msg(sim_scan, ros2=ros2))
    expected = CornerDetector(DetectorParams(min_points=4)).detect(sim_scan)
    assert len(keypoints) == len(expected) >= 1
    np.testing.assert_array_equal(keypoints.xy, expected.xy)
    np.testing.assert_array_equal(keypoints.orientation, expected.orientation)
    assert keypoints.stamp == pytest.approx(sim_scan.stamp) and keypoints.frame_id == "laser"
    assert seconds > 0.0


def test_core_resolves_scan_dependent_presets_per_geometry(
    sim_scan: LaserScan, monkeypatch: pytest.MonkeyPatch
) -> None:
    def by_beams(scan: LaserScan | None) -> DetectorParams:
        if scan is None:
            raise InvalidParamsError("preset 'by_beams' needs a scan")
        return DetectorParams(min_points=3 if scan.n_beams < 500 else 7)

    monkeypatch.setitem(PRESETS, "by_beams", by_beams)
    config = NodeConfig.from_mapping({"preset": "by_beams", "max_fit_rmse": 0.02})
    assert config.needs_scan
    core = CornerNodeCore(config)
    assert sim_scan.n_beams >= 500
    core.process(scan_msg(sim_scan))
    assert core.detector.params.min_points == 7 and core.detector.params.max_fit_rmse == 0.02
    coarse = LaserScan(
        sim_scan.ranges[::4],
        sim_scan.angle_min,
        4 * sim_scan.angle_increment,
        sim_scan.range_min,
        sim_scan.range_max,
        stamp=1.0,
        frame_id="laser",
    )
    core.process(scan_msg(coarse))
    assert core.detector.params.min_points == 3
    # overrides of a scan-dependent preset are still checked at start
    with pytest.raises(InvalidParamsError, match="max_fit_rmse"):
        NodeConfig.from_mapping({"preset": "by_beams", "max_fit_rmse": -1.0})


def test_core_raises_on_malformed_message(sim_scan: LaserScan) -> None:
    core = CornerNodeCore(NodeConfig())
    msg = scan_msg(sim_scan)
    msg.angle_min = float("nan")
    with pytest.raises(InvalidScanError):
        core.process(msg)
    keypoints, _ = core.process(scan_msg(sim_scan))  # still works afterwards
    assert len(keypoints) >= 1


def test_ros2_parameter_values_skip_unset() -> None:
    from laser_corners.ros.ros2_node import parameter_values

    not_set = object()
    params = [
        SimpleNamespace(name="preset", type_="str", value="paper"),
        SimpleNamespace(name="min_points", type_=not_set, value=None),
        SimpleNamespace(name="scales", type_="arr", value=(0.1, 0.2, 0.3)),
    ]
    values = parameter_values(params, not_set)
    assert values == {"preset": "paper", "scales": [0.1, 0.2, 0.3]}
    assert NodeConfig.from_mapping(values).start_params().scales == (0.1, 0.2, 0.3)
