"""``laser-corners localise`` end to end on a simulated bag mapped by ``laser-corners slam``."""

from __future__ import annotations

import json
import math
import shutil
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from laser_corners.cli import app
from laser_corners.io.trajectory import read_tum
from laser_corners.sim import UST_10LX, rectangular_room, trajectory
from laser_corners.sim.export import simulate_sequence, write_bag

runner = CliRunner()


def _invoke(*args: str | Path):
    return runner.invoke(app, [str(a) for a in args])


def _one_line_error(result, *needles: str) -> None:
    assert result.exit_code == 2, result.output
    lines = result.stderr.strip().splitlines()
    assert "Traceback" not in result.stderr
    assert len(lines) == 1 and lines[0].startswith("laser-corners: error: "), result.stderr
    for needle in needles:
        assert needle in lines[0], lines[0]


@pytest.fixture(scope="module")
def mapped(tmp_path_factory) -> tuple[Path, Path, np.ndarray, np.ndarray]:
    """A bag of a drive through a room (odometry drifting) and the map ``slam`` made of it."""
    folder = tmp_path_factory.mktemp("cli")
    rng = np.random.default_rng(11)
    world = rectangular_room()
    n = 480
    truth = trajectory(world, n, rng, rate_hz=UST_10LX.rate_hz, speed=0.5)
    sequence = simulate_sequence(world, UST_10LX, truth, 0.005, rng, start_time=100.0)
    odometry = truth.copy()
    odometry[:, 2] += np.cumsum(np.full(n, math.radians(0.02)))
    bag = folder / "sim.bag"
    write_bag(replace(sequence, poses=odometry), bag)
    result = _invoke("slam", bag, "-o", folder / "map")
    assert result.exit_code == 0, result.output
    assert (folder / "map" / "keyframes.npz").is_file()
    return bag, folder / "map", sequence.stamps, truth


def test_localise_writes_trajectory_summary_and_plot(mapped, tmp_path: Path) -> None:
    bag, map_dir, stamps, _truth = mapped
    out = tmp_path / "out"
    result = _invoke("localise", map_dir, bag, "-o", out)
    assert result.exit_code == 0, result.output
    assert sorted(p.name for p in out.iterdir()) == [
        "online.tum",
        "summary.json",
        "trajectory.png",
        "trajectory.tum",
    ]
    summary = json.loads((out / "summary.json").read_text())
    fix = summary["first_fix"]
    assert fix is not None, summary
    online_t, online_p = read_tum(out / "online.tum")
    assert online_t[0] == pytest.approx(fix["stamp"]) and online_t[0] >= stamps[0]
    estimates = summary["counts"]["estimates"]
    assert len(online_t) == estimates >= 0.8 * (len(stamps) - fix["scan_index"])
    # local estimates (into unmapped space) are written too, and counted
    assert 0 <= summary["counts"]["local"] <= estimates
    # smoothed: every scan, those before the first fix too
    got_t, got_p = read_tum(out / "trajectory.tum")
    assert np.allclose(got_t, stamps) and summary["smoothed"]["scans"] == len(stamps)
    assert summary["smoothed"]["anchors"] > 0 and summary["smoothed"]["slam_ms_per_scan_mean"] > 0
    # the map's own trajectory is the reference: same frame
    map_t, map_p = read_tum(map_dir / "trajectory.tum")
    for t, p in ((online_t, online_p), (got_t, got_p)):
        ref = map_p[np.searchsorted(map_t, t)]
        assert np.max(np.hypot(*(p[:, :2] - ref[:, :2]).T)) < 0.15
    assert summary["ms_per_scan_mean"] > 0 and summary["lost"] == 0
    assert "first fix" in result.stdout


def test_initial_pose_and_start_scan(mapped, tmp_path: Path) -> None:
    bag, map_dir, stamps, _ = mapped
    _, map_p = read_tum(map_dir / "trajectory.tum")
    start = 200
    pose = ",".join(f"{v:.6f}" for v in map_p[start])
    out = tmp_path / "o"
    result = _invoke(
        "localise", map_dir, bag, "-o", out, "--initial-pose", pose, "--start-scan", start
    )
    assert result.exit_code == 0, result.output
    for name in ("online.tum", "trajectory.tum"):
        got_t, got_p = read_tum(out / name)
        assert got_t[0] == pytest.approx(stamps[start])  # tracking from the first scan used
        assert np.hypot(*(got_p[-1, :2] - map_p[-1, :2])) < 0.1
    # no initial pose: the fix's scan index is the recording's
    result = _invoke("localise", map_dir, bag, "-o", tmp_path / "g", "--start-scan", start)
    assert result.exit_code == 0, result.output
    fix = json.loads((tmp_path / "g" / "summary.json").read_text())["first_fix"]
    assert fix["scan_index"] > start and fix["stamp"] == pytest.approx(stamps[fix["scan_index"]])


