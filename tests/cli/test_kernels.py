"""The SLAM's first-run compile: ``slam`` and ``localise`` say it once when the cache of
their kernels is cold, and ``warmup`` compiles those kernels too."""

from __future__ import annotations

import importlib.util
import json
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

pytest.importorskip("gtsam")

from conftest import cache_answers
from laser_corners.cli import app
from laser_corners.registration import global_search

runner = CliRunner()


def _room_log(path: Path, n: int = 5) -> Path:
    """A CARMEN log of ``n`` 181-beam scans of a 6 m x 4 m room, odometry at the origin."""
    angles = np.linspace(-np.pi / 2, np.pi / 2, 181)
    along_x = 3.0 / np.maximum(np.abs(np.cos(angles)), 1e-9)
    along_y = 2.0 / np.maximum(np.abs(np.sin(angles)), 1e-9)
    body = " ".join(f"{r:.3f}" for r in np.minimum(along_x, along_y))
    lines = [f"FLASER 181 {body} 0 0 0 0 0 0 {i * 0.1:.3f} host {i * 0.1:.3f}" for i in range(n)]
    path.write_text("\n".join(lines) + "\n")
    return path


def test_slam_and_localise_announce_cold_slam_kernels_once(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    import laser_corners.cli.kernels as kernels

    log = _room_log(tmp_path / "room.clf")
    monkeypatch.setattr(kernels, "slam_kernels_are_cold", lambda: True)
    result = runner.invoke(app, ["slam", str(log), "-o", str(tmp_path / "map")])
    assert result.exit_code == 0, result.output
    assert result.stderr.count(kernels.COMPILING_SLAM) == 1
    counts = json.loads((tmp_path / "map" / "summary.json").read_text())["counts"]
    assert counts["relocalisations_attempted"] == counts["relocalisations_accepted"] == 0
    out = tmp_path / "loc"
    result = runner.invoke(app, ["localise", str(tmp_path / "map"), str(log), "-o", str(out)])
    assert result.stderr.count(kernels.COMPILING_SLAM) == 1, result.output
    monkeypatch.setattr(kernels, "slam_kernels_are_cold", lambda: False)
    result = runner.invoke(app, ["slam", str(log), "-o", str(tmp_path / "map2")])
    assert result.exit_code == 0, result.output
    assert kernels.COMPILING_SLAM not in result.stderr


def test_slam_kernel_cache_check_tells_cold_from_warm(tmp_path: Path) -> None:
    from laser_corners.cli.kernels import warm_slam_kernels

    warm_slam_kernels()  # this process's cache (the default one) is warm now
    check = (
        "from laser_corners.cli.kernels import slam_kernels_are_cold; "
        "print(slam_kernels_are_cold())"
    )
    warm, cold = cache_answers(check, tmp_path)
    assert warm.stdout.strip() == "False", warm.stderr
    assert cold.stdout.strip() == "True", cold.stderr


def test_warmup_compiles_the_slam_kernels_and_says_the_time() -> None:
    result = runner.invoke(app, ["warmup"])
    assert result.exit_code == 0, result.output
    lines = result.stdout.splitlines()
    assert any(line.startswith("detector kernels ready in") for line in lines)
    assert any(line.startswith("SLAM, localiser and matching kernels ready in") for line in lines)
    # the whole-map branch and bound, which the place index's answers would leave cold until
    # a relocalisation falls back to it (seconds of compiling in the middle of a run)
    assert global_search._advance.signatures


def test_warmup_without_gtsam_compiles_the_detector_and_says_why_not_the_slam(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """``make``'s base install runs ``warmup`` before any extra is installed: without gtsam it
    must still succeed (the SLAM part skipped, saying why), not stop the install."""
    find_spec = importlib.util.find_spec
    monkeypatch.setattr(
        importlib.util,
        "find_spec",
        lambda name, *args: None if name == "gtsam" else find_spec(name, *args),
    )
    result = runner.invoke(app, ["warmup"])
    assert result.exit_code == 0, result.output
    assert "detector kernels ready in" in result.stdout
    assert "not compiled (no gtsam" in result.stdout
