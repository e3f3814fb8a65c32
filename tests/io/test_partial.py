"""Folders written whole (laser_corners.io.partial.staging_folder, publish_folder)."""

from __future__ import annotations

from pathlib import Path

import pytest

import laser_corners.io.partial as partial
from laser_corners.errors import OutputError


@pytest.mark.parametrize("exchange", [True, False])  # renameat2, or two renames
def test_a_folder_is_replaced_whole(tmp_path: Path, monkeypatch, exchange: bool) -> None:
    if not exchange:
        monkeypatch.setattr(partial, "_exchange", lambda a, b: False)
    final = tmp_path / "out"
    staging = partial.staging_folder(final)
    assert staging.parent == tmp_path and staging.name.startswith(".out.")
    (staging / "a.txt").write_text("first\n")
    partial.publish_folder(staging, final)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]
    final.chmod(0o750)
    staging = partial.staging_folder(final)
    assert staging.stat().st_mode & 0o777 == 0o750  # the replaced folder's mode
    (staging / "b.txt").write_text("second\n")
    partial.publish_folder(staging, final)
    assert sorted(p.name for p in final.iterdir()) == ["b.txt"]  # no file of the first
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]  # nothing left aside


def test_a_missing_parent_is_one_line(tmp_path: Path) -> None:
    with pytest.raises(OutputError, match="cannot write in"):
        partial.staging_folder(tmp_path / "no" / "out")