def test_bad_inputs_are_one_line(mapped, tmp_path: Path) -> None:
    bag, map_dir, _, _ = mapped
    _one_line_error(
        _invoke("localise", tmp_path / "nomap", bag, "-o", tmp_path / "a"), "no such map folder"
    )
    (tmp_path / "half").mkdir()
    _one_line_error(
        _invoke("localise", tmp_path / "half", bag, "-o", tmp_path / "b"), "keyframes.npz missing"
    )
    _one_line_error(
        _invoke("localise", map_dir, bag, "-o", tmp_path / "c", "--initial-pose", "1,2"),
        "--initial-pose",
    )
    _one_line_error(
        _invoke("localise", map_dir, bag, "-o", tmp_path / "d", "--set", "fix_margin=2"),
        "fix_margin",
    )
    ranges = " ".join(["2.0"] * 181)
    lines = [
        f"RAWLASER1 0 -1.5708 3.1416 0.01745 80 0.01 0 181 {ranges} 0 {t:.3f} host {t:.3f}"
        for t in 10.0 + 0.1 * np.arange(20)
    ]
    log = tmp_path / "no_odom.clf"
    log.write_text("\n".join(lines) + "\n")
    _one_line_error(_invoke("localise", map_dir, log, "-o", tmp_path / "e"), "no_odom.clf")


def test_ctrl_c_keeps_the_poses_written_and_exits_130(mapped, tmp_path: Path, monkeypatch) -> None:
    import laser_corners.localise
    from laser_corners.localise import LocaliserEstimate, LocaliseRun

    def interrupted(map_data, path, options=None, *, on_estimate=None, **kwargs):
        estimate = LocaliserEstimate(
            np.array([1.0, 2.0, 0.5]), np.eye(3) * 1e-4, "relocalised", np.zeros(3), 0, 100.0
        )
        on_estimate(estimate)
        return LocaliseRun(
            [estimate], [], {"scans": 1, "estimates": 1}, np.ones(1), interrupted=True
        )

    monkeypatch.setattr(laser_corners.localise, "run_localise", interrupted)
    bag, map_dir, _, _ = mapped
    out = tmp_path / "out"
    result = _invoke("localise", map_dir, bag, "-o", out)
    assert result.exit_code == 130, result.output
    for name in ("online.tum", "trajectory.tum"):  # no smoothing in this run: the estimates
        stamps, poses = read_tum(out / name)
        assert stamps.tolist() == [100.0] and np.allclose(poses, [[1.0, 2.0, 0.5]])
    assert json.loads((out / "summary.json").read_text())["interrupted"] is True


def test_smooth_enabled_false_writes_the_online_estimates(mapped, tmp_path: Path) -> None:
    bag, map_dir, _, _ = mapped
    out = tmp_path / "o"
    result = _invoke("localise", map_dir, bag, "-o", out, "--set", "smooth.enabled=false")
    assert result.exit_code == 0, result.output
    online, smoothed = read_tum(out / "online.tum"), read_tum(out / "trajectory.tum")
    assert np.array_equal(online[0], smoothed[0]) and np.allclose(online[1], smoothed[1])
    assert json.loads((out / "summary.json").read_text())["smoothed"] is None


def test_the_old_smooth_names_are_one_line_before_any_work(mapped, tmp_path: Path) -> None:
    """``--set smooth=false`` (the name before the ``smooth`` group) and ``smooth_drift``:
    one line naming the new names, no output folder."""
    bag, map_dir, _, _ = mapped
    out = tmp_path / "o"
    result = _invoke("localise", map_dir, bag, "-o", out, "--set", "smooth=false")
    _one_line_error(result, "smooth.enabled")
    result = _invoke("localise", map_dir, bag, "-o", out, "--set", "smooth_drift=0.02")
    _one_line_error(result, "smooth_drift", "smooth.drift")
    assert not out.exists()


