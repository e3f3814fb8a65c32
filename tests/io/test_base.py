"""The shared pieces of io: outputs under a temporary name, the null writer, text and heads."""

from __future__ import annotations

import gzip
from pathlib import Path

import numpy as np
import pytest

from conftest import random_keypoints
from laser_corners import LaserScan
from laser_corners.errors import InputError, OutputError
from laser_corners.io import KeypointWriter, WriterSummary
from laser_corners.io.base import PartialOutput, open_text, read_head


def test_partial_output_is_renamed_only_when_published(tmp_path: Path) -> None:
    final = tmp_path / "out.parquet"
    partial = PartialOutput(final, overwrite=True)
    assert partial.temporary.exists() and partial.temporary.parent == tmp_path
    assert partial.temporary.name.startswith("out.")
    assert partial.temporary.name.endswith(".partial.parquet")
    partial.temporary.write_text("data")
    final.write_text("old")  # overwritten
    partial.publish()
    assert final.read_text() == "data" and not partial.temporary.exists()


def test_partial_output_refuses_what_it_must_not_overwrite(tmp_path: Path) -> None:
    final = tmp_path / "out.bag"
    final.write_text("there")
    with pytest.raises(OutputError, match=r"out\.bag: exists already"):
        PartialOutput(final, overwrite=False)
    final.unlink()
    partial = PartialOutput(final, overwrite=False, create=False)
    assert not partial.temporary.exists()  # reserved, left for the writer to create
    partial.temporary.write_text("bag")
    final.write_text("appeared meanwhile")
    with pytest.raises(OutputError, match=r"appeared while writing; the output is kept as"):
        partial.publish()
    assert partial.temporary.read_text() == "bag" and final.read_text() == "appeared meanwhile"
    partial.discard()
    assert not partial.temporary.exists()
    with pytest.raises(OutputError, match=r"the folder .*nowhere does not exist"):
        PartialOutput(tmp_path / "nowhere" / "x.csv", overwrite=True)


def test_the_null_writer_counts_and_keeps_nothing() -> None:
    writer = KeypointWriter()
    scan = LaserScan(np.ones(10), 0.0, 0.1, stamp=1.0)
    with writer:
        writer.write_many(0, [scan, scan], [random_keypoints(2), random_keypoints(3)])
        assert writer.summary() == WriterSummary(None, 2, 5, False)
    assert writer.summary() == WriterSummary(None, 2, 5, True)


def test_open_text_reads_plain_and_gzip_and_read_head_names_the_file(tmp_path: Path) -> None:
    plain, packed = tmp_path / "a.log", tmp_path / "a.log.gz"
    plain.write_text("FLASER 1\nODOM 2\n")
    with gzip.open(packed, "wt") as handle:
        handle.write("FLASER 1\nODOM 2\n")
    for path in (plain, packed):
        with open_text(path) as lines:
            assert list(lines) == ["FLASER 1\n", "ODOM 2\n"]
    assert read_head(packed, 2) == b"\x1f\x8b"
    folder = tmp_path / "folder"
    folder.mkdir()
    with pytest.raises(InputError, match=r"folder: cannot read \(Is a directory\)"):
        read_head(folder)


def test_a_path_that_is_already_a_temporary_name_is_written_directly(tmp_path: Path) -> None:
    """``batch`` writes ``X.parquet.partial`` and renames it itself: no second temporary."""
    own = tmp_path / "x.parquet.partial"
    partial = PartialOutput(own, overwrite=True)
    assert partial.temporary == own and list(tmp_path.iterdir()) == []
    own.write_text("rows")
    partial.publish()  # nothing to rename
    assert own.read_text() == "rows" and list(tmp_path.iterdir()) == [own]
