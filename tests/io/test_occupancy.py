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


def _foreign(tmp_path: Path, pixels: np.ndarray, **fields) -> Path:
    """A map_server map as another package writes it: ``pixels`` (top row first) + YAML."""
    rows, cols = pixels.shape
    (tmp_path / "f.pgm").write_bytes(
        f"P5\n{cols} {rows}\n255\n".encode() + pixels.astype(np.uint8).tobytes()
    )
    meta = {"image": "f.pgm", "resolution": 0.05, "origin": [0.0, 0.0, 0.0], **fields}
    (tmp_path / "f.yaml").write_text(yaml.safe_dump(meta))
    return tmp_path / "f.yaml"


# one row of pixels: black, dark grey, mid grey, light grey, white
_ROW = np.array([[0, 30, 128, 230, 255]])


@pytest.mark.parametrize(
    ("fields", "expected"),
    [
        ({}, [100, 100, -1, 0, 0]),  # trinary (the default)
        ({"mode": "trinary"}, [100, 100, -1, 0, 0]),
        ({"mode": "trinary", "negate": 1}, [0, 0, -1, 100, 100]),
        # scale: between the thresholds 1 + 98 * (occ - free) / (occupied - free)
        ({"mode": "scale"}, [100, 100, 66, 0, 0]),
        ({"mode": "raw"}, [0, 30, -1, -1, -1]),  # the pixel is the value (0..100, else unknown)
        ({"mode": "raw", "negate": 1}, [-1, -1, -1, 25, 0]),
        ({"occupied_thresh": 0.9, "free_thresh": 0.1}, [100, -1, -1, 0, 0]),
    ],
)
def test_foreign_maps_read_as_map_server_reads_them(tmp_path: Path, fields, expected) -> None:
    grid = read_map(_foreign(tmp_path, _ROW, **fields))
    assert grid.occupancy[0].tolist() == expected


@pytest.mark.parametrize(
    ("fields", "needle"),
    [
        ({"mode": "ternary"}, "field 'mode': 'ternary' is not one of trinary, scale, raw"),
        ({"resolution": 0.0}, "field 'resolution': must be a number > 0, got 0.0"),
        ({"resolution": "fine"}, "field 'resolution': must be a number > 0, got 'fine'"),
        ({"resolution": float("nan")}, "field 'resolution': must be a number > 0"),
        ({"origin": [0.0, "a", 0.0]}, "field 'origin'"),
        ({"origin": 3}, "field 'origin': expected [x, y, yaw]"),
        ({"negate": 2}, "field 'negate': must be 0 or 1, got 2"),
        ({"occupied_thresh": 1.5}, "field 'occupied_thresh': must be in [0, 1], got 1.5"),
        ({"free_thresh": 0.8}, "field 'free_thresh' (0.8) must be below occupied_thresh (0.65)"),
        ({"image": ""}, "field 'image'"),
    ],
)
def test_bad_fields_are_one_line_naming_file_and_field(tmp_path: Path, fields, needle) -> None:
    path = _foreign(tmp_path, _ROW, **fields)
    with pytest.raises(InputError) as err:
        read_map(path)
    message = str(err.value)
    assert message.startswith(str(path)) and "\n" not in message
    assert needle in message, message


def test_negate_may_be_a_boolean(tmp_path: Path) -> None:
    grid = read_map(_foreign(tmp_path, _ROW, negate=True))
    assert grid.occupancy[0].tolist() == [0, 0, -1, 100, 100]