def test_ctrl_c_while_smoothing_keeps_the_online_estimates(mapped, tmp_path, monkeypatch) -> None:
    import laser_corners.localise.run as run_module

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(run_module, "smooth", interrupted)
    bag, map_dir, _, _ = mapped
    out = tmp_path / "out"
    result = _invoke("localise", map_dir, bag, "-o", out, "--start-scan", 300)
    assert result.exit_code == 130, result.output
    assert "interrupted" in result.stderr
    online, written = read_tum(out / "online.tum"), read_tum(out / "trajectory.tum")
    assert len(online[0]) > 0 and np.array_equal(online[0], written[0])
    summary = json.loads((out / "summary.json").read_text())
    assert summary["interrupted"] is True and summary["smoothed"] is None


def test_thesmoothing_slam_takes_the_map_options(mapped, tmp_path: Path) -> None:
    """The SLAM of the smoothed trajectory runs with the map's ``options.yaml`` (and the
    localiser's mount); a bad one is one line naming it, unless smoothing is off."""
    import shutil

    from laser_corners.localise.run import smoothing_slam
    from laser_corners.registration.mapfolder import load_map

    bag, map_dir, _, _ = mapped
    copy = tmp_path / "map"
    shutil.copytree(map_dir, copy)
    options = copy / "options.yaml"
    text = options.read_text().replace("loop:\n  enabled: true", "loop:\n  enabled: false")
    options.write_text(text)
    slam = smoothing_slam(load_map(copy), np.array([0.1, 0.0, 0.0]))
    assert slam.options.loop.enabled is False and slam.options.mount == (0.1, 0.0, 0.0)
    options.write_text("max_range: -3\n")
    _one_line_error(_invoke("localise", copy, bag, "-o", tmp_path / "a"), "options.yaml")
    result = _invoke("localise", copy, bag, "-o", tmp_path / "b", "--set", "smooth.enabled=false")
    assert result.exit_code == 0, result.output


def _no_run(*args, **kwargs):
    raise AssertionError("the localisation started")


def test_outputs_over_the_map_or_the_recording_are_refused_before_any_work(
    mapped, tmp_path: Path, monkeypatch
) -> None:
    import laser_corners.localise

    bag, map_dir, _, _ = mapped
    before = {p.name: p.read_bytes() for p in map_dir.iterdir()}
    monkeypatch.setattr(laser_corners.localise, "run_localise", _no_run)
    _one_line_error(_invoke("localise", map_dir, bag, "-o", map_dir), "over the input")
    _one_line_error(_invoke("localise", map_dir, bag, "-o", map_dir / "loc"), "over the input")
    _one_line_error(_invoke("localise", map_dir, bag, "-o", bag.parent), "over the input")
    alone = tmp_path / "rec"  # the folder that holds the recording (and not the map)
    alone.mkdir()
    shutil.copy(bag, alone / bag.name)
    result = _invoke("localise", map_dir, alone / bag.name, "-o", alone)
    _one_line_error(result, f"over the input {alone / bag.name}")
    _one_line_error(_invoke("localise", map_dir, bag, "-o", ""), "needs a folder name")
    assert {p.name: p.read_bytes() for p in map_dir.iterdir()} == before


def test_a_failed_localise_keeps_the_previous_online_tum(
    mapped, tmp_path: Path, monkeypatch
) -> None:
    import laser_corners.localise
    from laser_corners.errors import InputError
    from laser_corners.localise import LocaliserEstimate

    bag, map_dir, _, _ = mapped
    out = tmp_path / "out"
    first = _invoke(
        "localise", map_dir, bag, "-o", out, "--stop-scan", 80, "--set", "smooth.enabled=false"
    )
    assert first.exit_code == 0, first.output
    before = (out / "online.tum").read_bytes()

    def fails(map_data, path, options=None, *, on_estimate=None, **kwargs):
        estimate = LocaliserEstimate(
            np.array([1.0, 2.0, 0.5]), np.eye(3) * 1e-4, "tracking", np.zeros(3), 0, 100.0
        )
        on_estimate(estimate)
        raise InputError(f"{path}: truncated at message 12")

    monkeypatch.setattr(laser_corners.localise, "run_localise", fails)
    _one_line_error(_invoke("localise", map_dir, bag, "-o", out), "truncated at message 12")
    assert (out / "online.tum").read_bytes() == before
    assert not [p for p in out.iterdir() if "partial" in p.name]
    # an error before the first estimate in a new folder: no header-only online.tum
    monkeypatch.setattr(laser_corners.localise, "run_localise", _no_run_input_error)
    _one_line_error(_invoke("localise", map_dir, bag, "-o", tmp_path / "new"), "no odometry")
    assert not (tmp_path / "new").exists()


