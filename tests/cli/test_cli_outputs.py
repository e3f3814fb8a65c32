"""Issue 21 on outputs: never the input, and the mode any new file gets."""

from __future__ import annotations

import os
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from conftest import real_file
from laser_corners import LaserScan
from laser_corners.cli import app
from laser_corners.io import write_scans_csv, write_scans_npz

runner = CliRunner()


def _room_scans(n: int) -> list[LaserScan]:
    """``n`` 181-beam scans of a 6 m x 4 m room, the sensor moving along x."""
    angles = np.linspace(-np.pi / 2, np.pi / 2, 181)
    scans = []
    for i in range(n):
        x = 0.01 * i
        ranges = np.minimum(
            (3.0 - x) / np.maximum(np.abs(np.cos(angles)), 1e-9),
            2.0 / np.maximum(np.abs(np.sin(angles)), 1e-9),
        )
        scans.append(LaserScan(ranges, angles[0], angles[1] - angles[0], 0.05, 30.0, 0.1 * i))
    return scans


@pytest.fixture
def umask() -> Iterator[None]:
    """Run the test under umask 027 (restored after)."""
    old = os.umask(0o027)
    try:
        yield
    finally:
        os.umask(old)


def test_detect_refuses_an_output_that_is_its_input(tmp_path: Path) -> None:
    """``detect s.csv -o s.csv`` (or -o a hard link to it) exits 2 naming both and leaves the
    recording byte for byte as it was."""
    recording = tmp_path / "s.csv"
    write_scans_csv(recording, _room_scans(300))
    before = recording.read_bytes()
    link = tmp_path / "link.csv"
    os.link(recording, link)
    for output in (recording, link):
        result = runner.invoke(app, ["detect", str(recording), "-o", str(output)])
        assert result.exit_code == 2, result.output
        assert "Traceback" not in result.output
        message = result.stderr.strip().splitlines()[-1]
        assert f"{output}: the output is the input {recording}" in message
        assert recording.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["link.csv", "s.csv"]


@pytest.mark.usefixtures("umask")
def test_outputs_get_the_mode_of_any_new_file(tmp_path: Path) -> None:
    """Keypoint tables, their sidecars and written scans are created ``0o666 & ~umask``
    (0640 under umask 027), as ``open()`` creates files, not mkstemp's 0600."""
    recording = tmp_path / "s.npz"
    write_scans_npz(recording, _room_scans(20))
    outputs = [tmp_path / "k.csv", tmp_path / "k.parquet"]
    for output in outputs:
        result = runner.invoke(app, ["detect", str(recording), "-o", str(output)])
        assert result.exit_code == 0, result.output
    made = [recording, *outputs, *(Path(f"{o}.params.yaml") for o in outputs)]
    modes = {p.name: oct(p.stat().st_mode & 0o777) for p in made}
    assert modes == {p.name: oct(0o640) for p in made}


@pytest.mark.real
def test_detect_compression_option(tmp_path: Path) -> None:
    """``--compression`` takes what rosbag offers and applies to ``.bag`` outputs only."""
    bag = real_file("fr079.bag")
    for args, needle in (
        (["-o", str(tmp_path / "k.bag"), "--compression", "zstd"], "unknown bag compression"),
        (["-o", str(tmp_path / "k.csv"), "--compression", "bz2"], "ROS 1 .bag output only"),
    ):
        result = runner.invoke(app, ["detect", str(bag), *args])
        assert result.exit_code == 2, result.output
        assert needle in result.stderr.strip().splitlines()[-1]
    assert sorted(p.name for p in tmp_path.iterdir()) == []
