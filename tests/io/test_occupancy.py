"""map_server maps: PGM values, YAML fields, round trip, errors."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml

from laser_corners.errors import InputError
from laser_corners.io.occupancy import OccupancyGrid, read_map, write_map


def _grid() -> OccupancyGrid:
    occupancy = np.full((4, 6), -1, dtype=np.int8)
    occupancy[0, :] = 100  # bottom row: occupied
    occupancy[1, 1:5] = 0  # free
    occupancy[2, 2] = 30  # uncertain: written unknown
    occupancy[3, 5] = 70  # occupied
    return OccupancyGrid(occupancy, 0.05, (-1.5, 2.0, 0.0))


def test_pgm_is_p5_with_map_saver_values_top_row_first(tmp_path: Path) -> None:
    _, pgm_path = write_map(_grid(), tmp_path / "map.yaml")
    assert pgm_path == tmp_path / "map.pgm"
    data = pgm_path.read_bytes()
    assert data.startswith(b"P5\n")
    pixels = np.frombuffer(data[-24:], dtype=np.uint8).reshape(4, 6)
    assert data[:-24].rstrip().endswith(b"6 4\n255")
    assert pixels[3].tolist() == [0] * 6  # the bottom row of the map is the last image row
    assert pixels[2].tolist() == [205, 254, 254, 254, 254, 205]
    assert pixels[1, 2] == 205 and pixels[0, 5] == 0
    assert set(np.unique(pixels)) == {0, 205, 254}


def test_yaml_has_the_map_server_fields(tmp_path: Path) -> None:
    yaml_path, _ = write_map(_grid(), tmp_path / "map.yaml")
    meta = yaml.safe_load(yaml_path.read_text())
    assert meta == {
        "image": "map.pgm",
        "resolution": 0.05,
        "origin": [-1.5, 2.0, 0.0],
        "negate": 0,
        "occupied_thresh": 0.65,
        "free_thresh": 0.196,
    }
    assert not list(tmp_path.glob("*.partial*"))


def test_round_trip_reads_as_map_server_does(tmp_path: Path) -> None:
    grid = _grid()
    yaml_path, _ = write_map(grid, tmp_path / "map.yaml")
    back = read_map(yaml_path)
    assert back.resolution == 0.05 and back.origin == (-1.5, 2.0, 0.0)
    expected = np.full(grid.occupancy.shape, -1)
    expected[grid.occupancy >= 65] = 100
    expected[(grid.occupancy >= 0) & (grid.occupancy <= 25)] = 0
    np.testing.assert_array_equal(back.occupancy, expected)
    assert back.cell(-1.5 + 0.06, 2.0 + 0.01) == (0, 1)
    assert back.extent == pytest.approx((-1.5, -1.2, 2.0, 2.2))


def test_bad_maps_are_one_line_errors(tmp_path: Path) -> None:
    with pytest.raises(InputError, match="no such file"):
        read_map(tmp_path / "none.yaml")
    (tmp_path / "a.yaml").write_text("image: a.pgm\nresolution: 0.05\n")
    with pytest.raises(InputError, match="missing field 'origin'"):
        read_map(tmp_path / "a.yaml")
    (tmp_path / "b.yaml").write_text("image: b.pgm\nresolution: 0.05\norigin: [0, 0, 0]\n")
    with pytest.raises(InputError, match="does not exist"):
        read_map(tmp_path / "b.yaml")
    (tmp_path / "b.pgm").write_bytes(b"P2\n1 1\n255\n0\n")
    with pytest.raises(InputError, match=r"not a binary PGM"):
        read_map(tmp_path / "b.yaml")
    (tmp_path / "b.pgm").write_bytes(b"P5\n4 4\n255\n\x00")
    with pytest.raises(InputError, match="4x4 pixels declared, 1 bytes found"):
        read_map(tmp_path / "b.yaml")
