"""Section-IV metrics on small synthetic cases whose answers are known by hand."""

from __future__ import annotations

import math

import numpy as np
import pytest

from laser_corners.errors import InputError
from laser_corners.eval.association import (
    associate,
    association_stats,
    observation_table,
    pair_distance_std,
)
from laser_corners.eval.falko_like import FalkoLikeDetector, FalkoLikeParams
from laser_corners.eval.grid import Grid
from laser_corners.eval.observability import ObservabilityMap, observability_map
from laser_corners.eval.pairs import pairs_from_poses, pairs_from_relations
from laser_corners.eval.persistent import persistent_features
from laser_corners.eval.poses import Trajectory, interpolate_poses, read_relations, read_tum
from laser_corners.eval.repeatability import pair_repeatability, repeatability
from laser_corners.eval.visibility import points_in_view
from laser_corners.scan import LaserScan, compose, invert, relative_pose
from laser_corners.sim import corner_scan


def wall_scan(distance: float, pose: tuple[float, float, float] | None = None) -> LaserScan:
    """181 beams over [-90, 90] deg, every beam hitting at ``distance`` (a circular wall)."""
    return LaserScan(np.full(181, distance), -math.pi / 2, math.radians(1.0), 0.05, 30.0, pose=pose)


# ----------------------------------------------------------------------------- visibility
def test_points_in_view_fov_range_and_occlusion() -> None:
    scan = wall_scan(2.0)
    pts = [[1.0, 0.0], [2.03, 0.0], [2.5, 0.0], [-1.0, 0.0], [0.0, 1.5], [0.01, 0.0]]
    seen = points_in_view(scan, pts, tolerance=0.06)
    # in front; just behind the surface (tolerance); occluded; behind the sensor; at +90 deg
    # (last beam); closer than range_min
    assert seen.tolist() == [True, True, False, False, True, False]
    assert points_in_view(scan, [[2.5, 0.0]], occlusion=False).tolist() == [True]
    assert points_in_view(scan, [[2.5, 0.0]], occlusion=False, max_range=2.4).tolist() == [False]


def test_points_in_view_beam_without_return_sees_nothing() -> None:
    ranges = np.full(181, 2.0)
    ranges[90] = np.nan  # the beam straight ahead has no return
    scan = LaserScan(ranges, -math.pi / 2, math.radians(1.0), 0.05, 30.0)
    assert points_in_view(scan, [[1.0, 0.0]]).tolist() == [True]  # the neighbour beam saw 2 m
    ranges[89:92] = np.nan
    scan = LaserScan(ranges, -math.pi / 2, math.radians(1.0), 0.05, 30.0)
    assert points_in_view(scan, [[1.0, 0.0]]).tolist() == [False]


# ----------------------------------------------------------------------------- observability
def _grid() -> Grid:
    return Grid(x0=-3.0, y0=-3.0, resolution=0.03, shape=(200, 200))


def test_observability_three_of_four_scans_in_view() -> None:
    grid = _grid()
    cell = grid.cell_of([[2.0, 0.0]])[0]
    feature = grid.center_of([cell])[0]
    neighbour = grid.center_of([cell + np.array([0, 1])])[0]
    scans = [
        wall_scan(2.5, (0.0, 0.0, 0.0)),  # sees the feature, detects it
        wall_scan(2.5, (0.0, 0.0, 0.0)),  # sees it, detects it
        wall_scan(2.5, (0.0, 0.0, 0.0)),  # sees it, detects it
        wall_scan(2.5, (0.0, 0.0, 0.0)),  # sees it, keypoint lands in the neighbour cell
        wall_scan(1.0, (0.0, 0.0, 0.0)),  # occluded by a wall at 1 m
        wall_scan(2.5, (0.0, 0.0, math.pi)),  # looks away
    ]
    kps = [[feature], [feature], [feature], [neighbour], np.zeros((0, 2)), np.zeros((0, 2))]
    obs = observability_map(scans, kps, grid)
    r, c = cell
    assert obs.n_scans == 6
    assert obs.in_view[r, c] == 4
    assert obs.hits[r, c] == 3
    assert obs.ratio[r, c] == pytest.approx(0.75)
    assert obs.ratio_n8[r, c] == pytest.approx(1.0)  # the 4th keypoint is an 8-neighbour
    assert obs.ratio[r, c + 1] == pytest.approx(0.25)
    # a cell never in view is NaN, a cell in view without keypoints 0
    assert math.isnan(obs.ratio[0, 0])
    centre = grid.cell_of([[1.0, 0.5]])[0]
    assert obs.ratio[centre[0], centre[1]] == 0.0
    # without occlusion the occluded scan counts as a view: 3 of 5
    free = observability_map(scans, kps, grid, occlusion=False)
    assert free.ratio[r, c] == pytest.approx(0.6)


