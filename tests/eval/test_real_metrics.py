"""The eval pose files (:mod:`laser_corners.eval.poses`: TUM, relations, interpolation) and the
Section-IV docstring examples; each metric has its own mirrored file (test_visibility, ...)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from laser_corners.errors import InputError
from laser_corners.eval.poses import Trajectory, interpolate_poses, read_relations, read_tum
from laser_corners.scan import compose, invert, relative_pose


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
