"""Scan pairs for repeatability (:mod:`laser_corners.eval.pairs`): from relations (through the
mount) and from poses."""

from __future__ import annotations

import math

import pytest

from laser_corners.eval.pairs import pairs_from_poses, pairs_from_relations
from laser_corners.eval.poses import read_relations
from laser_corners.scan import compose, invert


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
