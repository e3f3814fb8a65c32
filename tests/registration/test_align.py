"""Tracking ICP against the local map's implicit surface: along a featureless corridor (the
position along it unobservable) the scan's own beam pattern must not move the estimate."""

from __future__ import annotations

import numpy as np
import pytest

from laser_corners.errors import InvalidParamsError
from laser_corners.localise.options import LocaliseOptions
from laser_corners.registration.align import IcpOptions, PointMap, icp, match_share
from laser_corners.registration.points import rotate, scan_points, transform
from laser_corners.sim import SICK_LMS_1DEG, World
from laser_corners.slam.options import SlamOptions
from laser_corners.slam.tracking import SURFACE_SPACINGS


def _along_errors(surface: float) -> np.ndarray:
    """Error along a 2.4 m wide corridor (its far end beyond ``max_range``) of ICP started at
    the true pose, 5 cm past the keyframe whose points form the map, with a 5 cm prior at the
    truth: 20 keyframes, each scan with its own noise."""
    world = World().add_polygon([[0, 0], [60, 0], [60, 2.4], [0, 2.4]])
    rng = np.random.default_rng(0)
    opt = SlamOptions()
    zero = np.zeros(3)
    out = []
    for x0 in np.arange(2.0, 12.0, 0.5):
        key = np.array([x0, 1.2, 0.0])
        scan = world.scan(tuple(key), SICK_LMS_1DEG, noise_sigma=0.01, rng=rng, stamp=0.0)
        pts = scan_points(scan, zero, opt.min_range, opt.max_range, opt.point_spacing)
        line = pts.has_normal
        pointmap = PointMap.build(transform(pts.xy[line], key), rotate(pts.normals[line], 0.0))
        true = key + np.array([0.05, 0.0, 0.0])
        scan = world.scan(tuple(true), SICK_LMS_1DEG, noise_sigma=0.01, rng=rng, stamp=0.0)
        pts = scan_points(scan, zero, opt.min_range, opt.max_range, opt.point_spacing)
        aligned = icp(
            pts.xy,
            pointmap,
            true,
            np.diag(1.0 / np.array([0.05, 0.05, 0.05]) ** 2),
            opt.icp,
            inlier_distance=opt.inlier_distance,
            surface=surface,
        )
        out.append(aligned.pose[0] - true[0])
    return np.array(out)


def test_a_corridor_scan_does_not_snap_to_the_keyframes_beam_pattern() -> None:
    # nearest map point's line (the old tracking): its noisy normal turns the offset along
    # the wall into a residual, so the pose is pulled to where scan and keyframe points
    # coincide (RMS 7.3 mm here); the implicit surface averages the lines around each point
    # (2.9 mm)
    surface = _along_errors(SURFACE_SPACINGS * SlamOptions().point_spacing)
    line = _along_errors(0.0)
    rms_surface = float(np.sqrt(np.mean(surface**2)))
    rms_line = float(np.sqrt(np.mean(line**2)))
    assert rms_surface < 0.6 * rms_line
    assert rms_surface < 0.005


def test_the_kernel_wrappers_refuse_non_finite_poses() -> None:
    """A NaN, infinite or absurd pose is a ValueError before any kernel runs (a kernel turns
    it into a cell index far outside its grid: a crash, not an exception)."""
    from laser_corners.registration.correlative import ScoreGrid, search

    rng = np.random.default_rng(1)
    xy = rng.uniform(-5, 5, (200, 2))
    normals = np.tile([1.0, 0.0], (200, 1))
    pointmap = PointMap.build(xy, normals)
    grid = ScoreGrid.build(xy, 0.05, 0.05, 1.0)
    info = np.eye(3)
    for bad in ([np.nan, 0, 0], [0, np.inf, 0], [1e300, 0, 0], [0, 0, np.nan]):
        pose = np.array(bad, dtype=float)
        with pytest.raises(ValueError, match="pose"):
            match_share(xy, pointmap, pose, 0.1)
        with pytest.raises(ValueError, match="pose"):
            icp(
                xy,
                pointmap,
                pose,
                info,
                IcpOptions(max_distance=0.5, iterations=5),
                inlier_distance=0.1,
            )
        with pytest.raises(ValueError, match="pose"):
            search(grid, xy, pose, 0.5, 0.1)
    bad_points = xy.copy()
    bad_points[3] = [np.nan, 1.0]
    with pytest.raises(ValueError, match="finite"):
        PointMap.build(bad_points, normals)
    assert match_share(xy, pointmap, np.zeros(3), 0.1) == 1.0


def test_icp_options_refuse_out_of_range_values_in_one_line_naming_the_field() -> None:
    for bad, field in (({"max_distance": 0.0}, "max_distance"), ({"iterations": 0}, "iterations")):
        with pytest.raises(InvalidParamsError, match=f"IcpOptions.{field}: input should be"):
            IcpOptions(**bad)
    with pytest.raises(InvalidParamsError, match=r"icp: IcpOptions.max_distance") as info:
        SlamOptions().with_overrides(["icp.max_distance=9"])
    assert "\n" not in str(info.value)


@pytest.mark.parametrize(
    ("cls", "gate", "iterations"), [(SlamOptions, 0.15, 20), (LocaliseOptions, 0.3, 15)]
)
def test_icp_options_are_one_group_set_by_dotted_keys(
    cls: type, gate: float, iterations: int
) -> None:
    options = cls()
    assert options.icp == IcpOptions(max_distance=gate, iterations=iterations)
    changed = options.with_overrides(["icp.max_distance=0.2"])
    assert changed.icp == IcpOptions(max_distance=0.2, iterations=options.icp.iterations)
    assert cls.from_mapping({"icp": {"iterations": 7}}).icp.iterations == 7
    for old in ("icp_max_distance", "icp_iterations"):
        with pytest.raises(InvalidParamsError, match=f"unknown option '{old}'"):
            options.with_overrides([f"{old}=0.2"])


def test_icp_takes_its_settings_as_one_group() -> None:
    line = np.array([[x, 0.0] for x in np.arange(-2.0, 2.0, 0.05)])
    wall = np.array([[0.0, y] for y in np.arange(0.2, 2.0, 0.05)])
    xy = np.vstack([line, wall])
    normals = np.vstack([np.tile([0.0, 1.0], (len(line), 1)), np.tile([1.0, 0.0], (len(wall), 1))])
    pointmap = PointMap.build(xy, normals)
    start = np.array([0.05, -0.04, 0.02])  # the truth is the identity
    info = np.eye(3) * 1e-6
    one = icp(
        xy, pointmap, start, info, IcpOptions(max_distance=0.3, iterations=1), inlier_distance=0.1
    )
    many = icp(
        xy, pointmap, start, info, IcpOptions(max_distance=0.3, iterations=30), inlier_distance=0.1
    )
    assert np.abs(many.pose).max() < 1e-3  # converged to the truth
    assert np.abs(one.pose).max() > np.abs(many.pose).max()  # the iteration cap is used
