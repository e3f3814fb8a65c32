"""Issue 13 on the command line: interrupted bag output, output paths, nonsense options, help."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from laser_corners import LaserScan
from laser_corners.cli import app

runner = CliRunner()
CLI = [str(Path(sys.executable).with_name("laser-corners"))]


def _invoke(*args: str | Path):
    return runner.invoke(app, [str(a) for a in args])


def _one_line_error(result, *needles: str) -> str:
    assert result.exit_code == 2, result.output
    assert "Traceback" not in result.output
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("laser-corners: error: "), result.stderr
    for needle in needles:
        assert needle in lines[0], lines[0]
    return lines[0]


def _small_log(path: Path, n: int = 5) -> Path:
    """A CARMEN log of ``n`` 181-beam scans of a square room (written here)."""
    angles = np.linspace(-np.pi / 2, np.pi / 2, 181)
    ranges = np.minimum(
        3.0 / np.maximum(np.abs(np.cos(angles)), 1e-9),
        2.0 / np.maximum(np.abs(np.sin(angles)), 1e-9),
    )
    lines = []
    for i in range(n):
        body = " ".join(f"{r:.3f}" for r in ranges)
        lines.append(f"FLASER 181 {body} 0 0 0 0 0 0 {i * 0.1:.3f} host {i * 0.1:.3f}")
    path.write_text("\n".join(lines) + "\n")
    return path


# ------------------------------------------------------------------ (4) interrupted bag output
def _small_bag(path: Path, n: int = 300) -> Path:
    """A ROS 1 bag of ``n`` 360-beam LaserScans of a square room on /scan (written here)."""
    from rosbags.rosbag1 import Writer
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS1_NOETIC)
    scan_type, header_type = (
        store.types["sensor_msgs/msg/LaserScan"],
        store.types["std_msgs/msg/Header"],
    )
    time_type = store.types["builtin_interfaces/msg/Time"]
    angles = np.linspace(-np.pi, np.pi, 360, endpoint=False)
    walls = np.minimum(
        3.0 / np.maximum(np.abs(np.cos(angles)), 1e-9),
        2.0 / np.maximum(np.abs(np.sin(angles)), 1e-9),
    )
    ranges = walls.astype(np.float32)
    with Writer(path) as writer:
        connection = writer.add_connection("/scan", scan_type.__msgtype__, typestore=store)
        for i in range(n):
            stamp = 1_000_000_000 + i * 100_000_000
            msg = scan_type(
                header=header_type(
                    seq=i,
                    stamp=time_type(sec=stamp // 10**9, nanosec=stamp % 10**9),
                    frame_id="laser",
                ),
                angle_min=-np.pi,
                angle_max=np.pi,
                angle_increment=2 * np.pi / 360,
                time_increment=0.0,
                scan_time=0.1,
                range_min=0.05,
                range_max=30.0,
                ranges=ranges,
                intensities=np.zeros(0, dtype=np.float32),
            )
            writer.write(connection, stamp, store.serialize_ros1(msg, scan_type.__msgtype__))
    return path


def _topic_counts(bag: Path) -> dict[str, int]:
    from rosbags.highlevel import AnyReader

    with AnyReader([bag]) as reader:
        return {c.topic: c.msgcount for c in reader.connections}


def test_detect_to_bag_interrupted_keeps_the_keypoints_written(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from laser_corners import CornerDetector

    bag = _small_bag(tmp_path / "room.bag")
    real_detect_many = CornerDetector.detect_many
    done = {"scans": 0}

    def detect_many_then_ctrl_c(self, scans):  # type: ignore[no-untyped-def]
        if done["scans"] >= 120:  # Ctrl-C in the middle of the run
            raise KeyboardInterrupt
        done["scans"] += len(scans)
        return real_detect_many(self, scans)

    monkeypatch.setattr(CornerDetector, "detect_many", detect_many_then_ctrl_c)
    out = tmp_path / "x.bag"
    result = _invoke("detect", bag, "-o", out)
    assert result.exit_code == 130, result.output
    message = result.stderr.strip().splitlines()[-1]
    assert message.startswith("interrupted at message") and "keeps what was written" in message
    scans = int(re.search(r"after (\d+) scans", message).group(1))  # type: ignore[union-attr]
    counts = _topic_counts(out)
    assert counts["/scan"] == 300  # the copy of the input is whole
    assert counts["/scan_corners"] == counts["/scan_corner_markers"] == scans == done["scans"] > 0


def test_detect_to_bag_interrupted_in_its_first_writes_keeps_a_whole_bag(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from rosbags.rosbag1 import Writer

    bag = _small_bag(tmp_path / "room.bag")
    real_write = Writer.write
    calls = {"n": 0}

    def write_then_ctrl_c(self, *args):  # type: ignore[no-untyped-def]
        calls["n"] += 1
        if calls["n"] == 50:  # Ctrl-C while the first input messages are being copied
            raise KeyboardInterrupt
        return real_write(self, *args)

    monkeypatch.setattr(Writer, "write", write_then_ctrl_c)
    out = tmp_path / "x.bag"
    result = _invoke("detect", bag, "-o", out)
    assert result.exit_code == 130, result.output
    message = result.stderr.strip().splitlines()[-1]
    assert "keeps what was written" in message, result.stderr
    scans = int(re.search(r"after (\d+) scans", message).group(1))  # type: ignore[union-attr]
    # the bag writer copies the input as it goes and the rest on close: a whole, indexed bag
    counts = _topic_counts(out)
    assert counts["/scan"] == 300
    assert counts.get("/scan_corners", 0) == scans
    assert not list(tmp_path.glob("*.partial*"))


# ------------------------------------------------------------------ (5) output paths
def test_outputs_into_missing_folders_are_created(tmp_path: Path) -> None:
    png = tmp_path / "new" / "folder" / "demo.png"
    result = _invoke("demo", "-o", png)
    assert result.exit_code in (0, 1), result.output  # 1: a corner missed, still a plot
    assert png.read_bytes()[:4] == b"\x89PNG"
    log = _small_log(tmp_path / "room.clf")
    plot = tmp_path / "plots" / "deep" / "scan.png"
    result = _invoke("plot", log, "-o", plot)
    assert result.exit_code == 0, result.output
    assert plot.read_bytes()[:4] == b"\x89PNG"


def test_folder_outputs_onto_an_existing_file_fail_in_one_line(tmp_path: Path) -> None:
    taken = tmp_path / "taken"
    taken.write_text("not a folder")
    _one_line_error(_invoke("simulate", "-o", taken, "--scans", "2"), "taken", "--output")
    _one_line_error(
        _invoke("evaluate", "sim", "-o", taken, "--worlds", "1", "--poses", "1"),
        "taken",
        "--output",
    )
    log = _small_log(tmp_path / "room.clf")
    _one_line_error(_invoke("evaluate", "real", log, "-o", taken), "taken", "--output")
    assert taken.read_text() == "not a folder"


# ------------------------------------------------------------------ (6) nonsense options
@pytest.mark.parametrize(
    ("args", "needles"),
    [
        (("evaluate", "real", "LOG", "--methods", "foo"), ("--methods", "'foo'", "paper")),
        (("simulate", "--noise", "-1"), ("--noise", ">= 0")),
        (("demo", "--noise", "-0.5"), ("--noise", ">= 0")),
        (("simulate", "--speed", "nan"), ("--speed", "finite")),
        (("evaluate", "sim", "--noise", "0,-0.01"), ("--noise", ">= 0")),
    ],
    ids=["methods", "simulate-noise", "demo-noise", "speed-nan", "sim-noise"],
)
def test_nonsense_options_are_rejected_naming_the_option(
    tmp_path: Path, args: tuple[str, ...], needles: tuple[str, ...]
) -> None:
    log = _small_log(tmp_path / "room.clf")
    out = tmp_path / "out"
    argv = [str(log) if a == "LOG" else a for a in args]
    result = runner.invoke(app, [*argv, "-o", str(out / "x.png" if args[0] == "demo" else out)])
    _one_line_error(result, *needles)
    assert not (out / "x.png").exists()


# ------------------------------------------------------------------ (8) plot index, help width
def test_plot_beyond_the_last_scan_says_how_many_there_are(tmp_path: Path) -> None:
    log = _small_log(tmp_path / "room.clf", n=7)
    line = _one_line_error(_invoke("plot", log, "--scan", "99999", "-o", tmp_path / "p.png"))
    assert "scan 99999" in line and "7 scans" in line and "0 to 6" in line


def test_help_keeps_long_option_text_whole() -> None:
    from laser_corners.cli.common import PresetOption

    text = PresetOption.__metadata__[0].help  # type: ignore[attr-defined]
    assert len(text) > 150
    process = subprocess.run(
        [*CLI, "detect", "--help"],
        capture_output=True,
        text=True,
        check=True,
        env={**os.environ, "COLUMNS": "80"},
    )
    flat = " ".join(process.stdout.replace("│", " ").split())
    assert " ".join(text.split()) in flat
    assert max(len(line) for line in process.stdout.splitlines()) > 80
    assert "…" not in process.stdout


def test_laserscan_import_is_cheap_for_the_helpers() -> None:
    # the helpers above write CARMEN lines the reader accepts
    scan = LaserScan(np.ones(181), -np.pi / 2, np.pi / 180, 0.0, 81.0)
    assert scan.n_beams == 181
