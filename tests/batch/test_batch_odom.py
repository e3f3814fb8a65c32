"""``batch --odom-topic``: the odometry of bags with several sources, as ``detect`` takes it."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pyarrow.parquet as pq
import pytest
from typer.testing import CliRunner

from laser_corners.batch import run_batch
from laser_corners.cli import app
from laser_corners.errors import OutputError
from laser_corners.sim import World
from sim_drives import write_drive_bag

SOURCES = {"/odom": (5.0, 0.0, 0.0), "/wheel_odom": (0.0, 0.0, 0.0)}
"""Two odometry sources 5 m apart: the keypoints' map columns tell which one was read."""


def _bag(path: Path) -> Path:
    world = World().add_polygon([[0, 0], [8, 0], [8, 5], [0, 5]])
    world = world.add_polygon([[3, 2], [3.8, 2], [3.8, 2.6], [3, 2.6]])
    drive = np.array([(1.5 + 0.05 * i, 1.2, 0.0) for i in range(12)])
    return write_drive_bag(path, world, drive, (0.2, 0.0, 0.0), SOURCES)


def _map_x(outdir: Path) -> float:
    (table,) = sorted(outdir.glob("*.parquet"))
    return float(np.nanmean(pq.read_table(table).column("map_x").to_numpy()))


def test_batch_takes_the_named_odometry_and_fails_a_bag_with_several_unnamed(
    tmp_path: Path,
) -> None:
    bag = _bag(tmp_path / "two.bag")
    unnamed = run_batch([bag], tmp_path / "unnamed", workers=1)
    assert [r.status for r in unnamed.results] == ["failed"]
    error = unnamed.results[0].error  # one line naming the choices and the option
    assert "\n" not in error and "/odom" in error and "/wheel_odom" in error, error
    assert "--odom-topic" in error, error
    means = {}
    for name in SOURCES:
        outdir = tmp_path / name.strip("/")
        report = run_batch([bag], outdir, workers=1, odom_topic=name)
        assert [r.status for r in report.results] == ["done"], report.results[0].error
        means[name] = _map_x(outdir)
    assert means["/odom"] - means["/wheel_odom"] == pytest.approx(5.0, abs=1e-6)


def test_cli_batch_has_the_odom_topic_option(tmp_path: Path) -> None:
    bag = _bag(tmp_path / "two.bag")
    result = CliRunner().invoke(
        app, ["batch", str(bag), "-o", str(tmp_path / "out"), "-w", "1", "--odom-topic", "tf"]
    )
    assert result.exit_code == 1, result.output  # the job fails: this bag has no /tf odometry
    assert "tf" in result.output


def test_a_folder_made_with_one_odometry_refuses_another(tmp_path: Path) -> None:
    """Resuming with another ``--odom-topic`` would mix two odometries in one folder."""
    bag = _bag(tmp_path / "two.bag")
    outdir = tmp_path / "out"
    assert run_batch([bag], outdir, workers=1, odom_topic="/odom").results[0].status == "done"
    for other in ("/wheel_odom", None):
        with pytest.raises(OutputError, match="another --odom-topic"):
            run_batch([bag], outdir, workers=1, odom_topic=other)
    again = run_batch([bag], outdir, workers=1, odom_topic="/odom")  # the same: resumes
    assert again.results == [] and len(again.already_done) == 1
