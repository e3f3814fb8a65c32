"""``evaluate real``: the pipeline on simulated scans with known corners, the report, the CLI."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from conftest import real_file
from laser_corners.cli import app
from laser_corners.eval.methods import detect_all
from laser_corners.eval.real import RealEvalConfig, RealEvaluation, evaluate_real
from laser_corners.scan import LaserScan
from laser_corners.sim import UST_10LX, rectangular_room
from laser_corners.viz.report import write_real_report

runner = CliRunner()


def room_scans(n: int = 24, noise: float = 0.002) -> tuple[list[LaserScan], np.ndarray]:
    """Scans of the 6 x 4 m room with a pillar from a path through it; returns the corners."""
    world = rectangular_room()
    rng = np.random.default_rng(5)
    scans = []
    for k in range(n):
        u = k / (n - 1)
        pose = (-2.0 + 2.5 * u, -1.2 + 0.4 * u, 0.3 + 0.6 * math.sin(3.0 * u))
        scans.append(world.scan(pose, UST_10LX, noise_sigma=noise, rng=rng, stamp=10.0 + 0.5 * k))
    return scans, world.corners


SMALL = RealEvalConfig(
    min_views=5, max_pairs=40, pair_min_motion=0.3, methods=("paper", "falko-like")
)


@pytest.fixture(scope="module")
def room_result() -> tuple[RealEvaluation, np.ndarray]:
    scans, corners = room_scans()
    return evaluate_real(scans, SMALL, source="room"), corners


def test_pipeline_finds_the_room_corners_and_nothing_else(room_result) -> None:
    result, corners = room_result
    feats = result.features.xy
    assert len(feats) >= 4
    dist = np.linalg.norm(feats[:, None, :] - corners[None, :, :], axis=2).min(axis=1)
    assert dist.max() < 0.03  # every persistent feature is a true corner
    # exact poses and 2 mm noise: the detector places corners consistently
    assert result.association.n_pairs_with_std > 0
    assert result.association.max_std < 0.01
    assert result.association.share_std_within == 1.0
    ours = result.repeatability["paper"]
    assert ours.n_pairs > 10
    assert ours.repeatability[0] > 0.9
    assert set(result.repeatability) == {"paper", "falko-like"}
    # a room has few corners: the association distance rests on few pairs, and says so
    assert result.warnings == [
        f"association distance rests on only {result.association.n_pairs_with_std} feature "
        "pairs (fewer than 20): too little evidence"
    ]
    assert "pairs" in result.pairs_source


def test_report_files(room_result, tmp_path: Path) -> None:
    result, _ = room_result
    paths = write_real_report(result, tmp_path)
    for name in (
        "observability.png",
        "observability_n8.png",
        "observability.npz",
        "observability_counts.npz",
        "association_matrix.png",
        "association_histogram.png",
        "association.npz",
        "repeatability.csv",
        "persistent_features.csv",
        "report.md",
        "summary.json",
        "params.yaml",
    ):
        assert (tmp_path / name).is_file(), name
        assert name in paths
    ratio = np.load(tmp_path / "observability.npz")["ratio_n8"]
    assert ratio.shape == result.obs.grid.shape
    np.testing.assert_array_equal(ratio, result.obs.ratio_n8.astype(np.float32))
    std = np.load(tmp_path / "association.npz")["std"]
    np.testing.assert_allclose(std, result.pair_std, rtol=1e-6)
    info = json.loads((tmp_path / "summary.json").read_text())
    assert info["persistent_features"]["count"] == len(result.features)
    assert "M. F. Silva" in info["method_reference"] and "Petry" not in info["method_reference"]
    assert info["association"]["pairs_never_together"] == result.association.n_pairs_never_together
    report = (tmp_path / "report.md").read_text()
    for link in ("observability.png", "association_matrix.png", "association_histogram.png"):
        assert f"({link})" in report
    assert "| paper |" in report and "| falko-like |" in report
    assert "M. F. Silva" in report and "10.1109/ICARA60736.2024.10553006" in report
    rows = (tmp_path / "repeatability.csv").read_text().splitlines()
    assert rows[0].startswith("method,keypoints_per_scan,pairs,visible,repeatability_r0.05")
    assert len(rows) == 3


# ----------------------------------------------------------------------------- CLI
def _carmen_line(scan: LaserScan, with_pose: bool) -> str:
    ranges = np.where(np.isfinite(scan.ranges), scan.ranges, scan.range_max)
    head = (
        f"{scan.angle_min:.6f} {math.radians(270):.6f} {scan.angle_increment:.8f} "
        f"{scan.range_max:.1f} 0.01 0 {scan.n_beams} "
    )
    body = " ".join(f"{r:.4f}" for r in ranges) + " 0 "
    if with_pose:
        x, y, th = scan.pose
        tail = f"{x:.6f} {y:.6f} {th:.6f} {x:.6f} {y:.6f} {th:.6f} 0 0 0 0 0 {scan.stamp:.6f}"
        return f"ROBOTLASER1 0 {head}{body}{tail} host {scan.stamp:.6f}"
    return f"RAWLASER1 0 {head}{body}{scan.stamp:.6f} host {scan.stamp:.6f}"


def test_cli_evaluate_real_on_a_carmen_log(tmp_path: Path) -> None:
    scans, corners = room_scans(n=16)
    log = tmp_path / "room.clf"
    log.write_text("\n".join(_carmen_line(s, True) for s in scans) + "\n")
    out = tmp_path / "report"
    args = [
        "evaluate",
        "real",
        str(log),
        "-o",
        str(out),
        "--min-views",
        "4",
        "--methods",
        "paper,falko",
        "--max-pairs",
        "20",
    ]
    result = runner.invoke(app, args)
    assert result.exit_code == 0, result.output
    assert (out / "report.md").is_file() and (out / "observability.png").is_file()
    info = json.loads((out / "summary.json").read_text())
    assert info["scans"] == 16
    # "falko": the older name of falko-like, still accepted
    assert [r["method"] for r in info["repeatability"]["rows"]] == ["paper", "falko-like"]
    assert info["persistent_features"]["count"] >= 3
    # the log's poses put the map-frame keypoints on the true corners
    feats = np.loadtxt(out / "persistent_features.csv", delimiter=",", skiprows=1, ndmin=2)
    dist = np.linalg.norm(feats[:, None, :2] - corners[None, :, :], axis=2).min(axis=1)
    assert dist.max() < 0.03


def test_cli_rejects_an_unknown_method(tmp_path: Path) -> None:
    scans, _ = room_scans(n=6)
    log = tmp_path / "room.clf"
    log.write_text("\n".join(_carmen_line(s, True) for s in scans) + "\n")
    out = tmp_path / "report"
    result = runner.invoke(
        app, ["evaluate", "real", str(log), "-o", str(out), "--methods", "paper,nosuch"]
    )
    assert result.exit_code == 2
    assert "unknown method 'nosuch'" in result.output and "falko-like" in result.output
    assert not (out / "report.md").exists()


def test_cli_needs_poses_or_a_trajectory(tmp_path: Path) -> None:
    scans, _ = room_scans(n=12)
    log = tmp_path / "raw.clf"
    log.write_text("\n".join(_carmen_line(s, False) for s in scans) + "\n")
    result = runner.invoke(app, ["evaluate", "real", str(log), "-o", str(tmp_path / "r")])
    assert result.exit_code == 2
    assert "no scan has a sensor pose" in result.output
    assert "give a trajectory" in result.output  # the library names no CLI flag
    # the same scans with their poses from a TUM trajectory
    tum = tmp_path / "traj.tum"
    tum.write_text(
        "".join(
            f"{s.stamp} {s.pose[0]} {s.pose[1]} 0 0 0 {math.sin(s.pose[2] / 2)} "
            f"{math.cos(s.pose[2] / 2)}\n"
            for s in scans
        )
    )
    out = tmp_path / "with_traj"
    result = runner.invoke(
        app,
        [
            "evaluate",
            "real",
            str(log),
            "-o",
            str(out),
            "--trajectory",
            str(tum),
            "--min-views",
            "4",
            "--methods",
            "paper",
        ],
    )
    assert result.exit_code == 0, result.output
    info = json.loads((out / "summary.json").read_text())
    assert info["scans_with_pose"] == 12
    assert "TUM trajectory" in info["pose_source"]


def test_cli_bad_relations_mount_is_one_line(tmp_path: Path) -> None:
    result = runner.invoke(
        app, ["evaluate", "real", str(tmp_path / "x.clf"), "--relations-mount", "1,2"]
    )
    assert result.exit_code == 2
    assert "--relations-mount needs x,y,theta" in result.output


# ----------------------------------------------------------------------------- real data
@pytest.mark.real
def test_real_corrected_log_small(tmp_path: Path) -> None:
    log = real_file("fr079-corrected.clf.gz")
    out = tmp_path / "fr079"
    result = runner.invoke(
        app,
        ["evaluate", "real", str(log), "-o", str(out), "--max-scans", "150", "--max-pairs", "80"],
    )
    assert result.exit_code == 0, result.output
    info = json.loads((out / "summary.json").read_text())
    assert info["scans"] == 150 and info["scans_with_pose"] == 150
    rows = {r["method"]: r for r in info["repeatability"]["rows"]}
    assert {"paper", "split-and-merge", "falko-like"} <= set(rows)
    for row in rows.values():
        assert 0.0 <= row["repeatability_r0.05"] <= row["repeatability_r0.1"] <= 1.0
    # measured on the whole log: 0.73 (docs/real-evaluation.md); a broken pose chain or
    # frame convention drops it towards 0
    assert rows["paper"]["repeatability_r0.1"] > 0.5
    assert info["persistent_features"]["count"] > 0


@pytest.mark.real
def test_real_bag_uses_its_relations(tmp_path: Path) -> None:
    bag = real_file("fr079.bag")
    real_file("fr079.relations")
    out = tmp_path / "bag"
    result = runner.invoke(
        app,
        [
            "evaluate",
            "real",
            str(bag),
            "-o",
            str(out),
            "--max-scans",
            "600",
            "--max-pairs",
            "60",
            "--methods",
            "paper",
        ],
    )
    assert result.exit_code == 0, result.output
    info = json.loads((out / "summary.json").read_text())
    assert info["repeatability"]["pairs_source"].startswith("ground-truth relations")
    assert info["repeatability"]["pairs"] > 0
    assert info["repeatability"]["rows"][0]["repeatability_r0.1"] > 0.5


def test_a_shared_detect_loop_plugs_in() -> None:
    """evaluate_real runs every detector through the loop it is given (the pipeline's, later)."""
    scans, _ = room_scans(n=10)
    calls: list[tuple[str, int]] = []

    def loop(detector, batch, step):  # type: ignore[no-untyped-def]
        calls.append((type(detector).__name__, len(batch)))
        return detect_all(detector, batch, step)

    cfg = RealEvalConfig(min_views=3, pair_min_motion=0.3, methods=("paper", "falko-like"))
    plain = evaluate_real(scans, cfg)
    looped = evaluate_real(scans, cfg, detect_loop=loop)
    assert calls[0] == ("CornerDetector", 10)  # the maps' detector on every scan
    assert [name for name, _ in calls[1:]] == ["FalkoLikeDetector"]  # paper already ran
    for name in plain.repeatability:
        assert plain.repeatability[name] == looped.repeatability[name]
