"""Planar poses (:mod:`laser_corners.pose`) against 3x3 homogeneous matrices, computed here."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from laser_corners.pose import (
    MAX_COORDINATE,
    between_many,
    check_pose,
    compose,
    compose_many,
    distinct_poses,
    invert,
    invert_many,
    pose_error,
    pose_problem,
    poses_apart,
    relative_pose,
    rotate_covariance,
    transform_points,
    wrap_angle,
)

coordinate = st.floats(-50.0, 50.0, allow_nan=False)
heading = st.floats(-10.0, 10.0, allow_nan=False)
poses = st.tuples(coordinate, coordinate, heading)


def matrix(pose) -> np.ndarray:
    """The homogeneous 3x3 matrix of a planar pose."""
    x, y, theta = pose
    c, s = math.cos(theta), math.sin(theta)
    return np.array([[c, -s, x], [s, c, y], [0.0, 0.0, 1.0]])


def pose_of(m: np.ndarray) -> tuple[float, float, float]:
    return float(m[0, 2]), float(m[1, 2]), math.atan2(m[1, 0], m[0, 0])


def assert_same_pose(a, b) -> None:
    np.testing.assert_allclose(a[:2], b[:2], atol=1e-9)
    assert abs(math.remainder(a[2] - b[2], math.tau)) < 1e-9


@settings(max_examples=60, deadline=None)
@given(poses, poses)
def test_compose_invert_and_relative_are_matrix_products(a, b) -> None:
    assert_same_pose(compose(a, b), pose_of(matrix(a) @ matrix(b)))
    assert_same_pose(invert(a), pose_of(np.linalg.inv(matrix(a))))
    assert_same_pose(relative_pose(a, b), pose_of(np.linalg.inv(matrix(a)) @ matrix(b)))
    assert -math.pi <= compose(a, b)[2] <= math.pi


@settings(max_examples=30, deadline=None)
@given(st.lists(st.tuples(poses, poses), min_size=1, max_size=6))
def test_the_many_versions_equal_the_one_pose_versions_row_by_row(pairs) -> None:
    a = np.array([p for p, _ in pairs])
    b = np.array([q for _, q in pairs])
    many = compose_many(a, b)
    assert many.shape == (len(pairs), 3)
    for row, (p, q) in zip(many, pairs, strict=True):
        assert_same_pose(row, compose(p, q))
    for row, p in zip(invert_many(a), a, strict=True):
        assert_same_pose(row, invert(tuple(p)))
    for row, (p, q) in zip(between_many(a, b), pairs, strict=True):
        assert_same_pose(row, relative_pose(p, q))
    # one pose on either side broadcasts
    assert_same_pose(compose_many(a[0], b)[-1], compose(tuple(a[0]), tuple(b[-1])))


def test_transform_points_moves_points_as_the_pose_matrix() -> None:
    pose = (1.0, -2.0, 0.7)
    xy = np.array([[0.0, 0.0], [1.0, 0.0], [-3.0, 2.5]])
    homogeneous = matrix(pose) @ np.column_stack([xy, np.ones(3)]).T
    np.testing.assert_allclose(transform_points(xy, pose), homogeneous[:2].T, atol=1e-12)


def test_wrap_angle_keeps_the_angle_and_lands_in_range() -> None:
    angles = np.array([0.0, 3 * math.pi / 2, -3 * math.pi / 2, 7.0, -100.0, math.pi])
    wrapped = wrap_angle(angles)
    assert np.all(np.abs(wrapped) <= math.pi)
    np.testing.assert_allclose(np.sin(wrapped), np.sin(angles), atol=1e-12)
    np.testing.assert_allclose(np.cos(wrapped), np.cos(angles), atol=1e-12)
    assert wrap_angle(3 * math.pi / 2) == pytest.approx(-math.pi / 2)


def test_rotate_covariance_is_r_cov_r_transposed() -> None:
    cov = np.diag([4.0, 1.0, 0.5])
    turned = rotate_covariance(cov, math.pi / 2)
    np.testing.assert_allclose(turned, np.diag([1.0, 4.0, 0.5]), atol=1e-12)
    back = rotate_covariance(rotate_covariance(cov + 0.1, 0.3), -0.3)
    np.testing.assert_allclose(back, cov + 0.1, atol=1e-12)


def test_pose_error_and_poses_apart() -> None:
    distance, angle = pose_error((3.0, 4.0, math.pi - 0.1), (0.0, 0.0, -math.pi + 0.1))
    assert distance == pytest.approx(5.0) and angle == pytest.approx(0.2)
    assert not poses_apart((0.0, 0.0, 3.1), (0.5, 0.0, -3.1), 1.0, 0.3)  # 0.08 rad apart
    assert poses_apart((0.0, 0.0, 0.0), (1.0, 0.0, 0.0), 1.0, 0.3)
    assert poses_apart((0.0, 0.0, 0.0), (0.0, 0.0, 0.31), 1.0, 0.3)
    assert poses_apart((0.0, 0.0, 3.0), (0.0, 0.0, -3.0), 1.0, 0.25)  # 0.28 rad over ±π


@pytest.mark.parametrize(
    ("pose", "message"),
    [
        ((1.0, 2.0), "pose must be 3 numbers x, y, theta, got 2"),
        ((1.0, math.nan, 0.0), "pose must be finite"),
        ((2 * MAX_COORDINATE, 0.0, 0.0), "pose x, y must be within"),
    ],
)
def test_bad_poses_are_named(pose, message: str) -> None:
    assert message in pose_problem(pose)
    with pytest.raises(ValueError, match=f"^start: {message}"):
        check_pose(pose, "start")


def test_good_pose_passes_the_check() -> None:
    assert pose_problem((1.0, 2.0, 3.0)) is None
    checked = check_pose([[1, 2, 3]])
    assert checked.dtype == np.float64 and checked.tolist() == [1.0, 2.0, 3.0]


def _distinct_reference(poses, order, count, xy, yaw) -> list[int]:
    chosen: list[int] = []
    for i in order:
        if all(poses_apart(poses[i], poses[j], xy, yaw) for j in chosen):
            chosen.append(int(i))
            if len(chosen) == count:
                break
    return chosen


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_distinct_poses_is_the_greedy_pass_over_the_order(seed: int) -> None:
    """The compiled pass takes the same poses as the pairwise loop it replaces (heading
    differences across ±π included), in order, at most ``count``."""
    rng = np.random.default_rng(seed)
    poses = np.column_stack(
        [rng.uniform(0, 4, 600), rng.uniform(0, 4, 600), rng.uniform(-4, 4, 600)]
    )
    order = rng.permutation(600)
    for count in (1, 10, 64, 600):
        got = distinct_poses(poses, order, count, 1.0, 0.3)
        assert got == _distinct_reference(poses, order, count, 1.0, 0.3)
        assert len(got) <= count
    assert distinct_poses(np.zeros((0, 3)), [], 5, 1.0, 0.3) == []
