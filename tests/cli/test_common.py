"""Helpers the commands share (:mod:`laser_corners.cli.common`): option values parsed or
refused in one line naming the option (exit 2), output files and folders checked before any
work, and the exit code of a run that stopped early."""

from __future__ import annotations

import math
import os
from pathlib import Path

import pytest
import typer
from rich.text import Text

from laser_corners.cli.app import created_folders
from laser_corners.cli.common import (
    check_number,
    image_file,
    new_folder,
    params_choice,
    parse_pose,
    quoted,
    refuse_overlap,
    stop_exit_code,
    writable_file,
)
from laser_corners.errors import printable


def refused(capsys: pytest.CaptureFixture[str], call, *args) -> str:
    """The one line a refused option prints (exit 2)."""
    with pytest.raises(typer.Exit) as info:
        call(*args)
    assert info.value.exit_code == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1, err
    return err


def test_parse_pose(capsys) -> None:
    assert parse_pose("1, -2.5, 0.3", "--initial-pose") == (1.0, -2.5, 0.3)
    assert parse_pose("[0,0,3.1]", "--initial-pose") == (0.0, 0.0, 3.1)
    assert "expected x,y,yaw numbers" in refused(capsys, parse_pose, "1,a,2", "--initial-pose")
    assert "(3 numbers), got 2" in refused(capsys, parse_pose, "1,2", "--initial-pose")
    assert "finite" in refused(capsys, parse_pose, "nan,0,0", "--initial-pose")
    assert "--initial-pose" in refused(capsys, parse_pose, "1e9,0,0", "--initial-pose")


def test_check_number(capsys) -> None:
    check_number("--noise", None)
    check_number("--noise", 0.0, minimum=0.0)
    assert "--noise must be a finite number" in refused(capsys, check_number, "--noise", math.inf)
    assert "--noise must be >= 0, got -1" in refused(capsys, check_number, "--noise", -1.0, 0.0)


def test_writable_file_makes_its_folder_and_refuses_a_folder(tmp_path: Path, capsys) -> None:
    target = tmp_path / "a" / "b" / "out.csv"
    assert writable_file(target) == target and target.parent.is_dir()
    assert "is a folder; --output needs a file name" in refused(capsys, writable_file, tmp_path)
    blocker = tmp_path / "file"
    blocker.write_text("")
    assert "cannot create the folder" in refused(capsys, writable_file, blocker / "x" / "y.csv")


def test_image_file_takes_the_suffix_or_png(tmp_path: Path, capsys) -> None:
    assert image_file(tmp_path / "map.pdf") == (tmp_path / "map.pdf", "pdf")
    assert image_file(tmp_path / "map") == (tmp_path / "map", "png")
    line = refused(capsys, image_file, tmp_path / "map.docx")
    assert "cannot write '.docx' images" in line and ".png" in line


def test_new_folder_records_what_it_created(tmp_path: Path, capsys) -> None:
    created_folders().clear()
    deep = tmp_path / "x" / "y"
    assert new_folder(deep) == deep and deep.is_dir()
    assert created_folders() == [deep, tmp_path / "x"]  # deepest first
    new_folder(deep)  # already there: nothing more recorded
    assert len(created_folders()) == 2
    created_folders().clear()
    blocker = tmp_path / "file"
    blocker.write_text("")
    assert "is a file; --output needs a folder" in refused(capsys, new_folder, blocker)


def test_refuse_overlap(tmp_path: Path, capsys, monkeypatch) -> None:
    recording = tmp_path / "data" / "run.bag"
    recording.parent.mkdir()
    recording.write_text("")
    refuse_overlap(tmp_path / "out", [recording])  # fine
    line = refused(capsys, refuse_overlap, recording.parent, [recording])
    assert "would write over the input" in line and str(recording) in line
    assert "would write over" in refused(capsys, refuse_overlap, recording / "sub", [recording])
    monkeypatch.chdir(tmp_path)
    assert "needs a folder name" in refused(capsys, refuse_overlap, Path("."), [recording])
    if os.geteuid() != 0:  # root writes anywhere
        locked = tmp_path / "locked"
        locked.mkdir()
        locked.chmod(0o500)
        try:
            assert "cannot write into" in refused(capsys, refuse_overlap, locked / "o", [])
        finally:
            locked.chmod(0o700)


def test_params_choice_refuses_a_preset_and_a_file(tmp_path: Path, capsys) -> None:
    choice = params_choice("auto", None, ["min_points=4"])
    assert choice.preset == "auto" and choice.overrides == ("min_points=4",)
    assert "not both" in refused(capsys, params_choice, "paper", tmp_path / "p.yaml", None)


def test_stop_exit_code_and_quoted() -> None:
    from laser_corners.pipeline.interrupt import STOP_REASONS

    by_signal = {int(signum): text for signum, text in STOP_REASONS.items()}
    assert stop_exit_code(None) == 0 and stop_exit_code("RuntimeError at scan 3: x") == 1
    assert {stop_exit_code(text) for text in by_signal.values()} == {128 + s for s in by_signal}
    # rich shows the text as it is: no markup applied, controls escaped
    for text in ("[bold]a\x1b[0m", "[red]x[/red] [link=y]z"):
        assert Text.from_markup(quoted(text)).plain == printable(text)
    assert "\x1b" not in quoted("\x1b[2J")
