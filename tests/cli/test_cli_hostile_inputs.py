"""Hostile inputs to ``slam``, ``localise`` and ``evaluate slam`` (issue 32): what a reader
skips is counted and said, a broken pose or stamp is a counted skip or one line, never a crash.

The commands that could crash in a numba kernel run in a subprocess: a segfault there would
end pytest itself.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from itertools import islice
from pathlib import Path

import numpy as np
import pytest
from rosbags.rosbag1 import Reader
from typer.testing import CliRunner

from conftest import REPO_ROOT, damaged_copy, die_with_parent, real_file
from laser_corners.cli import app
from laser_corners.io import open_scans
from laser_corners.io.arrays import write_scans_npz
from laser_corners.io.trajectory import read_tum

runner = CliRunner()
N_SCANS = 300
FLIPPED = 160000  # a byte inside fr079.bag's second bz2 chunk (scans 246 to 492)


def _invoke(*args: str | Path):
    return runner.invoke(app, [str(a) for a in args], terminal_width=200)


def _cli(*args: str | Path, env: dict[str, str] | None = None) -> subprocess.CompletedProcess:
    """``laser-corners ARGS`` in a new Python (this checkout's sources), output captured."""
    paths = [str(REPO_ROOT / "src"), os.environ.get("PYTHONPATH", "")]
    environment = {**os.environ, "PYTHONPATH": os.pathsep.join(paths), **(env or {})}
    return subprocess.run(
        [sys.executable, "-c", "from laser_corners.cli import main; main()", *map(str, args)],
        capture_output=True,
        text=True,
        env={k: v for k, v in environment.items() if v is not None},
        timeout=600,
        preexec_fn=die_with_parent(),
    )


def _one_line(process: subprocess.CompletedProcess, *needles: str) -> str:
    """The process failed with exit 2 and one ``laser-corners: error:`` line holding
    ``needles``; that line."""
    assert process.returncode == 2, (process.returncode, process.stderr)
    assert "Traceback" not in process.stderr, process.stderr
    lines = process.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("laser-corners: error: "), process.stderr
    for needle in needles:
        assert needle in lines[0], lines[0]
    return lines[0]


@pytest.fixture(scope="module")
def fr079(tmp_path_factory) -> tuple[Path, Path]:
    """The first 300 scans of fr079.bag as an NPZ, and the map ``slam`` made of them."""
    folder = tmp_path_factory.mktemp("fr079")
    npz = folder / "fr079.npz"
    write_scans_npz(npz, islice(open_scans(real_file("fr079.bag")), N_SCANS))
    result = _invoke("slam", npz, "-o", folder / "map")
    assert result.exit_code == 0, result.output
    return npz, folder / "map"


def _lost_scans(bag: Path, offset: int) -> int:
    """How many /scan messages the chunk of ``bag`` holding byte ``offset`` has."""
    with Reader(bag) as reader:
        pos = next(
            p for p, c in reader.chunks.items() if c.datapos <= offset < c.datapos + c.datasize
        )
        scan = next(c for c in reader.connections if c.topic == "/scan")
        return sum(1 for entry in reader.indexes[scan.id] if entry.chunk_pos == pos)


def _warning_lines(stderr: str) -> list[str]:
    return [line for line in stderr.splitlines() if line.startswith("laser-corners: warning:")]


@pytest.mark.real
def test_slam_and_localise_say_how_many_scans_a_damaged_chunk_lost(
    fr079: tuple[Path, Path], tmp_path: Path
) -> None:
    intact = real_file("fr079.bag")
    bag = damaged_copy(intact, tmp_path / "fr079.bag", flip=slice(FLIPPED, FLIPPED + 1))
    lost = _lost_scans(intact, FLIPPED)
    assert 200 < lost < 300
    _, map_folder = fr079
    for command in (["slam", bag], ["localise", map_folder, bag]):
        out = tmp_path / command[0]
        result = _invoke(*command, "-o", out, "--stop-scan", N_SCANS)
        assert result.exit_code == 0, result.output
        warnings = _warning_lines(result.stderr)
        assert len(warnings) == 1, result.stderr
        assert f"{lost} scans in damaged chunks or records" in warnings[0], warnings
        assert "1 damaged bag chunk" in warnings[0] and str(bag) in warnings[0], warnings
        summary = json.loads((out / "summary.json").read_text())
        assert summary["skipped"] == {
            "damaged bag chunk": 1,
            "scans in damaged chunks or records": lost,
        }, summary["skipped"]
        assert any(f"{lost} scans in damaged" in w for w in summary["warnings"]), summary


@pytest.mark.real
def test_broken_rows_of_an_npz_are_counted_skips_of_slam(
    fr079: tuple[Path, Path], tmp_path: Path
) -> None:
    """A NaN pose, a pose 1e300 m away and a NaN stamp: three counted skips, said on one
    line and in summary.json; no crash."""
    npz, _ = fr079
    data = dict(np.load(npz))
    data["poses"][100, 0] = np.nan
    data["poses"][150, 0] = 1e300
    data["stamps"][200] = np.nan
    bad = tmp_path / "bad.npz"
    np.savez(bad, **data)
    out = tmp_path / "out"
    process = _cli("slam", bad, "-o", out)
    assert process.returncode == 0, process.stderr
    assert "Traceback" not in process.stderr, process.stderr
    warnings = _warning_lines(process.stderr)
    assert len(warnings) == 1, process.stderr
    summary = json.loads((out / "summary.json").read_text())
    assert sum(summary["skipped"].values()) == 3, summary["skipped"]
    assert summary["counts"]["scans"] == N_SCANS - 3
    for reason, count in summary["skipped"].items():
        assert f"{count} {reason}" in warnings[0], warnings


@pytest.mark.real
@pytest.mark.parametrize("pose", ["nan,0,0", "0,inf,0", "1e300,0,0", "0,0,-inf"])
def test_a_non_finite_or_absurd_initial_pose_is_one_line(
    fr079: tuple[Path, Path], tmp_path: Path, pose: str
) -> None:
    npz, map_folder = fr079
    out = tmp_path / "out"
    process = _cli("localise", map_folder, npz, "-o", out, f"--initial-pose={pose}")
    _one_line(process, "--initial-pose")
    assert not out.exists()
    process = _cli("localise", map_folder, npz, "-o", out, f"--mount={pose}")
    _one_line(process, "--mount")
    if "1e300" not in pose:  # a mount of 1e300 m is out of the option's range, said as such
        process = _cli("localise", map_folder, npz, "-o", out, "--set", f"mount={pose}")
        _one_line(process, "mount", "finite")


@pytest.mark.real
def test_a_start_scan_beyond_the_recording_says_how_many_scans_it_has(
    fr079: tuple[Path, Path], tmp_path: Path
) -> None:
    npz, map_folder = fr079
    result = _invoke("localise", map_folder, npz, "-o", tmp_path / "o", "--start-scan", 99999)
    assert result.exit_code == 2, result.output
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in result.stderr, result.stderr
    assert f"the recording has {N_SCANS} scans" in lines[0] and "99999" in lines[0], lines


def _tum(path: Path, stamps: np.ndarray, quaternion: str = "0 0 0 1") -> Path:
    path.write_text("".join(f"{t:.3f} {0.5 * t:.4f} 0 0 {quaternion}\n" for t in stamps))
    return path


def _relations(path: Path, start: float, n: int = 9) -> Path:
    rows = [f"{t:.1f} {t + 1:.1f} 0.5 0 0 0 0 0" for t in start + np.arange(n)]
    path.write_text("\n".join(rows) + "\n")
    return path


def test_evaluate_slam_refuses_a_zero_quaternion_naming_file_and_row(tmp_path: Path) -> None:
    trajectory = _tum(tmp_path / "t.tum", np.arange(10.0))
    lines = trajectory.read_text().splitlines()
    lines[3] = "3.000 1.5000 0 0 0 0 0 0"
    trajectory.write_text("\n".join(lines) + "\n")
    relations = _relations(tmp_path / "r.relations", 0.0)
    process = _cli("evaluate", "slam", trajectory, relations)
    _one_line(process, f"{trajectory}:4", "quaternion")


def test_evaluate_slam_with_relations_of_another_recording_fails_saying_so(
    tmp_path: Path,
) -> None:
    trajectory = _tum(tmp_path / "t.tum", np.arange(10.0))
    relations = _relations(tmp_path / "r.relations", 5000.0)
    process = _cli("evaluate", "slam", trajectory, relations)
    line = _one_line(process, "no relation", "covered", str(relations))
    assert "0.000" in line and "5000.0" in line, line  # the two time spans


def test_evaluate_slam_given_a_folder_says_it_is_a_folder(tmp_path: Path) -> None:
    folder = tmp_path / "map"
    folder.mkdir()
    _tum(folder / "trajectory.tum", np.arange(10.0))
    relations = _relations(tmp_path / "r.relations", 0.0)
    process = _cli("evaluate", "slam", folder, relations)
    _one_line(process, f"{folder}: is a folder", str(folder / "trajectory.tum"))
    process = _cli("evaluate", "slam", folder / "trajectory.tum", tmp_path)
    _one_line(process, f"{tmp_path}: is a folder")


def _table_row(stdout: str, name: str) -> str:
    """The value cell of the row ``name`` of a rich table in ``stdout``."""
    for line in stdout.splitlines():
        cells = line.split("│")
        if len(cells) > 2 and cells[1].strip() == name:
            return cells[2].strip()
    raise AssertionError(f"no row {name!r} in:\n{stdout}")


@pytest.mark.real
def test_the_initial_pose_is_recorded_and_its_rejection_said(
    fr079: tuple[Path, Path], tmp_path: Path
) -> None:
    npz, map_folder = fr079
    x, y, yaw = read_tum(map_folder / "trajectory.tum")[1][0]
    given = f"{x:.3f},{y:.3f},{yaw:.4f}"
    out = tmp_path / "good"
    result = _invoke("localise", map_folder, npz, "-o", out, "--initial-pose", given)
    assert result.exit_code == 0, result.output
    summary = json.loads((out / "summary.json").read_text())
    initial = summary["initial_pose"]
    assert initial["pose"] == pytest.approx([x, y, yaw], abs=1e-3)
    assert initial["accepted"] is True and initial["rejected_at_scan"] is None, initial
    assert "given" in _table_row(result.stdout, "initial pose"), result.stdout
    assert _table_row(result.stdout, "first fix") != "none", result.stdout
    assert summary["ms_per_scan_max"] >= summary["ms_per_scan_p95"], summary
    far = f"{x + 25:.3f},{y - 25:.3f},{yaw + 1.5:.4f}"
    out = tmp_path / "far"
    result = _invoke("localise", map_folder, npz, "-o", out, "--initial-pose", far)
    assert result.exit_code == 0, result.output
    summary = json.loads((out / "summary.json").read_text())
    initial = summary["initial_pose"]
    assert initial["accepted"] is False and initial["rejected_at_scan"] >= 0, initial
    assert "rejected" in _table_row(result.stdout, "initial pose"), result.stdout
    assert any("initial pose" in w and "rejected" in w for w in _warning_lines(result.stderr))


@pytest.mark.real
def test_a_recording_of_another_building_stops_saying_it_never_found_itself(
    fr079: tuple[Path, Path], tmp_path: Path
) -> None:
    """aces.bag in a map of fr079: no fix is right; after give_up_travel metres of odometry
    without one, the run stops: one line, exit 2 (it ran to the end of the recording, minutes,
    and exited 0 with an empty trajectory)."""
    _, map_folder = fr079
    bag = real_file("aces.bag")
    out = tmp_path / "out"
    result = _invoke("localise", map_folder, bag, "-o", out, "--set", "give_up_travel=10")
    assert result.exit_code == 2, result.output
    lines = result.stderr.strip().splitlines()
    assert "Traceback" not in result.stderr
    assert lines[-1].startswith("laser-corners: error: ") and "never found itself" in lines[-1]
    assert "10 m" in lines[-1] and "give_up_travel" in lines[-1], lines


def test_parameter_errors_do_not_name_internal_classes(tmp_path: Path) -> None:
    """``--preset``/``--set`` mistakes name the option's key, not ``ParamsChoice``."""
    from laser_corners import LaserScan

    npz = tmp_path / "s.npz"
    write_scans_npz(npz, [LaserScan(np.full(50, 2.0), -1.0, 0.04, stamp=1.0)])
    for args, needle in (
        (["--preset", "nonsense"], "preset: unknown preset 'nonsense'"),
        (["--set", "min_points=-1"], "min_points: must be in"),
        (["--set", "nosuch=1"], "unknown parameter 'nosuch'"),
    ):
        result = _invoke("detect", npz, "-o", tmp_path / "k.csv", *args)
        assert result.exit_code == 2, result.output
        line = result.stderr.strip().splitlines()[-1]
        assert needle in line and "ParamsChoice" not in line, line
        assert line.startswith(f"laser-corners: error: {needle[:6]}"), line


def test_info_keeps_each_stamp_on_one_line(tmp_path: Path) -> None:
    """Three LaserScan topics with epoch stamps at 80 columns: every first stamp whole on the
    "first stamp" line (the column folded it over two lines)."""
    from rosbags.rosbag1 import Writer
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS1_NOETIC)
    types = store.types
    bag = tmp_path / "three.bag"
    stamp = 1_700_000_000
    with Writer(bag) as writer:
        for k in range(3):
            name = f"/a_rather_long_scan_topic_name_{k}"
            connection = writer.add_connection(name, "sensor_msgs/msg/LaserScan", typestore=store)
            time = types["builtin_interfaces/msg/Time"](sec=stamp + k, nanosec=123456000)
            msg = types["sensor_msgs/msg/LaserScan"](
                header=types["std_msgs/msg/Header"](seq=0, stamp=time, frame_id="laser"),
                angle_min=-1.5,
                angle_max=1.5,
                angle_increment=0.01,
                time_increment=0.0,
                scan_time=0.0,
                range_min=0.1,
                range_max=30.0,
                ranges=np.full(301, 2.0, np.float32),
                intensities=np.zeros(0, np.float32),
            )
            raw = store.serialize_ros1(msg, connection.msgtype)
            writer.write(connection, (stamp + k) * 10**9, raw)
    result = runner.invoke(app, ["info", str(bag)], terminal_width=80)
    assert result.exit_code == 0, result.output
    row = next(line for line in result.stdout.splitlines() if "first stamp" in line)
    for k in range(3):
        assert f"{stamp + k}.123456" in row, result.stdout


