"""``laser-corners slam`` and ``evaluate slam`` on small simulated recordings with odometry."""

from __future__ import annotations

import csv
import json
import math
import os
import signal
import subprocess
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import yaml
from typer.testing import CliRunner

import laser_corners
import laser_corners.slam
from conftest import default_sigint, die_with_parent, real_file
from fake_slam import fake_result
from laser_corners.cli import app
from laser_corners.io.trajectory import read_tum, write_tum
from laser_corners.registration.mapfolder import load_map
from laser_corners.scan import LaserScan, relative_pose
from laser_corners.sim import UST_10LX, World, rectangular_room, trajectory
from laser_corners.sim.export import simulate_sequence, write_bag
from laser_corners.slam import Slam

runner = CliRunner()
CLI = [str(Path(sys.executable).with_name("laser-corners"))]
FILES = [
    "graph.g2o",
    "keyframes.npz",
    "landmarks.csv",
    "map.pgm",
    "map.png",
    "map.yaml",
    "odometry.tum",
    "options.yaml",
    "report.md",
    "summary.json",
    "trajectory.tum",
]


def _invoke(*args: str | Path):
    return runner.invoke(app, [str(a) for a in args])


def _one_line_error(result, *needles: str) -> None:
    assert result.exit_code == 2, result.output
    assert "Traceback" not in result.stderr
    lines = result.stderr.strip().splitlines()
    errors = [line for line in lines if line.startswith("laser-corners: error: ")]
    assert len(errors) == 1 and errors[0] == lines[-1], result.stderr
    for needle in needles:
        assert needle in errors[0], errors[0]


