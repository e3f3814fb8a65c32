"""The SLAM output folder and map figure, from a result built without running SLAM."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np
import pytest
import yaml
from matplotlib.collections import LineCollection
from matplotlib.figure import Figure

from conftest import run_until_killed
from fake_slam import fake_result
from laser_corners.citation import CITATION
from laser_corners.errors import OutputError
from laser_corners.io.occupancy import read_map
from laser_corners.io.trajectory import read_tum
from laser_corners.registration.mapfolder import LANDMARK_COLUMNS, check_map_folder
from laser_corners.slam.output import SlamRunInfo, slam_summary
from laser_corners.viz.slam import plot_ms_per_scan, plot_slam_map
from laser_corners.viz.slam_report import relation_cells, write_slam_outputs

METRICS = {
    "n_total": 10,
    "n_covered": 9,
    "trans_mean": 0.05,
    "trans_std": 0.01,
    "trans2_mean": 0.0026,
    "trans2_std": 0.001,
    "rot_deg_mean": 0.5,
    "rot_deg_std": 0.1,
    "rot2_mean": 0.26,
    "rot2_std": 0.1,
}


def _info(**kwargs) -> SlamRunInfo:
    return SlamRunInfo(source="sim.bag", wall_s=2.0, peak_rss_mb=321.0, **kwargs)


def test_folder_holds_every_file_with_one_pose_per_scan(tmp_path: Path) -> None:
    result = fake_result()
    info = _info(
        relations_file="sim.relations",
        closure_consistency=0.0,
        relations={"trajectory": METRICS, "odometry": {**METRICS, "trans_mean": 1.5}},
    )
    paths = write_slam_outputs(result, tmp_path, info)
    names = sorted(p.name for p in tmp_path.iterdir())
    assert names == sorted(
        [
            "trajectory.tum",
            "graph.g2o",
            "keyframes.npz",
            "landmarks.csv",
            "map.pgm",
            "map.yaml",
            "odometry.tum",
            "options.yaml",
            "map.png",
            "summary.json",
            "report.md",
        ]
    )
    assert set(paths) >= {"trajectory", "graph", "landmarks", "map_yaml", "map_pgm", "map_png"}
    stamps, poses = read_tum(tmp_path / "trajectory.tum")
    assert len(stamps) == len(result.stamps)
    np.testing.assert_allclose(poses[:, :2], result.poses[:, :2], atol=1e-6)
    with (tmp_path / "landmarks.csv").open() as handle:
        rows = list(csv.DictReader(handle))
    assert tuple(rows[0]) == LANDMARK_COLUMNS and len(rows) == len(result.landmarks.xy)
    assert float(rows[0]["cov_xx"]) == 1e-4 and rows[0]["observations"] == "3"
    _, odometry = read_tum(tmp_path / "odometry.tum")
    np.testing.assert_allclose(odometry[:, :2], result.odometry[:, :2], atol=1e-6)
    assert yaml.safe_load((tmp_path / "options.yaml").read_text()) == {
        "slam": result.options.model_dump()
    }
    assert "VERTEX_SE2" in (tmp_path / "graph.g2o").read_text()
    grid = read_map(tmp_path / "map.yaml")
    assert grid.resolution == 0.05
    assert np.count_nonzero(grid.occupancy == 100) > 100 and np.count_nonzero(grid.occupancy == 0)
    assert (tmp_path / "map.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert not list(tmp_path.glob("*partial*"))


def test_summary_and_report_hold_the_numbers(tmp_path: Path) -> None:
    result = fake_result()
    info = _info(
        relations_file="sim.relations", closure_consistency=0.5, relations={"trajectory": METRICS}
    )
    write_slam_outputs(result, tmp_path, info)
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["citation"] == CITATION and summary["interrupted"] is False
    assert summary["counts"]["scans"] == 120 and summary["counts"]["keyframes"] == 20
    assert summary["counts"]["keypoints"] == 1234
    assert summary["closures"] == {
        "proposed": 4,
        "accepted": 2,
        "rejected": 2,
        "rejected_by_reason": {"low overlap": 2},
    }
    timings = summary["timings"]
    assert timings["data_s"] == 11.9 or abs(timings["data_s"] - 11.9) < 1e-9
    assert abs(timings["real_time_factor"] - 11.9 / 2.0) < 1e-9
    assert abs(timings["ms_per_scan_mean"] - result.ms_per_scan.mean()) < 1e-12
    assert timings["peak_rss_mb"] == 321.0
    assert summary["options"] == result.options.model_dump()
    assert summary["mount"] == [0.1, 0.0, 0.0]
    assert summary["relations"]["trajectory"]["trans_mean"] == 0.05
    report = (tmp_path / "report.md").read_text()
    assert "![map](map.png)" in report and "9 / 10" in report and "0.0500 ± 0.0100" in report
    assert "50.0 %" in report and "Interrupted" not in report


def test_an_interrupted_result_says_so(tmp_path: Path) -> None:
    write_slam_outputs(fake_result(n_scans=30, interrupted=True), tmp_path, _info())
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["interrupted"] is True and summary["relations"] is None
    assert "**Interrupted" in (tmp_path / "report.md").read_text()
    assert len(read_tum(tmp_path / "trajectory.tum")[0]) == 30


def test_uncovered_relations_are_dashes_and_json_has_no_nan(tmp_path: Path) -> None:
    nan = float("nan")
    empty = {**dict.fromkeys(METRICS, nan), "n_total": 10, "n_covered": 0}
    assert relation_cells(empty) == ["0 / 10", "-", "-", "-", "-"]
    info = _info(relations_file="x.relations", relations={"trajectory": empty})
    write_slam_outputs(fake_result(n_scans=20), tmp_path, info)
    text = (tmp_path / "summary.json").read_text()
    assert "NaN" not in text and json.loads(text)["relations"]["trajectory"]["trans_mean"] is None


def test_relation_cells_format_mean_and_std() -> None:
    assert relation_cells(METRICS) == [
        "9 / 10",
        "0.0500 ± 0.0100",
        "0.00260 ± 0.00100",
        "0.500 ± 0.100",
        "0.260 ± 0.100",
    ]


def test_map_plot_draws_closures_between_keyframes_on_a_given_ax() -> None:
    result = fake_result()
    fig = Figure()
    ax = fig.subplots()
    plot_slam_map(
        ax, None, result.poses, result.keyframe_poses, result.landmarks.xy, result.closures
    )
    collections = [c for c in ax.collections if isinstance(c, LineCollection)]
    by_label = {c.get_label(): c for c in collections}
    accepted = by_label["2 accepted loop closures"]
    rejected = by_label["2 rejected loop closures"]
    assert accepted.get_alpha() > rejected.get_alpha()
    first = accepted.get_segments()[0]
    np.testing.assert_allclose(first, result.keyframe_poses[[-1, 0], :2])
    fig2 = Figure()
    ax2 = fig2.subplots()
    slow_start = np.r_[5000.0, np.ones(999)]
    plot_ms_per_scan(ax2, {"a": slow_start, "b": np.ones(10)})
    texts = [t.get_text() for t in ax2.get_legend().get_texts()]
    assert texts == ["a (mean 6.00 ms; 1 above the axis, max 5000 ms)", "b (mean 1.00 ms)"]
    assert ax2.get_ylim() == (0.0, 1.2)


def test_a_graph_the_library_cannot_write_does_not_cost_the_other_files(tmp_path: Path) -> None:
    result = fake_result(n_scans=30)

    def refuse(path) -> None:
        Path(path).write_text("VERTEX_SE2 0 0 0 0\n")  # half-written, then the writer fails
        raise ValueError("writeG2o: invalid noise model!")

    result.write_g2o = refuse
    (tmp_path / "graph.g2o").write_text("an earlier run's graph\n")
    info = _info()
    paths = write_slam_outputs(result, tmp_path, info)
    assert "graph" not in paths and not (tmp_path / "graph.g2o").exists()
    assert not list(tmp_path.glob("*partial*"))
    assert {"trajectory", "landmarks", "map_yaml", "map_png", "summary", "report"} <= set(paths)
    assert info.warnings == ["graph.g2o not written: writeG2o: invalid noise model!"]
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["warnings"] == info.warnings and "graph" not in summary["files"]
    assert "**Warning: graph.g2o not written" in (tmp_path / "report.md").read_text()


def _scans_in(folder: Path) -> int:
    return json.loads((folder / "summary.json").read_text())["counts"]["scans"]


def test_a_failure_while_writing_leaves_the_previous_result_whole(tmp_path: Path, monkeypatch):
    import laser_corners.viz.slam_report as report

    out = tmp_path / "map"
    write_slam_outputs(fake_result(n_scans=30), out, _info())
    before = {p.name: p.read_bytes() for p in out.iterdir()}

    def fail(*args, **kwargs):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(report, "save_slam_map", fail)  # after the tables, before the summary
    with pytest.raises(OSError):
        write_slam_outputs(fake_result(n_scans=60), out, _info())
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["map"]  # no staging folder left


def test_a_run_killed_while_writing_never_mixes_two_results(tmp_path: Path) -> None:
    out = tmp_path / "map"
    write_slam_outputs(fake_result(n_scans=30), out, _info())
    before = {p.name: p.read_bytes() for p in out.iterdir()}
    script = (
        "import sys, time\n"
        f"sys.path.insert(0, {str(Path(__file__).parents[1])!r})\n"
        "from pathlib import Path\n"
        "import laser_corners.viz.slam_report as report\n"
        "from laser_corners.slam.output import SlamRunInfo\n"
        "from fake_slam import fake_result\n"
        "def stall(*args, **kwargs):\n"
        "    print('writing', flush=True)\n"
        "    time.sleep(60)\n"
        "report.save_slam_map = stall\n"
        "info = SlamRunInfo('sim.bag', 1.0, 1.0)\n"
        "report.write_slam_outputs(fake_result(n_scans=60), Path(sys.argv[1]), info)\n"
    )
    assert run_until_killed(script, str(out)) == "writing"
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before  # SIGKILL mid-write
    (leftover,) = [p for p in tmp_path.iterdir() if p.name != "map"]
    assert leftover.name.startswith(".map.") and leftover.name.endswith(".partial")
    # the next run replaces the result whole, and sees the leftover as no result of its own
    write_slam_outputs(fake_result(n_scans=60), out, _info())
    assert _scans_in(out) == 60 and sorted(p.name for p in out.iterdir()) == sorted(before)


def test_a_folder_that_cannot_be_replaced_whole_is_refused(tmp_path: Path) -> None:
    out = tmp_path / "mixed"
    out.mkdir()
    (out / "notes.txt").write_text("mine\n")
    with pytest.raises(OutputError, match=r"mixed: holds files that are not a slam result \(notes"):
        check_map_folder(out)
    with pytest.raises(OutputError, match="not a slam result"):
        write_slam_outputs(fake_result(n_scans=20), out, _info())
    assert sorted(p.name for p in out.iterdir()) == ["notes.txt"]
    locked = tmp_path / "locked"
    write_slam_outputs(fake_result(n_scans=20), locked, _info())
    locked.chmod(0o555)
    try:  # refused by its mode, also for root (whom os.access lets write anywhere)
        with pytest.raises(OutputError, match="locked: cannot write into the folder"):
            check_map_folder(locked)
    finally:
        locked.chmod(0o755)
    assert _scans_in(locked) == 20


def test_a_partial_result_says_why(tmp_path: Path) -> None:
    result = fake_result(n_scans=30)
    result.partial_reason = "RuntimeError at scan 29: boom"
    result.interrupted = True
    result.warnings = ["optimiser: indeterminate; re-anchored x3 and went on"]
    write_slam_outputs(result, tmp_path / "m", _info())
    summary = json.loads((tmp_path / "m" / "summary.json").read_text())
    assert summary["partial"] is True and summary["partial_reason"] == result.partial_reason
    assert summary["warnings"] == result.warnings
    assert (
        "Interrupted (RuntimeError at scan 29: boom)" in (tmp_path / "m" / "report.md").read_text()
    )
    write_slam_outputs(fake_result(n_scans=30), tmp_path / "m", _info())
    summary = json.loads((tmp_path / "m" / "summary.json").read_text())
    assert summary["partial"] is False and summary["partial_reason"] is None


def test_closure_numbers_and_ms_per_scan_come_from_one_place() -> None:
    """The closure numbers of summary.json's counts, its closures section and report.md are
    one set, from the closures themselves (the front end's counters disagreed with them);
    ms per scan is mean, p95 and max everywhere (one slow scan puts the mean above p95)."""
    from laser_corners.viz.slam_report import slam_markdown

    result = fake_result()
    result.counts.update(closures_proposed=6, closures_accepted=3, closures_rejected=3)
    result.ms_per_scan[0] = 500.0
    summary = slam_summary(result, SlamRunInfo("in.bag", 1.0, 100.0))
    closures, counts, timings = summary["closures"], summary["counts"], summary["timings"]
    assert (closures["proposed"], closures["accepted"], closures["rejected"]) == (4, 2, 2)
    assert (counts["closures_proposed"], counts["closures_accepted"]) == (4, 2)
    assert counts["closures_rejected"] == 2
    assert timings["ms_per_scan_max"] == 500.0
    assert timings["ms_per_scan_mean"] > timings["ms_per_scan_p95"]
    report = slam_markdown(summary)
    assert "| loop closures proposed / accepted / rejected | 4 / 2 / 2 |" in report
    mean, p95 = timings["ms_per_scan_mean"], timings["ms_per_scan_p95"]
    assert f"| ms per scan mean / p95 / max | {mean:.2f} / {p95:.2f} / 500.00 |" in report
