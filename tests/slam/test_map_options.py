"""The SLAM's options as a map folder records them (``slam.options.map_options``; not
``test_options.py``, the name of ``tests/test_options.py``)."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from laser_corners.errors import InputError, InvalidParamsError
from laser_corners.registration.align import IcpOptions
from laser_corners.registration.odometry import OdometryNoise
from laser_corners.slam.options import LoopOptions, SlamOptions, map_options


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


OLD_LOOP = {
    "loop_closure": False,
    "loop_radius": 5.0,
    "loop_recent_distance": 12.0,
    "loop_search_xy": 1.5,
    "loop_search_yaw": 0.3,
    "loop_drift": 0.04,
    "loop_min_score": 0.6,
    "loop_submap_keyframes": 8,
    "loop_query_keyframes": 2,
    "loop_every": 3,
    "loop_candidates": 4,
    "loop_sigma_xy": 0.04,
    "loop_sigma_yaw": 0.006,
    "loop_inlier_distance": 0.12,
    "loop_agree_xy": 0.2,
    "loop_agree_yaw": 0.04,
}
"""Every flat loop name of an ``options.yaml`` written before the ``loop`` group, each with
a value other than its default."""


def test_the_loop_options_are_one_group_set_by_dotted_keys() -> None:
    options = SlamOptions()
    assert options.loop == LoopOptions()
    assert (options.loop.enabled, options.loop.radius, options.loop.every) == (True, 4.0, 5)
    changed = options.with_overrides(["loop.radius=5", "loop.enabled=false"])
    assert changed.loop == LoopOptions(radius=5.0, enabled=False)
    assert SlamOptions(loop=LoopOptions(radius=5.0)).loop.radius == 5.0
    assert SlamOptions.from_mapping({"loop": {"every": 2}}).loop.every == 2
    for old in OLD_LOOP:
        with pytest.raises(InvalidParamsError, match=f"unknown option '{old}'"):
            options.with_overrides([f"{old}=1"])


def test_the_loop_group_round_trips_through_a_map_folder(tmp_path: Path) -> None:
    options = SlamOptions().with_overrides(["loop.radius=5", "loop.sigma_yaw=0.01"])
    assert "loop:\n  enabled: true\n  radius: 5.0\n" in options.to_yaml()
    (tmp_path / "options.yaml").write_text(options.to_yaml())
    assert map_options(tmp_path) == options


def test_the_options_not_about_loops_have_their_own_names() -> None:
    """``inlier_distance`` drives tracking, relocalisation and the final passes too, and
    ``agree_*`` the refinement and rescan passes: not in the loop group."""
    options = SlamOptions(inlier_distance=0.12, agree_xy=0.2, agree_yaw=0.04)
    assert (options.inlier_distance, options.agree_xy, options.agree_yaw) == (0.12, 0.2, 0.04)
    assert SlamOptions().inlier_distance == 0.1
    assert (SlamOptions().agree_xy, SlamOptions().agree_yaw) == (0.15, 0.035)
    for name in ("inlier_distance", "agree_xy", "agree_yaw"):
        assert name not in LoopOptions.model_fields


def test_an_old_folders_flat_loop_names_load_to_the_same_values(tmp_path: Path) -> None:
    (tmp_path / "options.yaml").write_text(yaml.safe_dump({"keyframe_distance": 0.5, **OLD_LOOP}))
    options = map_options(tmp_path)
    assert options.loop == LoopOptions(
        enabled=False,
        radius=5.0,
        recent_distance=12.0,
        search_xy=1.5,
        search_yaw=0.3,
        drift=0.04,
        min_score=0.6,
        submap_keyframes=8,
        query_keyframes=2,
        every=3,
        candidates=4,
        sigma_xy=0.04,
        sigma_yaw=0.006,
    )
    assert (options.inlier_distance, options.agree_xy, options.agree_yaw) == (0.12, 0.2, 0.04)
    assert options.keyframe_distance == 0.5
    (tmp_path / "options.yaml").write_text("loop_agree_xy: 0.2\nagree_xy: 0.3\n")
    with pytest.raises(InputError, match=r"options.yaml: .*loop_agree_xy.*agree_xy") as info:
        map_options(tmp_path)
    assert "\n" not in str(info.value)


def test_a_bad_loop_value_names_loop_radius_in_one_line(tmp_path: Path) -> None:
    """``--set``, a YAML table and an old folder name the group and its field, as for
    ``icp`` (``loop: LoopOptions.radius``)."""
    for make in (
        lambda: SlamOptions().with_overrides(["loop.radius=-1"]),
        lambda: SlamOptions.from_mapping({"loop": {"radius": -1}}),
    ):
        with pytest.raises(InvalidParamsError, match=r"loop: LoopOptions\.radius: input") as info:
            make()
        assert "\n" not in str(info.value)
    (tmp_path / "options.yaml").write_text("loop_radius: -1\n")
    with pytest.raises(InputError, match=r"options.yaml: loop: LoopOptions\.radius: ") as info:
        map_options(tmp_path)
    assert "\n" not in str(info.value)
