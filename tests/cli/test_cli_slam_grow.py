"""``laser-corners slam INPUT --map OLD -o NEW``: a map grown by a second session."""

from __future__ import annotations

import hashlib
import json
import shutil
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

pytest.importorskip("gtsam")

from laser_corners.cli import app
from laser_corners.io.trajectory import read_tum
from laser_corners.registration.mapfolder import load_map
from laser_corners.sim import World
from sim_drives import TF, legs, marked_building, write_drive_bag

runner = CliRunner()
SESSION_1 = [[1.5, 1.5], [4.5, 1.5], [4.5, 6.5], [1.5, 6.5], [1.5, 1.5], [7.5, 4.0], [10.5, 2]]
SESSION_2 = [[10.5, 6.5], [10.5, 2.0], [7.5, 4.0], [3.0, 4.0], [1.5, 6.0]]
ELSEWHERE = (5.0, -3.0, 1.0)
"""Added to the second session's odometry: its frame is not the map's."""


def _invoke(*args: str | Path):
    return runner.invoke(app, [str(a) for a in args])


def _one_line_error(result, *needles: str) -> None:
    assert result.exit_code == 2, result.output
    assert "Traceback" not in result.stderr
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("laser-corners: error: "), result.stderr
    for needle in needles:
        assert needle in lines[0], lines[0]


def _hashes(folder: Path) -> dict[str, str]:
    return {
        p.name: hashlib.sha256(p.read_bytes()).hexdigest()
        for p in sorted(folder.iterdir())
        if p.is_file()
    }


@pytest.fixture(scope="module")
def sessions(tmp_path_factory) -> dict[str, Path]:
    """Two bags of the marked building (odometry exact, in the map's frame for the first,
    offset by :data:`ELSEWHERE` for the second) and the first one's map folder."""
    root = tmp_path_factory.mktemp("grow")
    world = marked_building()
    one = write_drive_bag(root / "one.bag", world, legs(SESSION_1), (0, 0, 0), {TF: (0, 0, 0)})
    two = write_drive_bag(root / "two.bag", world, legs(SESSION_2), (0, 0, 0), {TF: ELSEWHERE})
    old = root / "old"
    result = _invoke("slam", one, "-o", old)
    assert result.exit_code == 0, result.output
    return {"root": root, "one": one, "two": two, "old": old}


def test_slam_map_grows_the_old_map_into_a_new_one(sessions, tmp_path) -> None:
    old, new = sessions["old"], tmp_path / "new"
    before = _hashes(old)
    result = _invoke("slam", sessions["two"], "--map", old, "-o", new, "--start-scan", 5)
    assert result.exit_code == 0, result.output
    assert _hashes(old) == before  # OLD untouched
    n_old = len(load_map(old))
    grown = load_map(new)  # what localise and slam --map read
    summary = json.loads((new / "summary.json").read_text())
    counts = summary["counts"]
    assert counts["prior_keyframes"] == n_old and counts["grow_unjoined"] == 0
    assert summary["prior_map"] == {"folder": str(old), "keyframes": n_old}
    assert len(grown) == counts["keyframes"] > n_old
    # OLD's keyframes bent by the new closures (OLD's own graph, not fixed), not moved away
    np.testing.assert_allclose(grown.poses[:n_old], load_map(old).poses, atol=0.1)
    # the second session's trajectory, in the map's frame (the truth's)
    stamps, poses = read_tum(new / "trajectory.tum")
    truth = legs(SESSION_2)[5:]
    assert len(stamps) == len(truth)
    assert np.hypot(*(poses[:, :2] - truth[:, :2]).T).max() < 0.15
    assert "never found itself" not in result.stderr
    # grown again, from the grown map
    again = tmp_path / "again"
    result = _invoke("slam", sessions["one"], "--map", new, "-o", again, "--stop-scan", 60)
    assert result.exit_code == 0, result.output
    assert len(load_map(again)) > len(grown)


def test_an_initial_pose_places_the_first_scan(sessions, tmp_path) -> None:
    truth = legs(SESSION_2)
    pose = ",".join(f"{v:.3f}" for v in truth[0] + np.array([0.15, -0.1, 0.04]))
    new = tmp_path / "new"
    result = _invoke(
        "slam", sessions["two"], "--map", sessions["old"], "-o", new, "--initial-pose", pose
    )
    assert result.exit_code == 0, result.output
    counts = json.loads((new / "summary.json").read_text())["counts"]
    # placed from the first scan: a relocalisation only after the tracking lost a scan
    assert counts["relocalisations_attempted"] == 0 or counts["alignment_failures"] >= 1
    assert counts["grow_unjoined"] == 0
    _, poses = read_tum(new / "trajectory.tum")
    assert np.hypot(*(poses[:, :2] - truth[:, :2]).T).max() < 0.15


def test_bad_maps_and_outputs_are_one_line(sessions, tmp_path) -> None:
    old, two = sessions["old"], sessions["two"]
    before = _hashes(old)
    _one_line_error(_invoke("slam", two, "--map", old, "-o", old), "would write over the input")
    _one_line_error(
        _invoke("slam", two, "--map", old / "map.yaml", "-o", tmp_path / "n"), "map_server"
    )
    _one_line_error(
        _invoke("slam", two, "-o", tmp_path / "n", "--initial-pose", "0,0,0"), "only with --map"
    )
    _one_line_error(
        _invoke("slam", two, "--map", tmp_path / "none", "-o", tmp_path / "n"), "no such map folder"
    )
    other = tmp_path / "v9"
    shutil.copytree(old, other)
    with np.load(other / "keyframes.npz") as data:
        arrays = {k: data[k] for k in data.files}
    arrays["format_version"] = np.int64(9)
    np.savez(other / "keyframes.npz", **arrays)
    _one_line_error(_invoke("slam", two, "--map", other, "-o", tmp_path / "n"), "format version 9")
    broken = tmp_path / "broken"
    shutil.copytree(old, broken)
    (broken / "graph.g2o").write_text("VERTEX_SE2 0 0 0 0\nEDGE_SE2 0 1 garbage\n")
    _one_line_error(
        _invoke("slam", two, "--map", broken, "-o", tmp_path / "n"), "graph.g2o: unreadable"
    )
    assert not (tmp_path / "n").exists()
    assert _hashes(old) == before


def test_a_session_elsewhere_is_kept_with_a_warning(sessions, tmp_path) -> None:
    hall = World().add_polygon([[0, 0], [20, 0], [20, 3], [0, 3]])
    for x in (4.0, 9.0, 13.5):
        hall.add_circle((x, 1.0), 0.25)
    hall.add_polygon([[16, 2.2], [17.5, 2.2], [17.5, 3], [16, 3]])
    drive = legs([[1.5, 1.5], [18.5, 1.5], [18.5, 2.0], [1.5, 2.0]])
    bag = write_drive_bag(tmp_path / "hall.bag", hall, drive, (0, 0, 0), {TF: (0, 0, 0)})
    new = tmp_path / "new"
    result = _invoke("slam", bag, "--map", sessions["old"], "-o", new)
    assert result.exit_code == 0, result.output
    assert "never found itself in the prior map" in result.stderr
    summary = json.loads((new / "summary.json").read_text())
    assert summary["counts"]["grow_unjoined"] == 1
    assert any("never found itself" in w for w in summary["warnings"])
    assert len(load_map(new)) == summary["counts"]["keyframes"] > len(load_map(sessions["old"]))
