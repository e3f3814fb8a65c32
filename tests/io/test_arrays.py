"""NPZ and CSV scan arrays: round trips, bad rows, files that are not what they claim."""

from __future__ import annotations

import zipfile
from pathlib import Path

import numpy as np
import pytest

from conftest import damaged_copy, real_file
from laser_corners import InputError, LaserScan
from laser_corners.errors import OutputError
from laser_corners.io import (
    detect_kind,
    open_scans,
)
from laser_corners.io.arrays import write_scans_csv, write_scans_npz


def test_npz_and_csv_round_trip_the_intel_log(tmp_path: Path) -> None:
    scans = list(open_scans(real_file("intel-corrected.clf.gz")))[:50]
    write_scans_npz(tmp_path / "s.npz", scans)
    write_scans_csv(tmp_path / "s.csv", scans)
    for name, kind in (("s.npz", "npz"), ("s.csv", "csv")):
        assert detect_kind(tmp_path / name) == kind
        source = open_scans(tmp_path / name)
        back = list(source)
        assert source.n_scans == len(back) == 50
        for a, b in zip(scans, back, strict=True):
            np.testing.assert_array_equal(a.ranges, b.ranges)
            assert (b.stamp, b.pose, b.frame_id) == (a.stamp, a.pose, a.frame_id)
            assert (b.angle_min, b.angle_increment, b.range_max) == (
                a.angle_min,
                a.angle_increment,
                a.range_max,
            )


def test_csv_bad_rows_are_counted_and_missing_geometry_is_an_error(tmp_path: Path) -> None:
    good = tmp_path / "good.csv"
    good.write_text(
        "# angle_min: -1.0\n# angle_increment: 0.5\n# range_max: 10\n"
        "stamp,r0,r1,r2,r3,r4\n1.0,1,1,1,,nan\n2.0,1,x,1,1,1\n3.0,1,1\n4.0,2,2,2,2,2\n"
    )
    source = open_scans(good)
    scans = list(source)
    assert [s.stamp for s in scans] == [1.0, 4.0]
    assert scans[0].n_gaps == 2
    assert source.skipped == {"malformed row": 1, "wrong number of cells": 1}
    assert source.skip_examples[0].startswith("line 6:")
    bad = tmp_path / "bad.csv"
    bad.write_text("# angle_min: -1.0\nr0,r1,r2\n1,1,1\n")
    with pytest.raises(InputError, match=r"bad\.csv: missing '# angle_increment: value'"):
        open_scans(bad)


def test_npz_without_ranges_or_corrupt_is_an_error(tmp_path: Path) -> None:
    np.savez(tmp_path / "x.npz", angle_min=0.0)
    with pytest.raises(InputError, match="missing array 'ranges'"):
        open_scans(tmp_path / "x.npz")
    scans = list(open_scans(real_file("intel-corrected.clf.gz")))[:5]
    write_scans_npz(tmp_path / "ok.npz", scans)
    damaged_copy(tmp_path / "ok.npz", tmp_path / "cut.npz", keep=200)
    with pytest.raises(InputError, match=r"cut\.npz: not a readable \.npz"):
        open_scans(tmp_path / "cut.npz")


def test_a_zip_that_is_not_an_npz_says_what_it_holds(tmp_path: Path) -> None:
    """Freiburg's killian log ships as a zipped .g2o: say so instead of "missing array"."""
    archive = tmp_path / "killian.g2o.zip"
    with zipfile.ZipFile(archive, "w") as handle:
        handle.writestr("killian.g2o", "VERTEX_SE2 0 0 0 0\n")
    with pytest.raises(InputError) as info:
        open_scans(archive)
    assert str(info.value) == (
        f"{archive}: a zip archive holding killian.g2o, not an .npz; "
        "unzip it and pass the killian.g2o"
    )
    other = tmp_path / "notes.npz"
    with zipfile.ZipFile(other, "w") as handle:
        for i in range(5):
            handle.writestr(f"note{i}.md", "text")
    with pytest.raises(InputError, match=r"holding note0\.md, note1\.md, note2\.md and 2 more, "):
        open_scans(other)


def test_scan_array_writers_write_whole_files_and_name_output_problems(tmp_path: Path) -> None:
    scans = [LaserScan(np.full(5, 1.0 + i), -0.2, 0.1, stamp=float(i)) for i in range(3)]
    write_scans_npz(tmp_path / "plain", scans)  # numpy's rule: .npz appended
    write_scans_csv(tmp_path / "s.csv", scans)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["plain.npz", "s.csv"]
    for name in ("plain.npz", "s.csv"):
        read = list(open_scans(tmp_path / name))
        np.testing.assert_array_equal(read[2].ranges, scans[2].ranges)
    with pytest.raises(OutputError, match=r"empty\.npz: no scans to write"):
        write_scans_npz(tmp_path / "empty.npz", [])
    mixed = [*scans, LaserScan(np.ones(6), -0.2, 0.1)]
    with pytest.raises(OutputError, match=r"mixed\.csv: scans written to one array file must"):
        write_scans_csv(tmp_path / "mixed.csv", mixed)
    with pytest.raises(OutputError, match=r"the folder .*absent does not exist"):
        write_scans_csv(tmp_path / "absent" / "s.csv", scans)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["plain.npz", "s.csv"]


def test_rows_with_a_broken_stamp_or_pose_are_counted_skips(tmp_path: Path) -> None:
    """A NaN or infinite stamp, a NaN pose or a pose 1e300 m away is a counted skip of that
    row (the SLAM's grids and kernels would crash on it), in NPZ and CSV alike."""
    n = 8
    angles = np.linspace(-1.5, 1.5, 50)
    scans = [
        LaserScan(2.0 + 0.1 * np.cos(angles + i), -1.5, 3.0 / 49, stamp=10.0 + i, pose=(i, 0, 0))
        for i in range(n)
    ]
    write_scans_npz(tmp_path / "s.npz", scans)
    data = dict(np.load(tmp_path / "s.npz"))
    data["stamps"][1] = np.nan
    data["stamps"][2] = np.inf
    data["poses"][4, 1] = np.nan
    data["poses"][5, 0] = 1e300
    np.savez(tmp_path / "bad.npz", **data)
    source = open_scans(tmp_path / "bad.npz")
    kept = list(source)
    assert [s.stamp for s in kept] == [10.0, 13.0, 16.0, 17.0]
    assert sum(source.skipped.values()) == 4, source.skipped
    assert any("stamp" in e for e in source.skip_examples), source.skip_examples
    assert any("1e+300" in e for e in source.skip_examples), source.skip_examples
    write_scans_csv(tmp_path / "s.csv", scans)
    lines = (tmp_path / "s.csv").read_text().splitlines()
    first = next(i for i, line in enumerate(lines) if line.startswith("10.0,"))
    lines[first + 1] = "nan" + lines[first + 1][len("11.0") :]
    lines[first + 3] = lines[first + 3].replace("13.0,3.0,", "13.0,1e300,", 1)
    (tmp_path / "bad.csv").write_text("\n".join(lines) + "\n")
    source = open_scans(tmp_path / "bad.csv")
    assert [s.stamp for s in source] == [10.0, 12.0, 14.0, 15.0, 16.0, 17.0]
    assert sum(source.skipped.values()) == 2, source.skipped
