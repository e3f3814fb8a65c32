"""The install the README gives runs every command the README shows (issue 32, item 11)."""

from __future__ import annotations

import re

import tomllib

from conftest import REPO_ROOT


def _requirement_names(requirements: list[str]) -> set[str]:
    return {re.split(r"[<>=!~;\[ ]", r, maxsplit=1)[0].lower() for r in requirements}


def test_the_readme_install_runs_the_slam_commands_it_shows() -> None:
    """README shows ``laser-corners slam`` and ``localise`` (gtsam's back end); its install
    line (``pip install .``, what ``make demo`` installs) must bring gtsam."""
    project = tomllib.loads((REPO_ROOT / "pyproject.toml").read_text())["project"]
    readme = (REPO_ROOT / "README.md").read_text()
    install = readme[readme.index("## Install") :]
    assert "\npip install .  " in install
    assert re.search(r"^laser-corners slam ", readme, re.M)
    assert re.search(r"laser-corners localise ", readme)
    assert "gtsam" in _requirement_names(project["dependencies"])
