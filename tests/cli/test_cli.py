"""The command line: the "Done when" runs of issue 3, info, plot, errors, Ctrl-C, presets."""

from __future__ import annotations

import csv
import gzip
import math
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq
import pytest
from typer.testing import CliRunner

from conftest import default_sigint, real_file
from laser_corners import CornerDetector, DetectorParams, InvalidParamsError, Keypoints
from laser_corners.cli import app
from laser_corners.io import open_scans
from laser_corners.presets import auto_params, get_preset

runner = CliRunner()
CLI = [str(Path(sys.executable).with_name("laser-corners"))]


def _invoke(*args: str | Path):
    return runner.invoke(app, [str(a) for a in args])


def _one_line_error(result, *needles: str) -> None:
    assert result.exit_code == 2, result.output
    assert "Traceback" not in result.stderr
    lines = result.stderr.strip().splitlines()
    errors = [line for line in lines if line.startswith("laser-corners: error: ")]
    assert len(errors) == 1 and errors[0] == lines[-1], result.stderr  # after a progress bar
    for needle in needles:
        assert needle in errors[0]


def _check_map_columns(x, y, map_x, map_y, poses) -> None:
    for i in np.linspace(0, len(x) - 1, 25).astype(int):
        kp = Keypoints(np.array([[x[i], y[i]]]), [0], [90.0], [0.0], [3], [0.0], [1])
        expected = kp.transformed(poses[i]).xy[0]
        assert (map_x[i], map_y[i]) == pytest.approx(tuple(expected), abs=1e-9)


# ----------------------------------------------------------------------------- Done when
def test_detect_fr079_bag_to_parquet(tmp_path: Path) -> None:
    bag = real_file("fr079.bag")
    out = tmp_path / "fr079.parquet"
    result = _invoke("detect", bag, "-o", out)
    assert result.exit_code == 0, result.output
    scans = list(open_scans(bag))
    assert "4934" in result.stdout and "keypoints/scan" in result.stdout
    table = pq.read_table(out).to_pydict()
    n = len(table["x"])
    detector = CornerDetector(DetectorParams())
    expected_total = sum(len(detector.detect(s)) for s in scans[::50])
    got_total = sum(1 for i in table["scan_index"] if i % 50 == 0)
    assert got_total == expected_total > 0  # same keypoints as the detector on those scans
    index = np.array(table["scan_index"])
    assert index.min() >= 0 and index.max() < 4934 and np.all(np.diff(index) >= 0)
    stamps = np.array([scans[i].stamp for i in index])
    np.testing.assert_array_equal(np.array(table["stamp"]), stamps)
    _check_map_columns(
        table["x"], table["y"], table["map_x"], table["map_y"], [scans[i].pose for i in index]
    )
    assert f"{n}" in result.stdout
    saved = DetectorParams.from_file(Path(f"{out}.params.yaml"))
    assert saved == DetectorParams()
    meta = pq.read_schema(out).metadata
    assert (
        b"M. F. Silva" in meta[b"laser_corners.method"]
        and b"10.1109/ICARA" in meta[b"laser_corners.method"]
    )
    assert (
        DetectorParams.model_validate(__import__("yaml").safe_load(meta[b"laser_corners.params"]))
        == DetectorParams()
    )


def test_detect_intel_corrected_log_to_csv(tmp_path: Path) -> None:
    log = real_file("intel-corrected.clf.gz")
    out = tmp_path / "intel.csv"
    result = _invoke("detect", log, "-o", out)
    assert result.exit_code == 0, result.output
    assert "2672" in result.stdout
    with gzip.open(log, "rt") as handle:
        lines = [line.split() for line in handle if line.startswith("ROBOTLASER1")]
    poses, stamps = [], []
    for tokens in lines:
        n = int(tokens[8])
        after = 10 + n + int(tokens[9 + n])
        poses.append(tuple(float(v) for v in tokens[after : after + 3]))
        stamps.append(float(tokens[after + 11]))
    with out.open() as handle:
        rows = list(csv.DictReader(handle))
    assert rows, "no keypoints written"
    index = [int(r["scan_index"]) for r in rows]
    assert max(index) < len(lines) == 2672
    np.testing.assert_allclose([float(r["stamp"]) for r in rows], [stamps[i] for i in index])
    col = {k: np.array([float(r[k]) for r in rows]) for k in ("x", "y", "map_x", "map_y")}
    _check_map_columns(col["x"], col["y"], col["map_x"], col["map_y"], [poses[i] for i in index])


