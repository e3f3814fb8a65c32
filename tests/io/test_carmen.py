"""CARMEN logs: the real logs checked against their own lines, layouts, damaged and malformed
input."""

from __future__ import annotations

import gzip
import math
from pathlib import Path

import numpy as np
import pytest

from conftest import damaged_copy, real_file
from laser_corners import CornerDetector, InputError
from laser_corners.io import detect_kind, open_scans
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


def _room_ranges(angles: np.ndarray, sensor=(0.5, 0.2), half=(2.0, 1.5)) -> np.ndarray:
    """Ranges from ``sensor`` to the walls of the box ``|x| <= half[0], |y| <= half[1]``."""
    c, s = np.cos(angles), np.sin(angles)
    with np.errstate(divide="ignore"):
        tx = np.where(c > 0, (half[0] - sensor[0]) / c, (-half[0] - sensor[0]) / c)
        ty = np.where(s > 0, (half[1] - sensor[1]) / s, (-half[1] - sensor[1]) / s)
    return np.minimum(np.abs(tx), np.abs(ty))


def _robotlaser(start: float, res: float, ranges: np.ndarray, stamp: float) -> str:
    n = len(ranges)
    fov = abs(res) * (n - 1)
    readings = " ".join(f"{r:.4f}" for r in ranges)
    pose = "1.0 2.0 0.3 1.0 2.0 0.3 0 0 0.55 0.375 1000000"
    return (
        f"ROBOTLASER1 0 {start!r} {fov!r} {res!r} 30.0 0.1 0 {n} {readings} 0 {pose} "
        f"{stamp} host {stamp}\n"
    )


def test_a_negative_angular_resolution_turns_the_beams_clockwise(tmp_path: Path) -> None:
    """``res < 0``: beam i at ``start + i*res`` (clockwise). The same sweep written
    counter-clockwise (reversed readings, positive res) gives the same points and keypoints."""
    res = math.radians(1.0)
    angles = -math.pi / 2 + res * np.arange(181)
    ranges = _room_ranges(angles)
    ccw, cw = tmp_path / "ccw.clf", tmp_path / "cw.clf"
    ccw.write_text(_robotlaser(-math.pi / 2, res, ranges, 1.0))
    cw.write_text(_robotlaser(math.pi / 2, -res, ranges[::-1], 1.0))
    (a,), (b,) = list(open_scans(ccw)), list(open_scans(cw))
    assert a.angle_increment == pytest.approx(res) and b.angle_increment == pytest.approx(-res)
    assert b.angles[0] == pytest.approx(math.pi / 2) and b.angles[1] < b.angles[0]
    (xy_a, valid_a), (xy_b, _) = a.to_cartesian(), b.to_cartesian()
    assert valid_a.all()
    np.testing.assert_allclose(xy_b, xy_a[::-1], atol=1e-9)
    # the points lie on the walls: the geometry is the room's, not a mirror of it
    on_wall = np.isclose(np.abs(xy_a[:, 0] + 0.5), 2.0, atol=1e-3) | np.isclose(
        np.abs(xy_a[:, 1] + 0.2), 1.5, atol=1e-3
    )
    assert on_wall.all()
    detector = CornerDetector()
    ka, kb = detector.detect(a), detector.detect(b)
    assert len(ka) == len(kb) >= 2  # the two far corners of the room
    order_a, order_b = np.lexsort(ka.xy.T), np.lexsort(kb.xy.T)
    np.testing.assert_allclose(kb.xy[order_b], ka.xy[order_a], atol=1e-9)
    corners = {(round(x + 0.5, 1), round(y + 0.2, 1)) for x, y in ka.xy}
    assert {(2.0, 1.5), (2.0, -1.5)} <= corners


def test_laser_lines_of_a_g2o_file_are_read_and_graph_lines_skipped(tmp_path: Path) -> None:
    """A ``.g2o`` file mixes VERTEX/EDGE/FIX lines with ROBOTLASER1 lines (Freiburg's killian)."""
    res = math.radians(1.0)
    ranges = _room_ranges(-math.pi / 2 + res * np.arange(181))
    lines = [
        "VERTEX_SE2 0 0 0 0\n",
        "FIX 0\n",
        _robotlaser(-math.pi / 2, res, ranges, 10.0),
        "VERTEX_SE2 1 0.5 0 0.1\n",
        "EDGE_SE2 0 1 0.5 0 0.1 500 0 0 500 0 5000\n",
        _robotlaser(-math.pi / 2, res, ranges * 1.01, 11.0),
        "VERTEX_XY 7 1.0 2.0\n",
        "EDGE_SE2_XY 1 7 0.5 1.0 100 0 100\n",
        "PARAMS_SE2OFFSET 0 0 0 0\n",
        _robotlaser(-math.pi / 2, res, ranges * 1.02, 12.0),
    ]
    graph = tmp_path / "killian.g2o"
    graph.write_text("".join(lines))
    assert detect_kind(graph) == "carmen"
    source = open_scans(graph)
    scans = list(source)
    assert [s.stamp for s in scans] == [10.0, 11.0, 12.0]
    assert source.skipped == {} and source.skip_examples == []  # graph lines are no errors
    np.testing.assert_allclose(scans[1].ranges, np.round(ranges * 1.01, 4))
    assert scans[0].pose == pytest.approx((1.0, 2.0, 0.3))
    no_suffix = tmp_path / "graph"
    no_suffix.write_text("".join(lines))
    assert detect_kind(no_suffix) == "carmen"  # VERTEX first: a CARMEN-like file