def _sim_bag(folder: Path, n_scans: int = 240) -> tuple[Path, Path, np.ndarray]:
    """A ROS 1 bag of a drive through a room, /odom drifting from the truth (yaw 0.05 deg and
    5 mm per scan), and the relations of the true poses one second apart."""
    rng = np.random.default_rng(11)
    world = rectangular_room()
    truth = trajectory(world, n_scans, rng, rate_hz=UST_10LX.rate_hz, speed=0.5)
    sequence = simulate_sequence(world, UST_10LX, truth, 0.005, rng, start_time=100.0)
    odometry = truth.copy()
    odometry[:, 2] += np.cumsum(np.full(n_scans, math.radians(0.05)))
    odometry[:, 0] += 0.005 * np.arange(n_scans)
    bag = folder / "sim.bag"
    write_bag(replace(sequence, poses=odometry), bag)
    stamps = sequence.stamps
    step = int(UST_10LX.rate_hz)
    lines = []
    for i in range(0, n_scans - step, step // 4):
        r = relative_pose(tuple(truth[i]), tuple(truth[i + step]))
        lines.append(
            f"{stamps[i]:.6f} {stamps[i + step]:.6f} {r[0]:.6f} {r[1]:.6f} 0 0 0 {r[2]:.6f}\n"
        )
    relations = folder / "sim.relations"
    relations.write_text("".join(lines))
    return bag, relations, stamps


def test_slam_writes_every_file_with_one_pose_per_scan(tmp_path: Path) -> None:
    bag, relations, stamps = _sim_bag(tmp_path)
    out = tmp_path / "out"
    result = _invoke("slam", bag, "-o", out, "--relations", relations)
    assert result.exit_code == 0, result.output
    assert sorted(p.name for p in out.iterdir()) == FILES, _warnings(out)
    got_stamps, _ = read_tum(out / "trajectory.tum")
    np.testing.assert_allclose(got_stamps, stamps, atol=1e-6)
    summary = json.loads((out / "summary.json").read_text())
    assert summary["counts"]["scans"] == len(stamps) and summary["interrupted"] is False
    n_relations = len(relations.read_text().splitlines())
    ours, odometry = summary["relations"]["trajectory"], summary["relations"]["odometry"]
    assert ours["n_total"] == n_relations and ours["n_covered"] >= n_relations - 1
    assert ours["trans_mean"] <= odometry["trans_mean"]
    with (out / "landmarks.csv").open() as handle:
        assert next(csv.reader(handle))[:3] == ["x", "y", "cov_xx"]
    assert "relation metric" in result.stdout and "trajectory" in result.stdout
    # the options written beside the result repeat the run
    again = _invoke(
        "slam",
        bag,
        "-o",
        tmp_path / "again",
        "--config",
        out / "options.yaml",
        "--stop-scan",
        "20",
        "--resolution",
        "0.1",
    )
    assert again.exit_code == 0, again.output
    assert (tmp_path / "again" / "options.yaml").read_text() == (out / "options.yaml").read_text()
    assert yaml.safe_load((tmp_path / "again" / "map.yaml").read_text())["resolution"] == 0.1
    assert len(read_tum(tmp_path / "again" / "trajectory.tum")[0]) < len(stamps)


def test_ctrl_c_writes_what_was_mapped_and_exits_130(tmp_path: Path, monkeypatch) -> None:
    bag, _, _ = _sim_bag(tmp_path, n_scans=20)
    partial = fake_result(n_scans=40, interrupted=True)

    def interrupted_run(path, options=None, *, progress=None, **kwargs):
        for i in range(40):
            progress(i, 100, float(partial.stamps[i]))
        return partial  # what run_slam returns when Ctrl-C stops it

    monkeypatch.setattr(laser_corners.slam, "run_slam", interrupted_run)
    out = tmp_path / "out"
    result = _invoke("slam", bag, "-o", out)
    assert result.exit_code == 130, result.output
    assert "interrupted after 40 scans" in result.stderr and str(out) in result.stderr
    assert sorted(p.name for p in out.iterdir()) == FILES
    assert len(read_tum(out / "trajectory.tum")[0]) == 40
    assert json.loads((out / "summary.json").read_text())["interrupted"] is True


@pytest.mark.real
@pytest.mark.slow
def test_sigint_during_a_real_run_keeps_the_map(tmp_path: Path) -> None:
    # intel.bag holds 2691 s of data: 8 s after the output folder appears (it is created just
    # before the run starts) the run is under way and far from its end
    bag = real_file("intel.bag")
    out = tmp_path / "intel"
    process = subprocess.Popen(
        [*CLI, "slam", str(bag), "-o", str(out)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        preexec_fn=default_sigint,
    )
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline and process.poll() is None and not out.exists():
        time.sleep(0.05)
    time.sleep(8.0)
    assert process.poll() is None, "the run ended before it could be interrupted"
    process.send_signal(signal.SIGINT)
    _, stderr = process.communicate(timeout=120)
    assert process.returncode == 130, stderr
    assert "interrupted after" in stderr and "holds the map up to there" in stderr, stderr
    assert sorted(p.name for p in out.iterdir()) == FILES, _warnings(out)
    summary = json.loads((out / "summary.json").read_text())
    n_scans = summary["counts"]["scans"]
    assert summary["interrupted"] is True and 0 < n_scans
    assert len(read_tum(out / "trajectory.tum")[0]) == n_scans


def _warnings(folder: Path) -> list[str]:
    """The warnings the run recorded (why a file is missing)."""
    summary = folder / "summary.json"
    return json.loads(summary.read_text())["warnings"] if summary.exists() else []


def _line(folder: Path, speed: float) -> Path:
    """A TUM trajectory driving along x at ``speed`` m/s for 10 s (101 poses)."""
    t = np.linspace(0.0, 10.0, 101)
    path = folder / f"v{speed}.tum"
    write_tum(path, t, np.column_stack([speed * t, np.zeros_like(t), np.zeros_like(t)]))
    return path


def test_evaluate_slam_gives_the_known_error(tmp_path: Path) -> None:
    relations = tmp_path / "line.relations"
    # 0.6 m and 0.02 rad per second; one relation outside the trajectory's time span
    rows = [f"{t:.1f} {t + 1:.1f} 0.6 0 0 0 0 0.02" for t in range(9)] + ["50 51 0.6 0 0 0 0 0"]
    relations.write_text("\n".join(rows) + "\n")
    result = _invoke(
        "evaluate", "slam", _line(tmp_path, 0.5), relations, "--odometry", _line(tmp_path, 0.6)
    )
    assert result.exit_code == 0, result.output
    rows = {line.split("│")[1].strip(): line for line in result.stdout.splitlines() if "│" in line}
    assert "trajectory (v0.5.tum)" in result.stdout and "odometry (v0.6.tum)" in result.stdout
    assert "9 / 10" in rows["covered / total"]
    trajectory, odometry = rows["|t| (m)"].split("│")[2:4]
    assert trajectory.strip() == "0.1000 ± 0.0000" and odometry.strip() == "0.0000 ± 0.0000"
    assert rows["|θ| (deg)"].split("│")[2].strip() == f"{math.degrees(0.02):.3f} ± 0.000"


def test_bad_relations_file_is_one_line_naming_file_and_line(tmp_path: Path) -> None:
    relations = tmp_path / "bad.relations"
    relations.write_text("0 1 0.6 0 0 0 0 0\n1 2 0.6 0 0 0 0 0\n1 2 x 0 0 0 0 0\n")
    result = _invoke("evaluate", "slam", _line(tmp_path, 0.5), relations)
    _one_line_error(result, f"{relations}:3")
    out = tmp_path / "out"
    result = _invoke("slam", _line(tmp_path, 0.5), "-o", out, "--relations", relations)
    _one_line_error(result, f"{relations}:3")
    assert not out.exists()  # checked before the run


def test_bad_inputs_are_one_line(tmp_path: Path) -> None:
    _one_line_error(_invoke("slam", tmp_path / "none.bag", "-o", tmp_path / "o"), "none.bag")
    _one_line_error(
        _invoke("evaluate", "slam", tmp_path / "none.tum", tmp_path / "none.tum"), "none.tum"
    )
    bag, _, _ = _sim_bag(tmp_path, n_scans=10)
    _one_line_error(_invoke("slam", bag, "-o", tmp_path / "o", "--resolution", "0"), "--resolution")
    _one_line_error(
        _invoke("slam", bag, "-o", tmp_path / "o", "--set", "no_such_option=1"), "no_such_option"
    )
    config = tmp_path / "bad.yaml"
    config.write_text("no_such_field: 1\n")
    _one_line_error(_invoke("slam", bag, "-o", tmp_path / "o", "--config", config), "no_such_field")
    config.write_text("a: [1\n")
    _one_line_error(_invoke("slam", bag, "-o", tmp_path / "o", "--config", config), "bad.yaml")


def test_the_loop_group_by_set_and_config_reaches_the_map_folder(tmp_path: Path) -> None:
    """``--set loop.radius=5`` and a ``--config`` ``loop:`` table are recorded in the map
    folder's ``options.yaml``; the old flat names and a bad value are one line."""
    bag, _, _ = _sim_bag(tmp_path, n_scans=20)
    config = tmp_path / "slam.yaml"
    config.write_text("loop:\n  every: 3\n")
    out = tmp_path / "out"
    args = ("--config", config, "--set", "loop.radius=5", "--set", "inlier_distance=0.12")
    result = _invoke("slam", bag, "-o", out, *args)
    assert result.exit_code == 0, result.output
    recorded = yaml.safe_load((out / "options.yaml").read_text())
    assert recorded["loop"]["radius"] == 5.0 and recorded["loop"]["every"] == 3
    assert recorded["inlier_distance"] == 0.12 and "loop_radius" not in recorded
    bad = tmp_path / "bad"
    _one_line_error(_invoke("slam", bag, "-o", bad, "--set", "loop_radius=5"), "loop_radius")
    _one_line_error(_invoke("slam", bag, "-o", bad, "--set", "loop.radius=-1"), "loop", "radius")
    assert not bad.exists()


def _carmen(path: Path, laser: bool, odometry: bool) -> Path:
    ranges = " ".join(["2.0"] * 181)
    lines = []
    for i in range(30):
        t = 10.0 + 0.1 * i
        if odometry:
            lines.append(f"ODOM {0.01 * i} 0 0 0 0 0 {t:.3f} host {t:.3f}")
        if laser:
            lines.append(
                f"RAWLASER1 0 -1.5708 3.1416 0.01745 80 0.01 0 181 {ranges} 0 "
                f"{t + 0.05:.3f} host {t + 0.05:.3f}"
            )
    path.write_text("\n".join(lines) + "\n")
    return path


def test_recordings_without_odometry_or_scans_are_one_line(tmp_path: Path) -> None:
    no_odometry = _carmen(tmp_path / "no_odom.clf", laser=True, odometry=False)
    _one_line_error(_invoke("slam", no_odometry, "-o", tmp_path / "a"), "no_odom.clf")
    no_scans = _carmen(tmp_path / "no_scans.clf", laser=False, odometry=True)
    _one_line_error(_invoke("slam", no_scans, "-o", tmp_path / "b"), "no_scans.clf")


def test_help_lists_both_commands() -> None:
    assert "slam" in _invoke("--help").stdout
    result = _invoke("evaluate", "--help")
    assert result.exit_code == 0 and "slam" in result.stdout
    assert "--relations" in _invoke("slam", "--help").stdout


def _blank(scan: LaserScan) -> LaserScan:
    """``scan`` with no valid return (every range NaN)."""
    ranges = np.full(scan.ranges.shape, np.nan)
    return LaserScan(
        ranges,
        scan.angle_min,
        scan.angle_increment,
        scan.range_min,
        scan.range_max,
        scan.stamp,
        scan.frame_id,
    )


def _hard_bag(folder: Path, kind: str, n_scans: int = 240) -> Path:
    """A ROS 1 bag of a drive that once broke or misled the mapping: ``jump`` (1 km added to
    the odometry halfway), ``midblank`` (100 scans without returns mid-run), ``startblank``
    (the first 50 scans without returns), ``corridor`` (a 2 m wide, 60 m long corridor, the
    odometry 10 % long)."""
    rng = np.random.default_rng(11)
    if kind == "corridor":
        world = World().add_polygon([[0, 0], [60, 0], [60, 2], [0, 2]])
        x = 20.0 + 0.0125 * np.arange(n_scans)
        truth = np.column_stack([x, np.ones(n_scans), np.zeros(n_scans)])
    else:
        world = rectangular_room()
        truth = trajectory(world, n_scans, rng, rate_hz=UST_10LX.rate_hz, speed=0.5)
    sequence = simulate_sequence(world, UST_10LX, truth, 0.005, rng, start_time=100.0)
    odometry = truth.copy()
    odometry[:, 2] += np.cumsum(np.full(n_scans, math.radians(0.05)))
    scans = list(sequence.scans)
    if kind == "jump":
        odometry[n_scans // 2 :, 0] += 1000.0
    elif kind == "midblank":
        scans[70:170] = [_blank(s) for s in scans[70:170]]
    elif kind == "startblank":
        scans[:50] = [_blank(s) for s in scans[:50]]
    elif kind == "corridor":
        odometry[:, 0] = x[0] + 1.1 * (x - x[0])
    bag = folder / f"{kind}.bag"
    write_bag(replace(sequence, poses=odometry, scans=scans), bag)
    return bag


@pytest.mark.parametrize(
    ("kind", "warning"),
    [
        ("jump", "re-anchored"),  # before: gtsam's "Indeterminate linear system", no output
        ("midblank", "100 scans without any valid return"),
        ("startblank", "50 scans without any valid return"),
        ("corridor", "walls of one direction only"),
    ],
)
def test_hard_drives_finish_with_a_usable_map_and_a_warning(tmp_path, kind, warning) -> None:
    out = tmp_path / "map"
    result = _invoke("slam", _hard_bag(tmp_path, kind), "-o", out)
    assert result.exit_code == 0, result.output
    summary = json.loads((out / "summary.json").read_text())
    assert summary["partial"] is False and summary["counts"]["scans"] == 240
    assert any(warning in w for w in summary["warnings"]), summary["warnings"]
    assert f"laser-corners: warning: {summary['warnings'][0]}" in result.stderr
    saved = load_map(out)
    assert len(saved) == summary["counts"]["keyframes"] > 1 and saved.partial_reason is None


def test_an_error_while_mapping_writes_a_partial_map(tmp_path: Path, monkeypatch) -> None:
    bag, _, _ = _sim_bag(tmp_path, n_scans=60)
    add = Slam.add

    def breaks_at_40(self, scan, odometry, stamp):
        if self.counts.scans == 40:
            raise RuntimeError("a bug\nsecond line")
        return add(self, scan, odometry, stamp)

    monkeypatch.setattr(Slam, "add", breaks_at_40)
    out = tmp_path / "out"
    result = _invoke("slam", bag, "-o", out)
    assert result.exit_code == 1, result.output
    assert "Traceback" not in result.stderr
    error = result.stderr.strip().splitlines()[-1]
    assert error.startswith("laser-corners: error: mapping stopped by RuntimeError at scan 40")
    summary = json.loads((out / "summary.json").read_text())
    assert summary["partial"] is True and summary["interrupted"] is True
    assert summary["partial_reason"] == "RuntimeError at scan 40: a bug"
    assert summary["counts"]["scans"] == 40 and len(read_tum(out / "trajectory.tum")[0]) == 40
    assert load_map(out).partial_reason == "RuntimeError at scan 40: a bug"


def test_sigterm_mid_run_writes_a_partial_map_and_exits_143(tmp_path: Path) -> None:
    bag, _, _ = _sim_bag(tmp_path, n_scans=240)
    out = tmp_path / "out"
    script = (  # the real command, each scan slowed so the signal comes mid-run
        "import sys, time\n"
        "from laser_corners.slam import Slam\n"
        "add = Slam.add\n"
        "def slow(self, *args):\n"
        "    if self.counts.scans == 30:\n"
        "        print('mapping', flush=True)\n"
        "    time.sleep(0.05)\n"
        "    return add(self, *args)\n"
        "Slam.add = slow\n"
        "from laser_corners.cli import main\n"
        "sys.argv = ['laser-corners', 'slam', *sys.argv[1:]]\n"
        "main()\n"
    )
    env = {**os.environ, "PYTHONPATH": str(Path(laser_corners.__file__).parents[1])}
    process = subprocess.Popen(
        [sys.executable, "-c", script, str(bag), "-o", str(out)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=env,
        preexec_fn=die_with_parent(),
    )
    try:
        assert process.stdout is not None
        assert process.stdout.readline().strip() == "mapping"
        process.send_signal(signal.SIGTERM)
        _, stderr = process.communicate(timeout=120)
    finally:
        if process.poll() is None:
            process.kill()
            process.wait(timeout=30)
    assert process.returncode == 143, stderr
    assert "terminated after" in stderr and "holds the map up to there" in stderr, stderr
    summary = json.loads((out / "summary.json").read_text())
    assert summary["partial"] is True and summary["partial_reason"] == "terminated (SIGTERM)"
    assert 30 <= summary["counts"]["scans"] < 240
    assert len(load_map(out)) == summary["counts"]["keyframes"]


def test_outputs_are_checked_before_mapping(tmp_path: Path, monkeypatch) -> None:
    bag, _, _ = _sim_bag(tmp_path, n_scans=20)
    out = tmp_path / "out"
    assert _invoke("slam", bag, "-o", out).exit_code == 0
    before = {p.name: p.read_bytes() for p in out.iterdir()}

    def no_mapping(*args, **kwargs):
        raise AssertionError("the mapping started")

    monkeypatch.setattr(laser_corners.slam, "run_slam", no_mapping)
    _one_line_error(_invoke("slam", bag, "-o", ""), "--output needs a folder name")
    _one_line_error(_invoke("slam", bag, "-o", out, "--resolution", "0.001"), "--resolution")
    _one_line_error(_invoke("slam", bag, "-o", tmp_path), "would write over the input")
    _one_line_error(_invoke("slam", out / "trajectory.tum", "-o", out), "over the input")
    out.chmod(0o555)
    try:
        _one_line_error(_invoke("slam", bag, "-o", out), "cannot write into the folder")
    finally:
        out.chmod(0o755)
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before
    (tmp_path / "mine").mkdir()
    (tmp_path / "mine" / "notes.txt").write_text("mine\n")
    _one_line_error(_invoke("slam", bag, "-o", tmp_path / "mine"), "not a slam result")
    assert sorted(p.name for p in (tmp_path / "mine").iterdir()) == ["notes.txt"]