def test_detect_hokuyo_left_scan(tmp_path: Path) -> None:
    bag = real_file("hokuyo270_rooms.bag")
    result = _invoke("detect", bag)
    assert result.exit_code == 2
    for topic in ("/left_scan", "/rear_scan", "/right_scan"):
        assert f"--topic {topic}" in result.stderr
    out = tmp_path / "left.parquet"
    result = _invoke("detect", bag, "--topic", "/left_scan", "-o", out)
    assert result.exit_code == 0, result.output
    assert "435" in result.stdout and "/left_scan" in result.stdout
    table = pq.read_table(out)
    assert "map_x" not in table.column_names  # no odometry in this bag
    source = open_scans(bag, topic="/left_scan")
    scans = list(source)
    index = table.column("scan_index").to_numpy()
    np.testing.assert_array_equal(table.column("stamp").to_numpy(), [scans[i].stamp for i in index])


# ----------------------------------------------------------------------------- info, plot
def test_info_lists_topics_geometry_and_counts() -> None:
    result = _invoke("info", real_file("fr079.bag"))
    assert result.exit_code == 0, result.output
    for text in ("/scan", "/odom", "4934", "360", "0.5014", "laser", "yes"):
        assert text in result.stdout
    result = _invoke("info", real_file("intel-corrected.clf.gz"))
    assert result.exit_code == 0, result.output
    assert "ROBOTLASER1 lines" in result.stdout and "2672" in result.stdout
    result = _invoke("info", real_file("hokuyo270_rooms.bag"))
    assert result.exit_code == 0, result.output
    assert "--topic /rear_scan" in result.stdout and "768" in result.stdout


def test_plot_writes_a_png(tmp_path: Path) -> None:
    out = tmp_path / "scan.png"
    result = _invoke("plot", real_file("fr079.bag"), "--scan", "10", "-o", out, "--preset", "auto")
    assert result.exit_code == 0, result.output
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert "keypoints" in result.stdout
    result = _invoke("plot", real_file("fr079.bag"), "--scan", "99999", "-o", out)
    _one_line_error(result, "fr079.bag", "scan 99999")


# ----------------------------------------------------------------------------- errors
def test_known_errors_are_one_line_with_exit_code_2(tmp_path: Path) -> None:
    bag = real_file("fr079.bag")
    _one_line_error(_invoke("detect", tmp_path / "none.bag"), "none.bag", "no such file")
    (tmp_path / "empty.clf").write_text("")
    _one_line_error(_invoke("info", tmp_path / "empty.clf"), "empty.clf", "empty")
    _one_line_error(_invoke("detect", bag, "--topic", "/odom"), "fr079.bag", "Odometry")
    _one_line_error(_invoke("detect", bag, "--preset", "nope"), "unknown preset 'nope'")
    _one_line_error(_invoke("detect", bag, "--set", "min_points=x"), "min_points")
    _one_line_error(_invoke("detect", bag, "--set", "bogus=1"), "unknown parameter 'bogus'")
    params = tmp_path / "p.yaml"
    params.write_text("min_points: 6\n")
    _one_line_error(
        _invoke("detect", bag, "--params", params, "--preset", "auto"), "--preset or --params"
    )
    _one_line_error(_invoke("detect", bag, "-o", tmp_path / "k.txt"), "k.txt", "unknown output")
    cut = tmp_path / "cut.bag"
    cut.write_bytes(bag.read_bytes()[:500_000])
    _one_line_error(_invoke("detect", cut), "cut.bag", "damaged or truncated")
    log = real_file("intel-corrected.clf.gz")
    cut_log = tmp_path / "cut.clf.gz"
    cut_log.write_bytes(log.read_bytes()[:300_000])
    _one_line_error(_invoke("detect", cut_log), "cut.clf.gz", "truncated gzip", "after line")


def test_malformed_log_lines_are_reported_in_the_summary(tmp_path: Path) -> None:
    with gzip.open(real_file("intel-corrected.clf.gz"), "rt") as handle:
        lines = [next(handle) for _ in range(60)]
    lines[5] = "ROBOTLASER1 0 -1.57 3.14 0.0174 50 0.1 0 180 1.0 2.0\n"
    log = tmp_path / "bad.clf"
    log.write_text("".join(lines))
    result = _invoke("detect", log)
    assert result.exit_code == 0, result.output
    assert "1 malformed ROBOTLASER1 line" in result.stdout
    assert "first at line 6" in result.stdout


