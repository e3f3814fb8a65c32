"""CSV and Parquet keypoint tables: rows, incremental writes, temporary names, interruptions."""

from __future__ import annotations

import csv
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from conftest import random_keypoints, real_file, run_until_killed
from laser_corners import CornerDetector, Keypoints, LaserScan
from laser_corners.errors import OutputError
from laser_corners.io import (
    WriterSummary,
    open_keypoint_writer,
    open_scans,
)
from laser_corners.io.writers import MAP_COLUMNS, TABLE_COLUMNS
from laser_corners.pipeline import detect_recording
from laser_corners.scan import transform_points


def _scans_withrandom_keypoints(n: int) -> list[tuple[LaserScan, Keypoints]]:
    out = []
    for i in range(n):
        pose = None if i == 2 else (float(i), -1.0, 0.3 * i)
        scan = LaserScan(np.ones(10), 0.0, 0.1, stamp=100.0 + i, frame_id="laser", pose=pose)
        out.append((scan, random_keypoints(i % 3, seed=i)))
    return out


@pytest.mark.parametrize("suffix", [".csv", ".parquet"])
def test_table_rows_match_therandom_keypoints(tmp_path: Path, suffix: str) -> None:
    items = _scans_withrandom_keypoints(7)
    path = tmp_path / f"k{suffix}"
    # the table writers do not use the source
    with open_keypoint_writer(path, None, with_map=True, flush_every=2) as writer:  # type: ignore[arg-type]
        for i, (scan, kps) in enumerate(items):
            writer.write(i, scan, kps)
    if suffix == ".csv":
        with path.open() as handle:
            rows = list(csv.DictReader(handle))
        columns = list(rows[0])
        get = lambda name: np.array([float(r[name]) if r[name] else np.nan for r in rows])  # noqa: E731
    else:
        table = pq.read_table(path)
        columns = table.column_names
        assert pq.ParquetFile(path).metadata.num_row_groups > 1  # written incrementally
        get = lambda name: table.column(name).to_numpy(zero_copy_only=False).astype(float)  # noqa: E731
    assert columns == list(TABLE_COLUMNS + MAP_COLUMNS)
    expected = [(i, scan, kps) for i, (scan, kps) in enumerate(items) for _ in range(len(kps))]
    assert len(get("x")) == len(expected) == writer.n_keypoints
    np.testing.assert_array_equal(get("scan_index"), [e[0] for e in expected])
    np.testing.assert_array_equal(get("stamp"), [e[1].stamp for e in expected])
    all_kps = [(kps, j) for _, (_, kps) in enumerate(items) for j in range(len(kps))]
    np.testing.assert_array_equal(get("x"), [k.xy[j, 0] for k, j in all_kps])
    np.testing.assert_array_equal(
        get("opening_angle_deg"), [k.opening_angle_deg[j] for k, j in all_kps]
    )
    np.testing.assert_array_equal(get("n_merged"), [k.n_merged[j] for k, j in all_kps])
    map_x = get("map_x")
    no_pose = np.array([scan.pose is None for _, scan, _ in expected])
    assert no_pose.any() and np.isnan(map_x[no_pose]).all() and not np.isnan(map_x[~no_pose]).any()
    first = items[1]  # scan 1 has a pose and one keypoint
    start = sum(len(k) for _, k in items[:1])
    assert map_x[start] == pytest.approx(first[1].transformed(first[0].pose).xy[0, 0])


def test_csv_rows_are_on_disk_before_close_under_a_temporary_name(tmp_path: Path) -> None:
    path = tmp_path / "k.csv"
    writer = open_keypoint_writer(path, None, with_map=False, flush_every=1)  # type: ignore[arg-type]
    scan = LaserScan(np.ones(10), 0.0, 0.1, stamp=1.0)
    writer.write(0, scan, random_keypoints(3))
    running = writer.summary()
    assert not running.complete and running.n_scans == 1 and running.n_keypoints == 3
    assert running.path is not None and running.path.parent == tmp_path
    assert running.path.name.startswith("k.") and running.path.name.endswith(".partial.csv")
    assert len(running.path.read_text().splitlines()) == 4  # header + 3 rows, not closed yet
    assert not path.exists()  # the final name appears only when complete
    writer.close()
    assert writer.summary() == WriterSummary(path, 1, 3, True)
    assert len(path.read_text().splitlines()) == 4 and not running.path.exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["k.csv"]


