"""CARMEN logs: the real logs checked against their own lines, layouts, damaged and malformed
input."""

from __future__ import annotations

import gzip
import math
from pathlib import Path

import numpy as np
import pytest

from conftest import damaged_copy, real_file
from laser_corners import InputError
from laser_corners.io import (
    open_scans,
)
from laser_corners.io.carmen import parse_carmen_line

pytestmark = pytest.mark.real


def _robotlaser_lines(path: Path) -> list[list[str]]:
    with gzip.open(path, "rt") as handle:
        return [line.split() for line in handle if line.startswith("ROBOTLASER1")]


def test_intel_corrected_log_matches_its_robotlaser_lines() -> None:
    log = real_file("intel-corrected.clf.gz")
    lines = _robotlaser_lines(log)
    source = open_scans(log)
    assert source.kind == "carmen" and source.n_scans is None
    scans = list(source)
    assert len(scans) == len(lines) == 2672
    assert source.skipped == {}
    for index in (0, 1337, len(lines) - 1):
        tokens, scan = lines[index], scans[index]
        n = int(tokens[8])
        n_rem = int(tokens[9 + n])
        after = 10 + n + n_rem
        assert scan.stamp == pytest.approx(float(tokens[after + 11]), abs=1e-6)
        assert scan.pose == pytest.approx(tuple(float(v) for v in tokens[after : after + 3]))
        ranges = np.array(tokens[9 : 9 + n], dtype=float)
        assert scan.range_max == float(tokens[5]) == 50.0
        # max-range readings (81.83 m here) are no-return gaps
        assert scan.n_gaps == int(np.count_nonzero(ranges >= 50.0))
        assert index != 0 or scan.n_gaps > 0  # the first scan has 81.83 m readings
        assert scan.angle_increment == pytest.approx(math.radians(1.0), rel=1e-4)


def test_truncated_gzip_log_names_the_line(tmp_path: Path) -> None:
    log = real_file("intel-corrected.clf.gz")
    cut = damaged_copy(log, tmp_path / "cut.clf.gz", keep=log.stat().st_size // 2)
    source = open_scans(cut)
    read = 0
    with pytest.raises(
        InputError, match=r"cut\.clf\.gz: truncated gzip stream: the file ends after line \d+"
    ):
        for _ in source:
            read += 1
    assert 0 < read < 2672  # what came before the cut was read


def test_byte_flipped_gzip_log_is_one_clear_error(tmp_path: Path) -> None:
    log = real_file("fr079-corrected.clf.gz")
    flipped = damaged_copy(log, tmp_path / "flip.clf.gz", flip=slice(300_000, 300_016))
    with pytest.raises(InputError, match=r"flip\.clf\.gz: corrupt gzip data.*\(at line \d+\)"):
        list(open_scans(flipped))


def test_malformed_carmen_lines_are_counted_skips(tmp_path: Path) -> None:
    with gzip.open(real_file("fr079-corrected.clf.gz"), "rt") as handle:
        lines = [next(handle) for _ in range(40)]
    laser_rows = [i for i, line in enumerate(lines) if line.startswith("ROBOTLASER1")]
    bad_number, bad_count = laser_rows[2], laser_rows[5]
    tokens = lines[bad_number].split()
    tokens[20] = "1.2.3"
    lines[bad_number] = " ".join(tokens) + "\n"
    lines[bad_count] = " ".join(lines[bad_count].split()[:100]) + "\n"  # cut inside readings
    lines.insert(0, "# a comment\n")
    lines.append("FLASER 3 1.0 2.0\n")
    lines.append("NOTAWORD 1 2 3\n")
    log = tmp_path / "bad.clf"
    log.write_text("".join(lines))
    source = open_scans(log)
    scans = list(source)
    assert len(scans) == len(laser_rows) - 2
    assert source.skipped == {
        "malformed ROBOTLASER1 line": 2,
        "malformed FLASER line": 1,
        "unknown record type": 1,
    }
    # line numbers are 1-based and count the inserted comment
    assert source.skip_examples[0].startswith(f"line {bad_number + 2}: malformed ROBOTLASER1")
    assert source.skip_examples[1].startswith(f"line {bad_count + 2}: malformed ROBOTLASER1")


def test_carmen_flaser_and_rawlaser_layouts() -> None:
    ranges = ["1.0"] * 180 + ["80.0"]
    flaser = parse_carmen_line(
        ["FLASER", "181", *ranges, "1", "2", "0.5", "0", "0", "0", "7.25", "h", "7.3"]
    )
    assert flaser.n_beams == 181 and flaser.pose == (1.0, 2.0, 0.5) and flaser.stamp == 7.25
    assert flaser.angles[-1] == pytest.approx(math.pi / 2)
    assert flaser.n_gaps == 1  # the 80 m reading
    raw = parse_carmen_line(
        [
            "RAWLASER2",
            "0",
            "-1.0",
            "2.0",
            "0.5",
            "30",
            "0.01",
            "0",
            "5",
            *["2"] * 5,
            "0",
            "3.5",
            "h",
            "3.6",
        ]
    )
    assert raw.pose is None and raw.frame_id == "laser2" and raw.n_beams == 5
    assert raw.angles[-1] == pytest.approx(1.0) and raw.stamp == 3.5
