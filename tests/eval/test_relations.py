"""The relation metric (Kümmerle et al. 2009, as Cartographer computes it) on known answers."""

from __future__ import annotations

import math

import numpy as np
import pytest

from laser_corners.errors import InputError
from laser_corners.eval.relations import read_relations, relation_metrics
from laser_corners.pose import between_many


def _square_path(n: int = 200) -> tuple[np.ndarray, np.ndarray]:
    t = np.linspace(0.0, 20.0, n)
    poses = np.stack([np.cos(0.3 * t) * 3, np.sin(0.3 * t) * 3, 0.3 * t + math.pi / 2], axis=1)
    poses[:, 2] = (poses[:, 2] + math.pi) % (2 * math.pi) - math.pi
    return t, poses


def _relations_of(t: np.ndarray, poses: np.ndarray, pairs: list[tuple[int, int]]) -> np.ndarray:
    rows = []
    for a, b in pairs:
        rel = between_many(poses[a], poses[b])
        rows.append((t[a], t[b], rel[0], rel[1], rel[2]))
    return np.array(rows)


def test_identical_trajectory_has_zero_error() -> None:
    t, poses = _square_path()
    rel = _relations_of(t, poses, [(i, i + 7) for i in range(0, 180, 5)])
    m = relation_metrics(t, poses, rel)
    assert m.n_covered == m.n_total == rel.shape[0]
    assert m.trans_mean < 1e-9 and m.rot_deg_mean < 1e-7


def test_a_rigid_map_motion_does_not_change_the_error() -> None:
    t, poses = _square_path()
    rel = _relations_of(t, poses, [(i, i + 11) for i in range(0, 180, 3)])
    c, s = math.cos(0.7), math.sin(0.7)
    moved = poses.copy()
    moved[:, 0] = c * poses[:, 0] - s * poses[:, 1] + 5.0
    moved[:, 1] = s * poses[:, 0] + c * poses[:, 1] - 2.0
    moved[:, 2] = poses[:, 2] + 0.7
    m = relation_metrics(t, moved, rel)
    assert m.trans_mean < 1e-9 and m.rot_deg_mean < 1e-7


def test_known_offset_gives_the_known_error() -> None:
    # straight line along x; the expected relations say 0.1 m more forward and 2 degrees more
    t = np.arange(10.0)
    poses = np.stack([t, np.zeros(10), np.zeros(10)], axis=1)
    rel = np.array(
        [[1.0, 2.0, 1.1, 0.0, math.radians(2.0)], [3.0, 5.0, 2.1, 0.0, math.radians(2.0)]]
    )
    m = relation_metrics(t, poses, rel)
    # error = expected^-1 * actual: actual (1,0,0); rotating the residual by -2 deg keeps |t|
    assert m.trans_mean == pytest.approx(0.1, abs=1e-9)
    assert m.rot_deg_mean == pytest.approx(2.0, abs=1e-9)
    assert m.trans2_mean == pytest.approx(0.01, abs=1e-9)
    assert m.rot2_mean == pytest.approx(4.0, abs=1e-9)


def test_interpolates_between_poses_and_unwraps_yaw() -> None:
    t = np.array([0.0, 1.0, 2.0])
    poses = np.array([[0.0, 0.0, 3.0], [1.0, 0.0, -3.0], [2.0, 0.0, -2.9]])  # crosses +-pi
    halfway_yaw = 3.0 + (2 * math.pi - 6.0) / 2  # interpolated on the short way round
    rel = np.array([[0.0, 0.5, 0.5 * math.cos(-3.0) * 0 + 0.0, 0.0, 0.0]])
    m = relation_metrics(t, poses, rel)
    expected_yaw = math.degrees(abs(halfway_yaw - 3.0))
    assert m.rot_deg_mean == pytest.approx(expected_yaw, abs=1e-6)


def test_relations_outside_the_trajectory_are_not_covered() -> None:
    t, poses = _square_path()
    rel = _relations_of(t, poses, [(10, 20), (30, 40)])
    outside = np.array([[-5.0, 1.0, 0.0, 0.0, 0.0], [19.0, 25.0, 0.0, 0.0, 0.0]])
    m = relation_metrics(t, poses, np.vstack([rel, outside]))
    assert (m.n_total, m.n_covered) == (4, 2)
    assert m.trans_mean < 1e-9
    none = relation_metrics(t, poses, outside)
    assert none.n_covered == 0 and math.isnan(none.trans_mean)


def test_read_relations(tmp_path) -> None:
    path = tmp_path / "log.relations"
    path.write_text("1.0 2.0 0.5 -0.1 0 0 0 0.2\n\n3.5 4.5 1 2 0 0 0 -0.3\n")
    rel = read_relations(path)
    np.testing.assert_allclose(rel, [[1.0, 2.0, 0.5, -0.1, 0.2], [3.5, 4.5, 1.0, 2.0, -0.3]])


@pytest.mark.parametrize(
    ("text", "where"),
    [
        ("1 2 3 4 0 0 0 5\n1 2 x 4 0 0 0 5\n", ":2:"),
        ("1 2 3 4 0 0 0\n", ":1:"),
        ("1 2 3 4 0 0 0 nan\n", ":1:"),
    ],
)
def test_bad_relations_line_names_file_and_line(tmp_path, text: str, where: str) -> None:
    path = tmp_path / "bad.relations"
    path.write_text(text)
    with pytest.raises(InputError) as info:
        read_relations(path)
    message = str(info.value)
    assert f"{path}{where}" in message and "\n" not in message


def test_missing_relations_file(tmp_path) -> None:
    with pytest.raises(InputError, match="no such file"):
        read_relations(tmp_path / "none.relations")