def test_interrupted_run_keeps_a_readable_parquet(tmp_path: Path) -> None:
    scans = list(open_scans(real_file("intel-corrected.clf.gz")))[:300]

    class Interrupting:
        path, kind, topic, skipped, skip_examples, position = (
            Path("x"),
            "npz",
            None,
            {},
            [],
            "row 0",
        )

        def __iter__(self) -> Iterator[LaserScan]:
            for i, scan in enumerate(scans):
                if i == 250:
                    raise KeyboardInterrupt
                self.position = f"row {i}"
                yield scan

    path = tmp_path / "k.parquet"
    writer = open_keypoint_writer(path, None, with_map=True, flush_every=100)  # type: ignore[arg-type]
    summary = detect_recording(Interrupting(), CornerDetector(), writer)  # type: ignore[arg-type]
    assert summary.interrupted and summary.n_scans == 250 and summary.position == "row 249"
    table = pq.read_table(path)
    assert table.num_rows == summary.n_keypoints > 0
    assert table.column("scan_index").to_numpy().max() <= 249
    # Ctrl-C: the file is finished and renamed, nothing else is left in the folder
    assert writer.summary() == WriterSummary(path, 250, summary.n_keypoints, True)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["k.parquet"]


@pytest.mark.parametrize("suffix", [".csv", ".parquet"])
def test_write_many_writes_what_write_writes(tmp_path: Path, suffix: str) -> None:
    items = _scans_withrandom_keypoints(7)
    one_by_one, chunked = tmp_path / f"a{suffix}", tmp_path / f"b{suffix}"
    with open_keypoint_writer(one_by_one, None, with_map=True, flush_every=2) as writer:  # type: ignore[arg-type]
        for i, (scan, kps) in enumerate(items):
            writer.write(i, scan, kps)
    with open_keypoint_writer(chunked, None, with_map=True, flush_every=2) as chunk_writer:  # type: ignore[arg-type]
        for start, stop in ((0, 3), (3, 4), (4, 7)):
            part = items[start:stop]
            chunk_writer.write_many(start, [s for s, _ in part], [k for _, k in part])
    assert (chunk_writer.n_scans, chunk_writer.n_keypoints) == (writer.n_scans, writer.n_keypoints)
    assert writer.n_keypoints > 0
    if suffix == ".csv":
        assert chunked.read_text() == one_by_one.read_text()
    else:
        assert pq.read_table(chunked).equals(pq.read_table(one_by_one))
    with pytest.raises(ValueError, match="2 scans but 1 keypoint sets"):
        chunk_writer.write_many(0, [items[0][0], items[1][0]], [items[0][1]])


_KILLED_WRITER = """
import sys, time
from pathlib import Path
import numpy as np
sys.path.insert(0, sys.argv[2])
from conftest import random_keypoints
from laser_corners import LaserScan
from laser_corners.io import open_keypoint_writer
writer = open_keypoint_writer(Path(sys.argv[1]), None, with_map=False, flush_every=1)
for i in range(5):
    writer.write(i, LaserScan(np.ones(10), 0.0, 0.1, stamp=float(i)), random_keypoints(3, i))
print(writer.summary().path, flush=True)
time.sleep(120)
"""


@pytest.mark.parametrize("suffix", [".csv", ".parquet"])
def test_a_killed_writer_leaves_only_its_temporary_file(tmp_path: Path, suffix: str) -> None:
    path = tmp_path / f"k{suffix}"
    temporary = Path(run_until_killed(_KILLED_WRITER, str(path), str(Path(__file__).parents[1])))
    assert not path.exists()  # never a half-written file under the final name
    assert [p.name for p in tmp_path.iterdir()] == [temporary.name]
    assert temporary.name.startswith("k.") and temporary.name.endswith(f".partial{suffix}")
    if suffix == ".csv":  # rows flushed every scan are there
        assert len(temporary.read_text().splitlines()) == 1 + 5 * 3
    else:  # the row groups are there, the footer is not: not a Parquet file
        with pytest.raises(pa.ArrowInvalid):
            pq.read_table(temporary)


def test_outputs_in_a_missing_folder_are_one_clear_output_error(tmp_path: Path) -> None:
    for suffix in (".csv", ".parquet"):
        path = tmp_path / "missing" / f"k{suffix}"
        with pytest.raises(OutputError, match=r"k\.\w+: the folder .*missing does not exist"):
            open_keypoint_writer(path, None, with_map=False)  # type: ignore[arg-type]


def test_map_xy_is_keypoints_transformed_bit_for_bit() -> None:
    rng = np.random.default_rng(3)
    for seed in range(20):
        keypoints = random_keypoints(1 + seed, seed=seed)
        pose = tuple(float(v) for v in rng.uniform(-50.0, 50.0, 3))
        assert np.array_equal(transform_points(keypoints.xy, pose), keypoints.transformed(pose).xy)
