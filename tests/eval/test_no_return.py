"""``evaluate real`` on a log whose "no return" beams read 81.9 m (issue 13 item 2).

The log is written here: a room scanned by a 180-beam, 1 deg scanner (like fr-clinic), with a
sector of every scan replaced by 81.9 m readings (an open door onto nothing the scanner can
see), in ROBOTLASER1 lines that declare a 100 m maximum range, so the reader keeps the 81.9 m
readings as valid ranges.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from laser_corners.cli import app
from laser_corners.eval.grid import bounded_grid
from laser_corners.eval.no_return import no_return_range, without_no_returns
from laser_corners.eval.real import RealEvalConfig, RealEvaluation, evaluate_real, load_scans
from laser_corners.eval.real_summary import headline, summary
from laser_corners.scan import LaserScan
from laser_corners.sim import SICK_LMS_1DEG, rectangular_room
from laser_corners.viz.report import write_real_report

NO_RETURN = 81.9


def _line(scan: LaserScan) -> str:
    ranges = np.where(np.isfinite(scan.ranges), scan.ranges, NO_RETURN)
    x, y, th = scan.pose
    return (
        f"ROBOTLASER1 0 {scan.angle_min:.6f} {math.pi:.6f} {scan.angle_increment:.8f} 100.0 "
        f"0.01 0 {scan.n_beams} " + " ".join(f"{r:.2f}" for r in ranges) + " 0 "
        f"{x:.6f} {y:.6f} {th:.6f} {x:.6f} {y:.6f} {th:.6f} 0 0 0 0 0 {scan.stamp:.6f} "
        f"host {scan.stamp:.6f}"
    )


def write_log(path: Path, n: int) -> Path:
    world = rectangular_room()
    rng = np.random.default_rng(11)
    lines = []
    for k in range(n):
        u = k / max(n - 1, 1)
        pose = (-2.0 + 3.0 * u, -1.0 + 0.6 * u, 0.2 + 0.8 * math.sin(4.0 * u))
        scan = world.scan(pose, SICK_LMS_1DEG, noise_sigma=0.005, rng=rng, stamp=5.0 + 0.2 * k)
        ranges = scan.ranges.copy()
        ranges[30:75] = np.inf  # the open door: no return on 45 beams
        lines.append(
            _line(
                LaserScan(
                    ranges,
                    scan.angle_min,
                    scan.angle_increment,
                    scan.range_min,
                    scan.range_max,
                    scan.stamp,
                    "laser",
                    pose,
                )
            )
        )
    path.write_text("\n".join(lines) + "\n")
    return path


@pytest.fixture(scope="module")
def log(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return write_log(tmp_path_factory.mktemp("noreturn") / "open-door.clf", 60)


def test_the_reader_keeps_81_9_m_as_ranges(log: Path) -> None:
    """The premise: without the evaluation's check, 81.9 m readings are valid echoes."""
    scans, _ = load_scans(log)
    assert scans[0].range_max == 100.0
    assert np.count_nonzero(scans[0].valid & (scans[0].ranges > 80.0)) == 45


def test_sentinel_found_and_made_gaps(log: Path) -> None:
    scans, _ = load_scans(log)
    limit = no_return_range(scans)
    assert limit == pytest.approx(NO_RETURN, abs=0.002)
    cleaned = without_no_returns(scans, limit)
    assert all(np.all(s.ranges[s.valid] < 10.0) for s in cleaned)
    # real far echoes spread out: no sentinel in a scan without one
    assert no_return_range([s for s in cleaned]) is None


def test_no_return_readings_never_enter_the_maps(log: Path, tmp_path: Path) -> None:
    scans, pose_source = load_scans(log)
    steps: list[tuple[str, int, int]] = []
    messages: list[str] = []
    cfg = RealEvalConfig(min_views=5, max_pairs=40, pair_min_motion=0.3, methods=("paper",))
    result = evaluate_real(
        scans,
        cfg,
        source=log.name,
        pose_source=pose_source,
        progress=messages.append,
        step=lambda *a: steps.append(a),
    )
    assert result.no_return_range == pytest.approx(NO_RETURN, abs=0.002)
    assert any("no return" in note for note in result.notes)
    traj = result.trajectory_xy
    for pts in (result.scan_points_map_xy, result.keypoints_map_xy):
        far = np.linalg.norm(pts[:, None, :] - traj[None, :, :], axis=2).min(axis=1)
        assert far.max() < 8.0  # the room is 6 x 4 m; nothing 81.9 m away
    rows, cols = result.obs.grid.shape
    assert rows * cols < 200 * 250  # about the room (0.03 m cells), not a 165 m square
    # progress: every long phase reports, and reaches its total
    done = {phase: (d, t) for phase, d, t in steps}
    assert {"detection", "observability"} <= set(done)
    assert done["detection"] == (60, 60) and done["observability"] == (60, 60)
    assert any(m.startswith("observability map") for m in messages)
    paths = write_real_report(result, tmp_path / "report")
    assert sum(p.stat().st_size for p in paths.values()) < 3_000_000


def test_map_size_bounded_by_coarser_cells() -> None:
    path = np.array([[0.0, 0.0], [100.0, 50.0]])
    kps = np.array([[5.0, 5.0], [95.0, 45.0], [900.0, 0.0]])  # the last one far beyond reach
    grid, notes = bounded_grid(kps, path, reach=20.0, resolution=0.03, max_cells=100_000)
    assert grid.shape[0] * grid.shape[1] <= 100_000
    assert grid.resolution > 0.03
    assert grid.extent[1] < 200.0  # the keypoint 900 m away did not widen the map
    assert any("coarsened" in n for n in notes) and any("beyond" in n for n in notes)


def _thin_result(tmp_path: Path) -> RealEvaluation:
    scans, _ = load_scans(write_log(tmp_path / "short.clf", 8))
    cfg = RealEvalConfig(min_views=2, methods=("paper",))
    return evaluate_real(scans, cfg, source="short.clf")


def test_thin_evidence_is_said_plainly_never_nan(tmp_path: Path) -> None:
    result = _thin_result(tmp_path)
    assert result.warnings  # 8 scans: too few pairs for every number
    assert any("too little evidence" in w or "no scan pair" in w for w in result.warnings)
    line = headline(result)
    assert "nan" not in line.lower()
    info = summary(result)
    text = json.dumps(info, allow_nan=False)  # raises on NaN
    assert info["warnings"] == result.warnings
    paths = write_real_report(result, tmp_path / "r")
    report = paths["report.md"].read_text()
    assert "nan" not in report.lower() and "## Warnings" in report
    assert json.loads(text)["association"]["enough_evidence"] is False


def test_cli_on_the_log(log: Path, tmp_path: Path) -> None:
    out = tmp_path / "cli"
    args = [
        "evaluate",
        "real",
        str(log),
        "-o",
        str(out),
        "--min-views",
        "5",
        "--methods",
        "paper,falko-like",
    ]
    result = CliRunner().invoke(app, args)
    assert result.exit_code == 0, result.output
    info = json.loads((out / "summary.json").read_text())
    assert info["no_return_range"] == pytest.approx(NO_RETURN, abs=0.002)
    assert info["grid"]["rows"] * info["grid"]["cols"] < 200 * 250
    assert not list(out.glob("*.npy"))