def test_observability_explicit_poses_and_skipped_scans() -> None:
    grid = _grid()
    feature = grid.center_of(grid.cell_of([[0.0, 2.0]]))[0]
    scans = [wall_scan(2.5), wall_scan(2.5)]
    # the sensor looks along +y, so the feature at (0, 2) is straight ahead
    obs = observability_map(scans, [[feature], []], grid, poses=[(0, 0, math.pi / 2)] * 2)
    r, c = grid.cell_of([feature])[0]
    assert obs.ratio[r, c] == pytest.approx(0.5)
    no_pose = observability_map(scans, [[feature], []], grid)  # scans have no pose: skipped
    assert no_pose.n_scans == 0
    assert np.all(no_pose.in_view == 0)


def test_persistent_features_peaks_nms_and_levels() -> None:
    grid = Grid(0.0, 0.0, 0.03, (50, 50))
    in_view = np.full(grid.shape, 40, dtype=np.int32)
    hits = np.zeros(grid.shape, dtype=np.int32)
    hits[10, 10] = 40  # 100 %
    hits[10, 12] = 36  # 90 %, 0.06 m from the first: suppressed
    hits[30, 30] = 24  # 60 %
    hits[40, 10] = 12  # 30 %
    hits[45, 45] = 5  # 12.5 %: below min_ratio
    in_view_rare = in_view.copy()
    in_view_rare[5, 40] = 2
    hits[5, 40] = 2  # 100 % but seen by 2 scans only
    obs = ObservabilityMap(grid, in_view_rare, hits, in_view_rare, hits, n_scans=40)
    feats = persistent_features(obs, min_ratio=0.25, min_views=20, nms_radius=0.2)
    assert len(feats) == 3
    assert sorted(map(tuple, feats.cells.tolist())) == [(10, 10), (30, 30), (40, 10)]
    assert feats.count_at_least(0.5) == 2
    assert feats.count_at_least(0.75) == 1
    assert feats.count_at_least(1.0) == 1
    np.testing.assert_allclose(feats.xy[0], grid.center_of([[10, 10]])[0])


# ----------------------------------------------------------------------------- association
def test_associate_nearest_one_to_one_within_radius() -> None:
    kps = [[0.0, 0.0], [1.05, 0.0], [2.0, 0.0]]
    feats = [[1.0, 0.0], [1.08, 0.0], [0.0, 0.1], [5.0, 5.0]]
    # keypoint 1 is nearest to feature 1 (0.03 m) and feature 0 (0.05 m): feature 1 wins it;
    # feature 2 is 0.1 m from keypoint 0: out of radius
    assert associate(kps, feats, 0.06).tolist() == [-1, 1, -1, -1]
    assert associate(np.zeros((0, 2)), feats, 0.06).tolist() == [-1, -1, -1, -1]


def test_pair_distance_std_known_values() -> None:
    features = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [9.0, 9.0]])
    shift = [
        np.array([0.01, -0.02]),
        np.array([-0.02, 0.0]),
        np.array([0.0, 0.01]),
        np.array([0.01, 0.0]),
    ]
    scans = []
    for s in range(4):
        a = features[0] + shift[s]  # features 0 and 1 move together: constant distance
        b = features[1] + shift[s]
        # distance of feature 2 to feature 0: 1 +- 0.05 (all within the 0.06 m radius)
        c = features[2] + np.array([0.0, 0.05 if s % 2 else -0.05]) + shift[s]
        kps = [a, b, c]
        if s == 0:
            kps = [a, b]  # feature 2 missing in scan 0
        scans.append(np.array(kps))
    scans.append(np.array([features[3]]))  # feature 3 alone
    table = observation_table(scans, features, 0.06)
    assert table.shape == (5, 4, 2)
    assert np.isnan(table[0, 2]).all() and np.isfinite(table[4, 3]).all()
    std, together = pair_distance_std(table)
    assert std[0, 1] == pytest.approx(0.0, abs=1e-12)
    # distances 0-2 over scans 1, 2, 3: 1.05, 0.95, 1.05 -> population std 0.0471
    d = np.array([1.05, 0.95, 1.05])
    assert std[0, 2] == pytest.approx(np.std(d), abs=1e-9)
    assert together[0, 1] == 4 and together[0, 2] == 3 and together[0, 3] == 0
    assert math.isnan(std[0, 3]) and math.isnan(std[1, 1])
    np.testing.assert_allclose(std, std.T, equal_nan=True)
    stats = association_stats(std, together, threshold=0.03)
    assert stats.n_pairs == 6
    assert stats.n_pairs_never_together == 3  # every pair with feature 3
    assert stats.n_pairs_with_std == 3
    assert stats.max_std == pytest.approx(np.std(d), abs=1e-9)
    assert stats.share_std_within == pytest.approx(1 / 3)


