"""What a SLAM run gives (:mod:`laser_corners.slam.result`): laser poses through the mount, and
the pose graph written as g2o (robust edges by their Gaussian base; a bad path in one line)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from laser_corners.errors import OutputError
from laser_corners.pose import compose
from laser_corners.slam.options import SlamOptions
from laser_corners.slam.result import COUNT_KEYS, Landmarks, SlamResult

gtsam = pytest.importorskip("gtsam")

POSES = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.5], [1.5, 1.0, math.pi]])
MOUNT = np.array([0.2, -0.1, 0.3])


def result(graph=None, values=None) -> SlamResult:
    return SlamResult(
        stamps=np.arange(3.0),
        poses=POSES,
        odometry=POSES,
        keyframes=np.array([0, 2]),
        keyframe_poses=POSES[[0, 2]],
        scans=[],
        mount=MOUNT,
        landmarks=Landmarks(),
        closures=[],
        ms_per_scan=np.ones(3),
        options=SlamOptions(),
        counts=dict.fromkeys(COUNT_KEYS, 0),
        graph=graph,
        values=values,
    )


def test_laser_poses_compose_the_mount() -> None:
    expected = [compose(tuple(p), tuple(MOUNT)) for p in POSES]
    np.testing.assert_allclose(result().laser_poses, expected, atol=1e-12)
    assert len(Landmarks()) == 0


def test_write_g2o_writes_robust_edges_with_their_gaussian_information(tmp_path: Path) -> None:
    sigmas = np.array([0.1, 0.2, 0.05])
    gaussian = gtsam.noiseModel.Diagonal.Sigmas(sigmas)
    robust = gtsam.noiseModel.Robust.Create(gtsam.noiseModel.mEstimator.Huber.Create(1.0), gaussian)
    graph = gtsam.NonlinearFactorGraph()
    graph.add(gtsam.BetweenFactorPose2(0, 1, gtsam.Pose2(1.0, 0.0, 0.5), robust))
    graph.add(gtsam.BetweenFactorPose2(1, 2, gtsam.Pose2(0.5, 1.0, 0.3), gaussian))
    values = gtsam.Values()
    for key, pose in enumerate(POSES):
        values.insert(key, gtsam.Pose2(*pose))
    path = tmp_path / "out" / "graph.g2o"  # the folder is made
    result(graph, values).write_g2o(path)
    lines = path.read_text().splitlines()
    vertices = [line.split() for line in lines if line.startswith("VERTEX_SE2")]
    edges = [line.split() for line in lines if line.startswith("EDGE_SE2")]
    assert len(vertices) == 3 and len(edges) == 2  # the robust edge too
    np.testing.assert_allclose([float(v) for v in vertices[1][2:5]], POSES[1], atol=1e-6)
    info = [float(v) for v in edges[0][6:12]]  # upper triangle of the information matrix
    np.testing.assert_allclose(info, [100.0, 0.0, 0.0, 25.0, 0.0, 400.0], rtol=1e-6)


def test_write_g2o_without_a_graph_and_into_a_bad_place(tmp_path: Path) -> None:
    empty = tmp_path / "empty.g2o"
    result().write_g2o(empty)
    assert empty.read_text().strip() == ""
    blocker = tmp_path / "file"
    blocker.write_text("")
    with pytest.raises(OutputError, match="cannot write the graph") as info:
        result().write_g2o(blocker / "graph.g2o")
    assert str(blocker) in str(info.value) and "\n" not in str(info.value)
