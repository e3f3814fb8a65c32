"""``laser-corners simulate``: writes its files, refuses a bad sensor and nonsense numbers in one
line."""

from __future__ import annotations

import pytest
from typer.testing import CliRunner

from laser_corners.cli import app


def test_cli_simulate_writes_files_and_reports_bad_sensor(tmp_path) -> None:
    runner = CliRunner()
    out = tmp_path / "s"
    result = runner.invoke(
        app, ["simulate", "-o", str(out), "--scans", "5", "--world", "l_room", "--noise", "0.01"]
    )
    assert result.exit_code == 0, result.output
    assert {p.name for p in out.iterdir()} == {"scans.npz", "truth.npz", "scans.bag"}
    assert "l_room" in result.output
    bad = runner.invoke(app, ["simulate", "-o", str(out), "--sensor", "lms"])
    assert bad.exit_code == 2
    assert "unknown sensor 'lms'" in bad.output


@pytest.mark.parametrize(("option", "value"), [("--noise", "-1"), ("--speed", "nan")])
def test_cli_simulate_rejects_nonsense_in_one_line(tmp_path, option: str, value: str) -> None:
    out = tmp_path / "sim"
    result = CliRunner().invoke(app, ["simulate", "-o", str(out), "--scans", "3", option, value])
    assert result.exit_code == 2, result.output
    assert result.output.count("\n") == 1 and option in result.output
    assert "must be >= 0" in result.output or "must be a finite number" in result.output
    assert not out.exists()