def _no_run_input_error(map_data, path, *args, **kwargs):
    from laser_corners.errors import InputError

    raise InputError(f"{path}: no odometry")


def test_an_error_while_localising_writes_a_partial_result(
    mapped, tmp_path: Path, monkeypatch
) -> None:
    from laser_corners.localise.localiser import Localiser

    bag, map_dir, _, _ = mapped
    add = Localiser.add

    def breaks_at_300(self, scan, odometry, stamp):
        if self.counts["scans"] == 300:
            raise RuntimeError("a bug")
        return add(self, scan, odometry, stamp)

    monkeypatch.setattr(Localiser, "add", breaks_at_300)
    out = tmp_path / "out"
    result = _invoke("localise", map_dir, bag, "-o", out)
    assert result.exit_code == 1, result.output
    assert "Traceback" not in result.stderr
    assert (
        result.stderr.strip()
        .splitlines()[-1]
        .startswith("laser-corners: error: localisation stopped by RuntimeError at scan 300: a bug")
    )
    summary = json.loads((out / "summary.json").read_text())
    assert summary["partial"] is True and summary["partial_reason"].startswith("RuntimeError")
    online_t, _ = read_tum(out / "online.tum")
    assert 0 < len(online_t) == summary["counts"]["estimates"] and online_t[-1] < 100.0 + 300 / 40


def test_a_partial_map_is_a_warning(mapped, tmp_path: Path) -> None:
    bag, map_dir, _, _ = mapped
    copy = tmp_path / "map"
    shutil.copytree(map_dir, copy)
    summary = json.loads((copy / "summary.json").read_text())
    summary.update(partial=True, partial_reason="terminated (SIGTERM)")
    (copy / "summary.json").write_text(json.dumps(summary))
    out = tmp_path / "out"
    result = _invoke(
        "localise", copy, bag, "-o", out, "--stop-scan", 40, "--set", "smooth.enabled=false"
    )
    assert result.exit_code == 0, result.output
    assert f"warning: {copy} is a partial map (terminated (SIGTERM))" in result.stderr
    assert json.loads((out / "summary.json").read_text())["map_partial_reason"] == (
        "terminated (SIGTERM)"
    )


def test_localise_in_a_map_server_yaml_alone(mapped, tmp_path: Path) -> None:
    """MAP may be a map_server YAML (a map made by another package): here the slam folder's
    map.yaml + map.pgm copied alone, without keyframes.npz (virtual keyframes)."""
    import shutil

    bag, map_dir, _, _ = mapped
    foreign = tmp_path / "foreign"
    foreign.mkdir()
    for name in ("map.yaml", "map.pgm"):
        shutil.copy(map_dir / name, foreign / name)
    out = tmp_path / "out"
    result = _invoke(
        "localise", foreign / "map.yaml", bag, "-o", out, "--set", "smooth.enabled=false"
    )
    assert result.exit_code == 0, result.output
    summary = json.loads((out / "summary.json").read_text())
    assert summary["first_fix"] is not None and summary["map"] == str(foreign / "map.yaml")
    online_t, online_p = read_tum(out / "online.tum")
    map_t, map_p = read_tum(map_dir / "trajectory.tum")
    d = np.hypot(*(online_p[:, :2] - map_p[np.searchsorted(map_t, online_t), :2]).T)
    assert len(d) >= 0.8 * len(map_t) - summary["first_fix"]["scan_index"]
    assert np.percentile(d, 95) < 0.15 and d.max() < 0.3
    # a bad YAML is one line naming the file and the field
    (foreign / "map.yaml").write_text(
        (map_dir / "map.yaml").read_text().replace("resolution: 0.05", "resolution: -1")
    )
    _one_line_error(
        _invoke("localise", foreign / "map.yaml", bag, "-o", tmp_path / "bad"),
        "map.yaml: field 'resolution'",
    )
    _one_line_error(
        _invoke("localise", foreign / "map.pgm", bag, "-o", tmp_path / "pgm"),
        "not a map folder nor a map_server .yaml",
    )


def test_help_says_map_may_be_a_yaml() -> None:
    result = _invoke("localise", "--help")
    assert result.exit_code == 0 and "map.yaml" in result.output