# ----------------------------------------------------------------------------- repeatability
def test_pair_repeatability_counts_visible_and_repeated() -> None:
    scan_b = wall_scan(5.0)
    pose_b_in_a = (1.0, 0.0, math.pi / 2)  # B is 1 m ahead of A, turned left
    # A's keypoints (A frame) -> B frame: (x, y) -> (y, 1 - x)
    kps_a = np.array(
        [
            [1.0, 2.0],  # B: (2, 0) ahead of B: visible
            [1.0, -2.0],  # B: (-2, 0) behind B: not visible
            [0.0, 1.0],  # B: (1, 1): visible
            [3.0, 1.0],  # B: (1, -2): visible
        ]
    )
    kps_b = np.array([[2.03, 0.0], [1.0, 1.08], [4.0, 4.0]])
    counts = pair_repeatability(kps_a, kps_b, scan_b, pose_b_in_a, radii=(0.05, 0.1))
    assert counts.n_a == 4
    assert counts.n_visible == 3
    assert counts.n_repeated == (1, 2)
    result = repeatability([kps_a, kps_b], [wall_scan(5.0), scan_b], [(0, 1, pose_b_in_a)])
    assert result.repeatability == pytest.approx((1 / 3, 2 / 3))
    assert result.keypoints_per_scan == pytest.approx(3.5)
    empty = repeatability([kps_a, kps_b], [scan_b, scan_b], [])
    assert empty.n_pairs == 0 and all(math.isnan(v) for v in empty.repeatability)


# ----------------------------------------------------------------------------- poses
def test_compose_invert_relative() -> None:
    a = (1.0, 2.0, 0.3)
    b = (-0.5, 4.0, -2.9)
    np.testing.assert_allclose(compose(a, relative_pose(a, b)), b, atol=1e-12)
    np.testing.assert_allclose(compose(a, invert(a)), (0.0, 0.0, 0.0), atol=1e-12)


def test_read_tum_and_interpolate(tmp_path) -> None:
    path = tmp_path / "traj.txt"
    q = [(0.0, 0.0, math.sin(a / 2), math.cos(a / 2)) for a in (3.0, -3.0)]
    path.write_text(
        "# t x y z qx qy qz qw\n"
        f"10.0 0 0 0 {q[0][0]} {q[0][1]} {q[0][2]} {q[0][3]}\n"
        f"11.0 2 4 0 {q[1][0]} {q[1][1]} {q[1][2]} {q[1][3]}\n"
        "\n"
    )
    traj = read_tum(path)
    assert len(traj) == 2
    assert traj.poses[0, 2] == pytest.approx(3.0)
    out = interpolate_poses(traj, [10.5, 10.0, 13.0], max_gap=1.5)
    # halfway; the yaw goes from 3.0 to -3.0 the short way (+0.283 rad), through pi
    assert out[0, :2] == pytest.approx([1.0, 2.0])
    assert math.remainder(out[0, 2] - math.pi, math.tau) == pytest.approx(0.0, abs=1e-9)
    assert out[1] == pytest.approx([0.0, 0.0, 3.0])
    assert np.isnan(out[2]).all()  # 2 s after the end
    assert np.isnan(interpolate_poses(traj, [10.5], max_gap=0.5)).all()  # stamps 1 s apart
    gap = Trajectory(np.array([0.0, 10.0]), np.zeros((2, 3)))
    assert np.isnan(interpolate_poses(gap, [5.0], max_gap=0.5)).all()


def test_bad_tum_and_relations_are_one_line_input_errors(tmp_path) -> None:
    bad = tmp_path / "bad.txt"
    bad.write_text("1 2 3\n")
    with pytest.raises(InputError, match=r"bad.txt:1: .*8 numbers"):
        read_tum(bad)
    with pytest.raises(InputError, match="no such file"):
        read_relations(tmp_path / "missing.relations")


