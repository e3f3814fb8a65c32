"""Accuracy benchmark on simulated scans, noise estimation, the fig. 1/fig. 2 helpers."""

from __future__ import annotations

import math

import numpy as np
import pytest
from typer.testing import CliRunner

from laser_corners import CornerDetector
from laser_corners.cli import app
from laser_corners.eval.accuracy import (
    AccuracyStats,
    default_methods,
    make_cases,
    markdown_table,
    match_scan,
    run_sweep,
)
from laser_corners.sim import UST_10LX
from laser_corners.viz.report import write_accuracy_report


def test_match_scan_counts_found_false_and_duplicates() -> None:
    visible = np.array([[1.0, 0.0], [0.0, 2.0]])
    all_corners = np.vstack([visible, [[5.0, 5.0]]])
    keypoints = np.array(
        [
            [1.01, 0.0],  # finds corner 0 (10 mm)
            [1.0, 0.05],  # a duplicate of corner 0
            [5.0, 5.02],  # near a corner that is not visible: neither found nor false
            [3.0, 3.0],  # false
        ]
    )
    m = match_scan(keypoints, visible, all_corners, match_radius=0.1)
    assert (m.n_visible, m.n_found, m.n_keypoints, m.n_false, m.n_on_found) == (2, 1, 4, 1, 2)
    assert m.errors == pytest.approx([0.01])


def test_match_scan_is_one_to_one() -> None:
    # one keypoint between two close corners finds only one of them
    visible = np.array([[0.0, 0.0], [0.12, 0.0]])
    m = match_scan([[0.06, 0.0]], visible, visible, match_radius=0.1)
    assert m.n_found == 1
    m = match_scan(np.zeros((0, 2)), visible, visible)
    assert (m.n_found, m.n_false, m.n_keypoints) == (0, 0, 0)


def test_stats_rates() -> None:
    s = AccuracyStats("x", 0.01)
    s.add(match_scan([[0, 0], [1, 1]], [[0, 0], [2, 2]], [[0, 0], [2, 2]]))
    s.add(match_scan([[2, 2.004]], [[2, 2]], [[2, 2]]))
    assert s.recall == pytest.approx(2 / 3)
    assert s.false_rate == pytest.approx(1 / 3)
    assert s.false_per_scan == pytest.approx(0.5)
    assert s.error_quantile(0.5) == pytest.approx(0.002)
    assert s.keypoints_per_corner == pytest.approx(1.0)
    assert math.isnan(AccuracyStats("y", 0.0).recall)


def test_small_sweep_paper_and_baseline(tmp_path) -> None:
    cases = make_cases(4, 3, UST_10LX, seed=3)
    assert all(c.visible.shape[1] == 2 for c in cases)
    # "baseline": the older name of split-and-merge, still accepted
    stats, used = run_sweep(cases, default_methods(["paper", "baseline"]), sigmas=(0.0, 0.02))
    assert [(s.method, s.sigma) for s in stats] == [
        ("paper", 0.0),
        ("split-and-merge", 0.0),
        ("paper", 0.02),
        ("split-and-merge", 0.02),
    ]
    by = {(s.method, s.sigma): s for s in stats}
    assert by["paper", 0.0].n_visible > 20
    assert by["paper", 0.0].recall > 0.9
    assert by["split-and-merge", 0.0].recall > 0.9
    assert by["paper", 0.0].error_quantile(0.5) < 0.005
    # the paper's thresholds: many more false keypoints with noise
    assert by["paper", 0.02].false_rate > by["paper", 0.0].false_rate
    assert isinstance(used["paper"][0.0], CornerDetector)
    paths = write_accuracy_report(stats, tmp_path / "r")
    assert {p.name for p in paths.values()} == {"accuracy.csv", "accuracy.md", "accuracy.png"}
    assert all(p.is_file() for p in paths.values())
    assert markdown_table(stats).count("\n") == 2 + len(stats)


def test_default_methods_rejects_unknown_preset() -> None:
    from laser_corners.errors import InvalidParamsError

    with pytest.raises(InvalidParamsError, match="unknown method 'nope'"):
        default_methods(["nope"])


def test_cli_evaluate_sim_small(tmp_path) -> None:
    out = tmp_path / "e"
    result = CliRunner().invoke(
        app,
        [
            "evaluate",
            "sim",
            "-o",
            str(out),
            "--worlds",
            "2",
            "--poses",
            "2",
            "--noise",
            "0,0.01",
            "--methods",
            "paper,baseline",
        ],
    )
    assert result.exit_code == 0, result.output
    assert {"accuracy.csv", "accuracy.md", "accuracy.png", "config.yaml"} <= {
        p.name for p in out.iterdir()
    }
    assert "split-and-merge" in result.output and "paper" in result.output
    bad = CliRunner().invoke(app, ["evaluate", "sim", "-o", str(out), "--noise", "a,b"])
    assert bad.exit_code == 2
    assert "--noise" in bad.output


@pytest.mark.parametrize("name", ["laser_corners.noise", "laser_corners.eval.baselines"])
def test_docstring_examples(name: str) -> None:
    import doctest
    import importlib

    result = doctest.testmod(importlib.import_module(name), optionflags=doctest.ELLIPSIS)
    assert result.attempted > 0 and result.failed == 0