def test_ctrl_c_keeps_what_was_written(tmp_path: Path) -> None:
    # a plain-text CARMEN log of twenty copies of intel-corrected (53,440 scans): several
    # seconds of reading; what the CSV writer's buffer holds at the interrupt must be kept too
    with gzip.open(real_file("intel-corrected.clf.gz"), "rt") as handle:
        text = handle.read()
    log = tmp_path / "intel20.clf"
    log.write_text(text * 20)
    n_scans = 20 * sum(1 for line in text.splitlines() if line.startswith("ROBOTLASER1"))
    out = tmp_path / "intel.csv"
    process = subprocess.Popen(
        [*CLI, "detect", str(log), "-o", str(out), "--preset", "auto"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        preexec_fn=default_sigint,
    )
    # interrupt once rows have reached the file under its temporary name (the name until it
    # is complete): however loaded the machine or cold the kernel cache, the interrupt then
    # lands mid-run with something written
    deadline = time.monotonic() + 300
    while time.monotonic() < deadline and process.poll() is None:
        partial = list(tmp_path.glob("intel.*.partial.csv"))
        if partial and partial[0].stat().st_size > 64 * 1024:
            break
        time.sleep(0.02)
    assert process.poll() is None, "the run ended before it could be interrupted"
    process.send_signal(signal.SIGINT)
    try:
        stdout, stderr = process.communicate(timeout=120)
    except subprocess.TimeoutExpired:
        process.kill()
        stdout, stderr = process.communicate()
        raise AssertionError(f"no exit 120 s after the interrupt: {stderr[-2000:]}") from None
    assert process.returncode == 130, stderr
    assert "interrupted at" in stderr and "keeps what was written" in stderr
    with out.open() as handle:
        rows = list(csv.DictReader(handle))
    index = [int(r["scan_index"]) for r in rows]
    assert rows and max(index) < n_scans - 1
    assert not list(tmp_path.glob("*.partial.*"))  # finished and renamed
    assert str(n_scans) not in stdout.split("keypoints")[0]  # the summary counts what ran


def test_help_is_fast_and_lazy() -> None:
    code = (
        "import sys; from laser_corners.cli import app; "
        "print(sorted(m for m in ('rosbags', 'pyarrow') if m in sys.modules))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"
    result = _invoke("--help")
    assert result.exit_code == 0
    for command in ("detect", "info", "plot", "params"):
        assert command in result.stdout


# ----------------------------------------------------------------------------- presets
def test_auto_preset_follows_the_angular_resolution() -> None:
    paper = DetectorParams()
    fine = auto_params(math.radians(0.25))
    assert fine.scales[0] == paper.scales[0] and fine.scales[-1] == pytest.approx(0.2618, 1e-3)
    coarse = auto_params(math.radians(1.0))
    assert coarse.scales[0] == 0.05 and coarse.scales[-1] == pytest.approx(
        5 * 4 * 3.0 * math.radians(1.0)
    )
    assert coarse.max_point_distance == pytest.approx(
        paper.max_point_distance * 4 * 3.0 * math.radians(1.0) / 0.05
    )
    assert (coarse.max_fit_rmse, coarse.min_points) == (paper.max_fit_rmse, paper.min_points)
    assert get_preset("paper") == paper
    with pytest.raises(InvalidParamsError, match="needs a scan"):
        get_preset("auto")


def test_auto_preset_finds_more_corners_on_a_one_degree_log() -> None:
    scans = list(open_scans(real_file("intel-corrected.clf.gz")))[:400]
    paper = CornerDetector(get_preset("paper", scans[0]))
    auto = CornerDetector(get_preset("auto", scans[0]))
    n_paper = sum(len(paper.detect(s)) for s in scans)
    n_auto = sum(len(auto.detect(s)) for s in scans)
    assert n_auto > 1.2 * n_paper


def test_preset_and_reader_docstring_examples() -> None:
    import doctest

    import laser_corners.io.registry
    import laser_corners.presets

    for module in (laser_corners.presets, laser_corners.io.registry):
        assert doctest.testmod(module).failed == 0
