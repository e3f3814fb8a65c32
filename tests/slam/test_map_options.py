"""The SLAM's options as a map folder records them (``slam.options.map_options``; not
``test_options.py``, the name of ``tests/test_options.py``)."""

from __future__ import annotations

from pathlib import Path

import pytest

from laser_corners.errors import InputError
from laser_corners.registration.align import IcpOptions
from laser_corners.registration.odometry import OdometryNoise
from laser_corners.slam.options import SlamOptions, map_options


def test_a_map_folder_keeps_the_groups(tmp_path: Path) -> None:
    options = SlamOptions().with_overrides(["icp.iterations=12", "odometry.sigma_xy=0.1"])
    (tmp_path / "options.yaml").write_text(options.to_yaml())
    assert map_options(tmp_path) == options
    assert "icp:\n  max_distance: 0.15\n  iterations: 12\n" in options.to_yaml()


def test_an_old_folders_flat_names_load_into_the_groups(tmp_path: Path) -> None:
    """A map folder written before the groups (flat ``icp_max_distance`` ...) still loads."""
    old = "keyframe_distance: 0.5\nicp_max_distance: 0.2\nicp_iterations: 25\n"
    old += "odometry_sigma_xy: 0.07\nodometry_sigma_yaw: 0.03\nmin_overlap: 0.4\n"
    (tmp_path / "options.yaml").write_text(old)
    options = map_options(tmp_path)
    assert options.icp == IcpOptions(max_distance=0.2, iterations=25)
    assert options.odometry == OdometryNoise(sigma_xy=0.07, sigma_yaw=0.03)
    assert options.keyframe_distance == 0.5


def test_an_old_folder_with_both_spellings_or_a_bad_value_is_one_line(tmp_path: Path) -> None:
    (tmp_path / "options.yaml").write_text("icp_iterations: 25\nicp:\n  iterations: 20\n")
    with pytest.raises(InputError, match=r"options.yaml: .*icp_iterations.*icp.iterations") as info:
        map_options(tmp_path)
    assert "\n" not in str(info.value)
    (tmp_path / "options.yaml").write_text("icp_max_distance: 99\n")
    with pytest.raises(InputError, match=r"options.yaml: .*max_distance") as info:
        map_options(tmp_path)
    assert "\n" not in str(info.value)
