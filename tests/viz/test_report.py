"""Report folders drawn by ``viz.report`` (eval returns data only; viz draws and writes)."""

from __future__ import annotations

import json
import math
import subprocess
import sys
import warnings
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

from laser_corners.eval.accuracy import default_methods, make_cases, run_sweep
from laser_corners.eval.real import evaluate_real
from laser_corners.eval.real_summary import headline
from laser_corners.scan import LaserScan
from laser_corners.sim import UST_10LX
from laser_corners.viz.report import write_accuracy_report, write_real_report

PNG = b"\x89PNG\r\n\x1a\n"


def test_accuracy_report_files_and_no_pyplot_state(tmp_path: Path) -> None:
    cases = make_cases(2, 2, UST_10LX, seed=1)
    stats, _ = run_sweep(cases, default_methods(["paper", "split-and-merge"]), sigmas=(0.0,))
    before = plt.get_fignums()
    paths = write_accuracy_report(stats, tmp_path / "acc")
    assert plt.get_fignums() == before  # figures are not left open in pyplot
    assert {p.name for p in paths.values()} == {"accuracy.csv", "accuracy.md", "accuracy.png"}
    assert paths["plot"].read_bytes()[:8] == PNG
    assert "split-and-merge" in paths["markdown"].read_text()


def test_importing_the_report_writer_leaves_the_backend_alone() -> None:
    code = (
        "import matplotlib; matplotlib.use('svg'); import laser_corners.viz.report; "
        "import laser_corners.eval.real; print(matplotlib.get_backend())"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "svg"


def test_eval_never_imports_viz() -> None:
    """eval is below viz: importing every eval module must not load a viz module."""
    code = (
        "import sys, importlib, pkgutil, laser_corners.eval as e\n"
        "for m in pkgutil.iter_modules(e.__path__):\n"
        "    importlib.import_module('laser_corners.eval.' + m.name)\n"
        "print(json.dumps(sorted(k for k in sys.modules if k.startswith('laser_corners.viz'))))"
    )
    out = subprocess.run(
        [sys.executable, "-c", "import json\n" + code], capture_output=True, text=True, check=True
    )
    assert json.loads(out.stdout) == []


def test_real_report_without_any_feature(tmp_path: Path) -> None:
    """A corridor of straight walls: no keypoint, no feature, no pair; still a clean report."""
    scans = [
        LaserScan(
            np.full(181, 2.0),
            -math.pi / 2,
            math.radians(1.0),
            0.05,
            30.0,
            stamp=float(k),
            pose=(0.1 * k, 0.0, 0.0),
        )
        for k in range(30)
    ]
    result = evaluate_real(scans)
    assert len(result.features) == 0
    assert result.warnings[0].startswith("only 0 persistent feature(s)")
    assert "not enough evidence" in headline(result)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no matplotlib complaint about an empty matrix
        paths = write_real_report(result, tmp_path / "r")
    info = json.loads(paths["summary.json"].read_text())
    assert info["association"]["max_std"] is None
    assert all(row["repeatability_r0.05"] is None for row in info["repeatability"]["rows"])
