"""``--odom-topic``: every command that reads a bag's odometry poses takes it; several Odometry
topics and none chosen print one ``--odom-topic NAME`` line each, as ``--topic`` does."""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from laser_corners.cli import app
from laser_corners.cli.app import error_line
from laser_corners.io import TopicChoiceError
from laser_corners.io.trajectory import read_tum
from sim_drives import TF, write_drive_bag

runner = CliRunner()
SOURCES = {"/odom": (1.0, 0.0, 0.0), "/wheel_odom": (0.0, 0.0, 0.0), TF: (0.0, 2.0, 0.0)}
"""Odometry sources of one drive and their offsets (``/odom`` among them: not preferred)."""


def _invoke(*args: str | Path):
    return runner.invoke(app, [str(a) for a in args])


def _drive(n: int = 40) -> np.ndarray:
    return np.array([(1.5 + 0.05 * i, 1.5, 0.0) for i in range(n)])


@pytest.fixture(scope="module")
def bag(tmp_path_factory: pytest.TempPathFactory) -> Path:
    from laser_corners.sim import World

    world = World().add_polygon([[0, 0], [8, 0], [8, 5], [0, 5]])
    world.add_polygon([[3, 2.4], [3.8, 2.4], [3.8, 3.0], [3, 3.0]])
    world.add_polygon([[5.5, 0.6], [6.1, 0.6], [5.8, 1.2]])
    path = tmp_path_factory.mktemp("odom") / "odom3.bag"
    return write_drive_bag(path, world, _drive(), (0.2, 0.0, 0.0), SOURCES)


def _choice_lines(result) -> list[str]:
    """The ``--odom-topic`` lines of a failed command (after its one error line)."""
    assert result.exit_code == 2, result.output
    assert "Traceback" not in result.stderr
    lines = result.stderr.strip().splitlines()
    errors = [i for i, line in enumerate(lines) if line.startswith("laser-corners: error: ")]
    assert len(errors) == 1, result.stderr
    assert "2 nav_msgs/msg/Odometry topics" in lines[errors[0]], result.stderr
    return [line.strip() for line in lines[errors[0] + 1 :]]


@pytest.mark.parametrize(
    "command",
    [
        ["detect"],
        ["plot", "-o", "{tmp}/scan.png"],
        ["view", "--save", "{tmp}/scans.rrd"],
        ["evaluate", "real", "-o", "{tmp}/real"],
        ["evaluate", "loops", "-o", "{tmp}/loops"],
        ["slam", "-o", "{tmp}/slam"],
    ],
    ids=lambda c: " ".join(w for w in c[:2] if not w.startswith("-")),
)
def test_several_odometry_topics_are_listed_for_every_command(
    bag: Path, tmp_path: Path, command: list[str]
) -> None:
    args = [a.format(tmp=tmp_path) for a in command]
    result = _invoke(args[0], *args[1:2], bag, *args[2:]) if args[0] == "evaluate" else None
    if result is None:
        result = _invoke(args[0], bag, *args[1:])
    assert _choice_lines(result) == ["--odom-topic /odom", "--odom-topic /wheel_odom"]
    assert not (tmp_path / "slam").exists() and not (tmp_path / "real").exists()


def test_an_unknown_odom_topic_is_one_line(bag: Path) -> None:
    result = _invoke("detect", bag, "--odom-topic", "/nope")
    assert result.exit_code == 2, result.output
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("laser-corners: error: "), result.stderr
    assert "'/nope'" in lines[0] and "Odometry topics: /odom, /wheel_odom" in lines[0]


def test_the_choice_lines_escape_non_printable_names() -> None:
    error = TopicChoiceError(
        Path("b.bag"), ["/odom\x1b[2J", "/b"], "nav_msgs/msg/Odometry", "--odom-topic"
    )
    line = error_line(error)
    assert line is not None and "\x1b" not in line
    assert line.splitlines()[1:] == ["  --odom-topic /odom\\x1b[2J", "  --odom-topic /b"]


def _map_columns(path: Path) -> np.ndarray:
    with path.open() as handle:
        rows = list(csv.DictReader(handle))
    return np.array([(float(r["map_x"]), float(r["map_y"])) for r in rows])


def test_detect_map_columns_follow_the_chosen_odometry(bag: Path, tmp_path: Path) -> None:
    found = {}
    for choice in ("/odom", "/wheel_odom", "tf"):
        out = tmp_path / f"{choice.strip('/')}.csv"
        result = _invoke("detect", bag, "--odom-topic", choice, "-o", out)
        assert result.exit_code == 0, result.output
        found[choice] = _map_columns(out)
    assert len(found["tf"]) > 20  # keypoints in every source, the same ones
    # same yaw in every source: the map points move by the offsets between the sources
    np.testing.assert_allclose(
        found["/odom"] - found["/wheel_odom"], [[1.0, 0.0]] * len(found["tf"]), atol=1e-5
    )
    np.testing.assert_allclose(
        found["tf"] - found["/wheel_odom"], [[0.0, 2.0]] * len(found["tf"]), atol=1e-5
    )


def test_slam_and_localise_take_odom_topic(bag: Path, tmp_path: Path) -> None:
    pytest.importorskip("gtsam")
    out = tmp_path / "map"
    result = _invoke("slam", bag, "-o", out, "--odom-topic", "tf", "--set", "loop.enabled=false")
    assert result.exit_code == 0, result.output
    _, odometry = read_tum(out / "odometry.tum")
    drive = _drive() + np.asarray(SOURCES[TF])
    np.testing.assert_allclose(odometry[1:-1, :2], drive[1:-1, :2], atol=1e-6)
    # localise in that map: the same listing without a choice, and a run with one
    loc = tmp_path / "loc"
    result = _invoke("localise", out, bag, "-o", loc)
    assert _choice_lines(result) == ["--odom-topic /odom", "--odom-topic /wheel_odom"]
    result = _invoke(
        "localise",
        out,
        bag,
        "-o",
        loc,
        "--odom-topic",
        "/wheel_odom",
        "--initial-pose",
        "1.5,3.5,0",
    )
    assert result.exit_code == 0, result.output
    assert (loc / "trajectory.tum").is_file()


def test_info_lists_the_odometry_choices(bag: Path) -> None:
    result = _invoke("info", bag)
    assert result.exit_code == 0, result.output
    assert "--odom-topic /odom" in result.stdout and "--odom-topic /wheel_odom" in result.stdout
