"""Place recognition (FLIRT's protocol): metric, window, revisits, end to end and CLI."""

from __future__ import annotations

import itertools
import json
import math

import numpy as np
import pytest
from typer.testing import CliRunner

from laser_corners.cli import app
from laser_corners.errors import InputError, InvalidParamsError, OutputError
from laser_corners.eval.loops import (
    LOOPS_MATCH,
    LoopsConfig,
    evaluate_loops,
    loop_bank,
    loop_detectors,
    precision_recall,
)
from laser_corners.eval.revisits import revisits, travel_distance
from laser_corners.io.arrays import write_scans_npz
from laser_corners.matching import describe, register_keypoints, register_pairs
from laser_corners.scan import LaserScan, compose, invert
from laser_corners.sim import UST_10LX, World
from laser_corners.viz.loops_report import check_output_dir, write_loops_report

JSON_KEYS = {"precision", "recall", "min_inliers", "queries", "ms_per_pair"}


def _world() -> World:
    """A 14 x 10 m hall with notched walls and square pillars: many distinct corners."""
    world = World(name="loop hall")
    world.add_polygon(
        [
            [0, 0],
            [6, 0],
            [6, -0.8],
            [7.5, -0.8],
            [7.5, 0],
            [14, 0],
            [14, 4],
            [14.7, 4],
            [14.7, 5.5],
            [14, 5.5],
            [14, 10],
            [8, 10],
            [8, 10.6],
            [6.5, 10.6],
            [6.5, 10],
            [0, 10],
            [0, 6],
            [-0.6, 6],
            [-0.6, 3.5],
            [0, 3.5],
        ]
    )
    for cx, cy, h in ((3.5, 5.2, 0.4), (10.5, 5.0, 0.5), (7.0, 3.0, 0.3), (7.2, 7.0, 0.35)):
        world.add_polygon([[cx - h, cy - h], [cx + h, cy - h], [cx + h, cy + h], [cx - h, cy + h]])
    return world


def _loop_poses(step: float = 0.35) -> np.ndarray:
    """A rectangular loop (2, 2) -> (12, 2) -> (12, 8) -> (2, 8) -> back, then 1.5 m more."""
    corners = np.array([[2.0, 2.0], [12.0, 2.0], [12.0, 8.0], [2.0, 8.0], [2.0, 2.0], [3.5, 2.0]])
    poses = []
    for a, b in itertools.pairwise(corners):
        n = max(1, round(float(np.hypot(*(b - a))) / step))
        heading = math.atan2(b[1] - a[1], b[0] - a[0])
        for t in np.arange(n) / n:
            p = a + t * (b - a)
            poses.append((p[0], p[1], heading))
    poses.append((3.5, 2.0, 0.0))
    return np.array(poses)


@pytest.fixture(scope="module")
def loop_scans() -> list[LaserScan]:
    world = _world()
    rng = np.random.default_rng(3)
    return [
        world.scan(tuple(p), UST_10LX, noise_sigma=0.005, rng=rng, stamp=0.1 * i)
        for i, p in enumerate(_loop_poses())
    ]


# ------------------------------------------------------------------ metric
def test_precision_recall_hand_made_case() -> None:
    inliers = np.array([9, 7, 7, 5, 3, 0])
    correct = np.array([True, True, False, True, True, False])
    revisit = np.array([True, True, True, False, True, False])
    pr = precision_recall(inliers, correct, revisit, [3, 6, 8, 10])
    assert pr["detections"].tolist() == [5, 3, 1, 0]
    assert pr["correct"].tolist() == [4, 2, 1, 0]
    # precision = correct / detections; no detection at T=10: NaN
    assert pr["precision"][:3] == pytest.approx([4 / 5, 2 / 3, 1.0])
    assert math.isnan(pr["precision"][3])
    # recall = correct detections of revisit queries / 4 revisit queries (query 3 has none)
    assert pr["recall"] == pytest.approx([3 / 4, 2 / 4, 1 / 4, 0.0])


def test_precision_recall_without_revisits_and_bad_shapes() -> None:
    pr = precision_recall(np.array([5]), np.array([True]), np.array([False]), [2])
    assert pr["precision"][0] == 1.0 and pr["recall"][0] == 0.0
    with pytest.raises(ValueError, match="one entry per query"):
        precision_recall(np.array([5, 1]), np.array([True]), np.array([False]), [2])


# ------------------------------------------------------------------ revisits
def test_revisits_found_only_after_the_loop(loop_scans: list[LaserScan]) -> None:
    rev = revisits(loop_scans, window_travel=5.0, overlap=0.5)
    travel = travel_distance(np.array([s.pose for s in loop_scans]))
    last = len(loop_scans) - 1
    # the last scans are back at the start: their revisit is one of the first scans
    assert rev[last] >= 0 and travel[rev[last]] < 2.0
    assert np.all((rev < 0) | (np.abs(travel[np.maximum(rev, 0)] - travel) >= 5.0))
    # a window longer than the whole loop leaves no revisit at all
    assert np.all(revisits(loop_scans, window_travel=travel[-1] + 1.0) < 0)