def test_relations_matched_to_stamps_with_mount(tmp_path) -> None:
    path = tmp_path / "x.relations"
    path.write_text("1.0 2.0 1.0 0.0 0 0 0 0.5\n2.0 9.0 1.0 0.0 0 0 0 0.0\n")
    rels = read_relations(path)
    assert rels[0].pose == (1.0, 0.0, 0.5)
    pairs = pairs_from_relations([0.5, 1.0004, 2.0, None], rels)
    assert [(i, j) for i, j, _ in pairs] == [(1, 2)]  # 9.0 matches no scan
    assert pairs[0][2] == pytest.approx((1.0, 0.0, 0.5))
    # a sensor 0.1 m ahead of the robot: mount^-1 + T + mount
    mount = (0.1, 0.0, 0.0)
    shifted = pairs_from_relations([1.0, 2.0], rels, mount)[0][2]
    expected = compose(compose(invert(mount), rels[0].pose), mount)
    assert shifted == pytest.approx(expected)
    assert shifted[1] == pytest.approx(0.1 * math.sin(0.5))


def test_pairs_from_poses_next_scan_far_enough() -> None:
    poses = [(0.0, 0.0, 0.0), (0.2, 0.0, 0.0), (0.6, 0.0, 0.0), None, (0.6, 0.0, 0.5)]
    pairs = pairs_from_poses(poses, min_motion=0.5, min_turn_deg=15.0)
    assert [(i, j) for i, j, _ in pairs] == [(0, 2), (1, 4), (2, 4)]
    assert pairs[0][2] == pytest.approx((0.6, 0.0, 0.0))
    assert len(pairs_from_poses(poses, 0.5, 15.0, max_pairs=2)) == 2


# ----------------------------------------------------------------------------- falko-like
def test_falko_finds_the_corner_and_not_a_wall() -> None:
    kps = FalkoLikeDetector().detect(corner_scan())
    assert len(kps) == 1
    assert np.hypot(*(kps.xy[0] - [2.0, 1.0])) < 0.02
    assert 80.0 < kps.opening_angle_deg[0] < 100.0
    straight = LaserScan(2.0 / np.cos(np.linspace(-0.6, 0.6, 200)), -0.6, 1.2 / 199, 0.05, 30.0)
    assert len(FalkoLikeDetector().detect(straight)) == 0


def test_falko_params_validated() -> None:
    from laser_corners.errors import InvalidParamsError

    with pytest.raises(InvalidParamsError, match="side_ratio"):
        FalkoLikeParams(side_ratio=0.5)


@pytest.mark.parametrize("occlusion", [True, False])
def test_observability_block_culling_matches_the_per_point_test(occlusion: bool) -> None:
    """The grid pass (culled by blocks of cells) counts exactly the cells points_in_view sees."""
    from laser_corners.sim import UST_10LX, rectangular_room

    world = rectangular_room()
    rng = np.random.default_rng(3)
    full_turn = LaserScan(np.full(360, 1.0), -math.pi, math.radians(1.0), 0.05, 30.0)
    scans = [
        world.scan((-1.0, -0.5, 0.4), UST_10LX, 0.01, rng),
        world.scan((2.0, 1.2, -2.5), UST_10LX, 0.01, rng),
        LaserScan(
            world.cast((0.5, -1.0, 3.0), full_turn.angles),
            -math.pi,
            math.radians(1.0),
            0.05,
            30.0,
            pose=(0.5, -1.0, 3.0),
        ),
    ]
    grid = Grid(-3.5, -2.5, 0.05, (100, 140))
    obs = observability_map(scans, [np.zeros((0, 2))] * 3, grid, occlusion=occlusion, max_range=4.0)
    rows, cols = np.indices(grid.shape)
    centres = grid.center_of(np.stack([rows.ravel(), cols.ravel()], axis=1))
    expected = np.zeros(grid.shape, dtype=int)
    for scan in scans:
        x, y, th = scan.pose
        c, s = math.cos(th), math.sin(th)
        local = (centres - [x, y]) @ np.array([[c, -s], [s, c]])
        seen = points_in_view(scan, local, occlusion=occlusion, max_range=4.0)
        expected += seen.reshape(grid.shape)
    np.testing.assert_array_equal(obs.in_view, expected)
    assert expected.max() == 3 and (expected == 0).any()


@pytest.mark.parametrize(
    "name",
    [
        "laser_corners.eval.falko_like",
        "laser_corners.eval.association",
        "laser_corners.eval.methods",
        "laser_corners.eval.no_return",
    ],
)
def test_docstring_examples(name: str) -> None:
    import doctest
    import importlib

    result = doctest.testmod(importlib.import_module(name), optionflags=doctest.ELLIPSIS)
    assert result.attempted > 0
    assert result.failed == 0
