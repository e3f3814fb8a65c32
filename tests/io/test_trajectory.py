"""TUM trajectories: round trip, quaternion convention, errors naming file:line, atomic writes."""

from __future__ import annotations

import doctest
import math
from pathlib import Path

import numpy as np
import pytest

import laser_corners.io.trajectory as trajectory_module
from laser_corners.errors import InputError
from laser_corners.eval.poses import read_tum as eval_read_tum
from laser_corners.io.trajectory import TumWriter, read_tum, write_tum, yaw_quaternion


def test_round_trip_keeps_stamps_positions_and_yaw(tmp_path: Path) -> None:
    rng = np.random.default_rng(3)
    stamps = 1_300_000_000.0 + np.cumsum(rng.uniform(0.01, 0.2, 50))
    poses = np.column_stack(
        [rng.normal(0, 20, 50), rng.normal(0, 20, 50), rng.uniform(-math.pi, math.pi, 50)]
    )
    path = tmp_path / "t.tum"
    write_tum(path, stamps, poses, header="laser-corners slam\nsecond line")
    got_t, got_p = read_tum(path)
    np.testing.assert_allclose(got_t, stamps, atol=1e-8)
    np.testing.assert_allclose(got_p[:, :2], poses[:, :2], atol=1e-6)
    np.testing.assert_allclose(np.angle(np.exp(1j * (got_p[:, 2] - poses[:, 2]))), 0, atol=1e-7)
    # the package's evaluation reader reads the same file to the same poses
    other = eval_read_tum(path)
    np.testing.assert_allclose(other.poses, got_p, atol=1e-12)
    lines = path.read_text().splitlines()
    assert lines[0] == "# laser-corners slam" and len(lines) == 52


def test_line_layout_is_tum_with_a_z_axis_quaternion(tmp_path: Path) -> None:
    path = tmp_path / "t.tum"
    with TumWriter(path) as writer:
        writer.write(12.5, (1.0, -2.0, math.pi / 2))
    tokens = [float(v) for v in path.read_text().split()]
    assert len(tokens) == 8
    assert tokens[:4] == [12.5, 1.0, -2.0, 0.0]
    np.testing.assert_allclose(tokens[4:], [0, 0, math.sqrt(0.5), math.sqrt(0.5)], atol=1e-9)
    np.testing.assert_allclose(
        yaw_quaternion([0.0, math.pi]), [[0, 0, 0, 1], [0, 0, 1, 0]], atol=1e-12
    )


def test_incremental_writer_publishes_only_when_closed(tmp_path: Path) -> None:
    path = tmp_path / "t.tum"
    writer = TumWriter(path)
    writer.write(0.0, (0.0, 0.0, 0.0))
    writer.write_many([0.1, 0.2], [[1.0, 0.0, 0.1], [2.0, 0.0, 0.2]])
    assert not path.exists() and len(list(tmp_path.glob("t.*.partial.tum"))) == 1
    writer.close()
    writer.close()
    assert path.exists() and not list(tmp_path.glob("*.partial*"))
    assert writer.n_poses == 3 and len(read_tum(path)[0]) == 3


@pytest.mark.parametrize(
    ("text", "needle"),
    [
        ("0 0 0 0 0 0 0 1\n1 2 3\n", ":2: a TUM line needs 8 numbers"),
        ("# c\n0 0 0 0 0 0 0 1\n0 x 0 0 0 0 0 1\n", ":3: not a number"),
        ("0 0 0 0 0 0 0 nan\n", ":1: non-finite"),
        ("# only a comment\n", "no TUM lines"),
    ],
)
def test_bad_lines_name_file_and_line(tmp_path: Path, text: str, needle: str) -> None:
    path = tmp_path / "bad.tum"
    path.write_text(text)
    with pytest.raises(InputError) as info:
        read_tum(path)
    assert str(path) in str(info.value) and needle in str(info.value)
    with pytest.raises(InputError, match="no such file"):
        read_tum(tmp_path / "missing.tum")


def test_docstring_example() -> None:
    assert doctest.testmod(trajectory_module).failed == 0


def test_a_with_block_left_by_an_error_keeps_the_earlier_file(tmp_path: Path) -> None:
    path = tmp_path / "online.tum"
    write_tum(path, [0.0], [[1.0, 2.0, 0.5]], header="an earlier run")
    before = path.read_bytes()
    with pytest.raises(RuntimeError), TumWriter(path, header="this run") as writer:
        writer.write(1.0, (0.0, 0.0, 0.0))
        raise RuntimeError("the run failed")
    assert path.read_bytes() == before and sorted(tmp_path.iterdir()) == [path]
    with pytest.raises(KeyError), TumWriter(tmp_path / "new.tum", header="no pose yet"):
        raise KeyError("before the first pose")
    assert sorted(tmp_path.iterdir()) == [path]  # no header-only file
