"""Weighted least-squares SE(2) (:mod:`laser_corners.matching.solve`): an exact transform is
recovered from a wrong start, with the covariance worked by hand; degenerate geometry keeps
the start."""

from __future__ import annotations

import math

import numpy as np
import pytest

from laser_corners.matching.solve import wls_pose

NAN_COV = np.full((1, 2, 2), np.nan)


def problem(pose, n: int = 6, seed: int = 0):
    """Points ``b``, centred, and ``a = R b + t``: every match (i, i)."""
    rng = np.random.default_rng(seed)
    b = rng.uniform(-3.0, 3.0, (n, 2))
    b -= b.mean(axis=0)
    c, s = math.cos(pose[2]), math.sin(pose[2])
    a = b @ np.array([[c, s], [-s, c]]) + pose[:2]
    m = np.column_stack([np.arange(n), np.arange(n)]).astype(np.int64)
    return a, b, m


@pytest.mark.parametrize("pose", [(0.5, -1.0, 0.3), (-2.0, 3.0, -2.8), (0.0, 0.0, 0.0)])
def test_an_exact_transform_is_recovered_with_the_known_covariance(pose) -> None:
    a, b, m = problem(np.array(pose))
    n = len(a)
    var = 0.01
    cov = np.repeat(np.eye(2)[None] * var, n, axis=0)
    pose_cov = np.zeros((3, 3))
    start = (pose[0] + 0.3, pose[1] - 0.2, pose[2] + 0.15)
    found = wls_pose(a, b, cov, cov, m, np.arange(n), n, *start, 0.5, pose_cov)
    np.testing.assert_allclose(found[:2], pose[:2], atol=1e-9)
    assert abs(math.remainder(found[2] - pose[2], math.tau)) < 1e-9
    # residual covariance 2 var per axis; with centred points the pose covariance is diagonal
    expected = 2 * var * np.diag([1 / n, 1 / n, 1 / float(np.sum(b**2))])
    np.testing.assert_allclose(pose_cov, expected, atol=1e-12)


def test_unknown_covariances_take_the_default_variance() -> None:
    a, b, m = problem(np.array([1.0, 1.0, 0.5]), n=4)
    nan = np.full((4, 2, 2), np.nan)
    pose_cov = np.zeros((3, 3))
    found = wls_pose(a, b, nan, nan, m, np.arange(4), 4, 0.0, 0.0, 0.0, 0.02, pose_cov)
    np.testing.assert_allclose(found, (1.0, 1.0, 0.5), atol=1e-9)
    assert pose_cov[0, 0] == pytest.approx(2 * 0.02 / 4)


def test_only_the_selected_matches_count() -> None:
    a, b, m = problem(np.array([1.0, -1.0, 0.2]), n=6)
    a[5] += 10.0  # an outlier, left out of the selection
    cov = np.repeat(np.eye(2)[None] * 0.01, 6, axis=0)
    pose_cov = np.zeros((3, 3))
    found = wls_pose(a, b, cov, cov, m, np.arange(6), 5, 0.0, 0.0, 0.0, 0.01, pose_cov)
    np.testing.assert_allclose(found, (1.0, -1.0, 0.2), atol=1e-9)


def test_one_match_is_degenerate_and_keeps_the_start() -> None:
    a, b, m = problem(np.array([1.0, 2.0, 0.4]), n=1)
    pose_cov = np.zeros((3, 3))
    found = wls_pose(a, b, NAN_COV, NAN_COV, m, np.arange(1), 1, 0.1, 0.2, 0.3, 0.01, pose_cov)
    assert found == (0.1, 0.2, 0.3) and np.isinf(pose_cov).all()