# ------------------------------------------------------------------ matcher
def test_loop_matcher_recovers_the_relative_pose(loop_scans: list[LaserScan]) -> None:
    """evaluate loops' pairs go through laser_corners.matching (register_pairs, scan check)."""
    detect = loop_detectors(["paper"], loop_scans[0])["paper"]
    kps = detect(loop_scans)
    bank = loop_bank(loop_scans, kps, LoopsConfig())
    last = len(loop_scans) - 1
    cands = np.arange(0, last - 20)
    res = register_pairs(bank, np.full(cands.shape, last), cands, LOOPS_MATCH)
    k = 4  # (3.5, 2, 0) against the scan at (3.4, 2, 0)
    assert res.accepted[k] and res.n_inliers[k] >= 4 and res.agreement[k] > 0.8
    truth = loop_scans[last].pose
    assert truth is not None
    # every accepted registration of this hall is right (the scan check rejects the others)
    assert res.accepted.sum() >= 3
    for j in np.flatnonzero(res.accepted):
        est = compose(loop_scans[cands[j]].pose, invert(tuple(res.poses[j])))  # type: ignore[arg-type]
        assert math.hypot(est[0] - truth[0], est[1] - truth[1]) < 0.1, j
        assert abs(math.remainder(est[2] - truth[2], math.tau)) < math.radians(2.0), j
    # the batch is the pairwise call, pair by pair
    desc = [describe(s, kp) for s, kp in ((loop_scans[last], kps[last]), (loop_scans[k], kps[k]))]
    single = register_keypoints(
        kps[last], desc[0], kps[k], desc[1], LOOPS_MATCH, loop_scans[last], loop_scans[k]
    )
    assert single.accepted and single.n_inliers == res.n_inliers[k]
    assert np.allclose(single.pose, res.poses[k]) and single.agreement == res.agreement[k]


# ------------------------------------------------------------------ end to end
def test_evaluate_loops_finds_the_known_revisit(loop_scans: list[LaserScan], tmp_path) -> None:
    config = LoopsConfig(methods=("paper", "falko-like"), min_inliers=4)
    seen: list[str] = []
    written: list[list[str]] = []
    result = evaluate_loops(
        loop_scans,
        config,
        "sim",
        progress=lambda stage, done, total: seen.append(stage),
        on_method=lambda partial: written.append(list(partial.methods)),
    )
    assert written == [["paper"], ["paper", "falko-like"]]
    assert "paper: matching" in seen
    last = len(loop_scans) - 1
    assert result.has_revisit[last]
    paper = result.methods["paper"]
    assert paper.best_inliers[last] >= 4 and paper.correct[last]
    assert paper.position_error[last] < 0.05
    assert travel_distance(np.array([s.pose for s in loop_scans]))[paper.best_candidate[last]] < 2
    summary = result.summary()
    assert set(summary) == {"methods"} and set(summary["methods"]) == {"paper", "falko-like"}
    row = summary["methods"]["paper"]
    assert set(row) == JSON_KEYS and row["queries"] == len(loop_scans) and row["min_inliers"] == 4
    assert row["recall"] > 0 and row["precision"] is not None and row["precision"] > 0.5
    paths = write_loops_report(result, tmp_path / "out")
    assert json.loads(paths["loops.json"].read_text()) == json.loads(json.dumps(summary))
    assert paths["precision_recall.png"].stat().st_size > 1000
    assert "| paper |" in paths["loops.md"].read_text()


def test_bad_input_and_options(loop_scans: list[LaserScan], tmp_path) -> None:
    with pytest.raises(InvalidParamsError, match="unknown method 'foo'"):
        evaluate_loops(loop_scans[:5], LoopsConfig(methods=("foo",)))
    with pytest.raises(InvalidParamsError, match="thresholds"):
        LoopsConfig(thresholds=(0, 2))
    no_pose = [
        LaserScan(s.ranges, s.angle_min, s.angle_increment, s.range_min, s.range_max)
        for s in loop_scans[:3]
    ]
    with pytest.raises(InputError, match="fewer than two scans with a pose"):
        evaluate_loops(no_pose, LoopsConfig(methods=("paper",)), "x.npz")
    blocker = tmp_path / "file"
    blocker.write_text("x")
    with pytest.raises(OutputError, match="exists and is not a folder"):
        check_output_dir(blocker)


def test_cli_evaluate_loops(loop_scans: list[LaserScan], tmp_path) -> None:
    log = tmp_path / "loop.npz"
    write_scans_npz(log, loop_scans)
    out = tmp_path / "report"
    args = ["evaluate", "loops", str(log), "-o", str(out), "--methods", "paper,split-and-merge"]
    result = CliRunner().invoke(app, [*args, "--min-inliers", "4"])
    assert result.exit_code == 0, result.output
    data = json.loads((out / "loops.json").read_text())
    assert set(data["methods"]) == {"paper", "split-and-merge"}
    assert all(set(v) == JSON_KEYS for v in data["methods"].values())
    assert data["methods"]["paper"]["queries"] == len(loop_scans)
    assert data["methods"]["paper"]["recall"] > 0
    assert (out / "precision_recall.png").is_file() and (out / "loops.md").is_file()
    # an output path that is a file: one line, exit 2
    result = CliRunner().invoke(app, ["evaluate", "loops", str(log), "-o", str(log)])
    assert result.exit_code == 2
    assert "is a file; --output needs a folder" in result.output  # as evaluate real, sim
    result = CliRunner().invoke(
        app, ["evaluate", "loops", str(log), "-o", str(out), "--methods", "nope"]
    )
    assert result.exit_code == 2 and "unknown method 'nope'" in result.output


def test_one_inlier_threshold_and_config_checks(loop_scans: list[LaserScan]) -> None:
    config = LoopsConfig(methods=("paper",), min_inliers=1)
    result = evaluate_loops(loop_scans, config, "sim")
    paper = result.methods["paper"]
    detected = paper.best_inliers >= 1
    # detections are accepted registrations only, and in this hall all of them are right
    assert detected.sum() >= 5 and paper.correct[detected].all()
    assert np.all(paper.best_candidate[~detected] == -1)
    with pytest.raises(InvalidParamsError, match=r"descriptor: input should be .bsc. or .csc."):
        LoopsConfig(descriptor="sift")
    with pytest.raises(InvalidParamsError, match="min_inliers"):
        LoopsConfig(min_inliers=0)