@pytest.mark.real
def test_slam_takes_mount_as_localise_does(fr079: tuple[Path, Path], tmp_path: Path) -> None:
    """``slam --mount X,Y,YAW``: the same option, the same help as ``localise``'s, recorded in
    summary.json; a non-finite one is one line naming it."""
    npz, _ = fr079
    helps = {}
    for command in ("slam", "localise"):
        result = runner.invoke(app, [command, "--help"], terminal_width=200)
        line = next(
            line
            for line in result.stdout.splitlines()
            if line.replace("│", " ").split()[:1] == ["--mount"]  # the option, not a mention
        )
        helps[command] = " ".join(line.replace("│", " ").split())
    assert helps["slam"] == helps["localise"], helps
    out = tmp_path / "out"
    result = _invoke("slam", npz, "-o", out, "--stop-scan", 40, "--mount", "0.1,0,0.05")
    assert result.exit_code == 0, result.output
    assert json.loads((out / "summary.json").read_text())["mount"] == [0.1, 0.0, 0.05]
    _one_line(_cli("slam", npz, "-o", tmp_path / "o2", "--mount", "nan,0,0"), "--mount")
    assert not (tmp_path / "o2").exists()


@pytest.mark.real
def test_slam_with_relations_of_another_recording_warns(
    fr079: tuple[Path, Path], tmp_path: Path
) -> None:
    """``slam --relations`` of another log: the map is written (exit 0) and one warning line
    says that no relation is covered (it printed 0 / N and nothing else)."""
    npz, _ = fr079
    relations = _relations(tmp_path / "r.relations", 5000.0)
    out = tmp_path / "out"
    result = _invoke("slam", npz, "-o", out, "--stop-scan", 40, "--relations", relations)
    assert result.exit_code == 0, result.output
    warnings = _warning_lines(result.stderr)
    assert len(warnings) == 1 and "no relation covered" in warnings[0], result.stderr
    assert str(relations) in warnings[0]
    summary = json.loads((out / "summary.json").read_text())
    assert any("no relation covered" in w for w in summary["warnings"]), summary["warnings"]
