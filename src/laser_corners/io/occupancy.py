"""Occupancy grids in the ROS ``map_server`` format: ``map.pgm`` + ``map.yaml``.

The image is a binary PGM (``P5``, 8 bits) whose first row is the *top* of the map (largest
y); the YAML names it and gives the cell size and the pose of the *lower-left* pixel::

    image: map.pgm
    resolution: 0.05
    origin: [x, y, yaw]
    negate: 0
    occupied_thresh: 0.65
    free_thresh: 0.196

With ``negate: 0`` map_server reads a pixel ``p`` as occupancy ``(255 - p) / 255``: occupied
above ``occupied_thresh``, free below ``free_thresh``, unknown in between. The writer uses
the three values ``map_saver`` writes: 0 (occupied), 254 (free) and 205 (unknown), from
cells of occupancy >= :data:`OCCUPIED_PERCENT` and <= :data:`FREE_PERCENT` (``map_saver``'s
own thresholds). :func:`read_map` also reads the maps other packages save (slam_toolbox,
Cartographer, GMapping through map_saver): ``mode: trinary | scale | raw``, ``negate``, any
thresholds, an origin with a yaw (kept in :attr:`OccupancyGrid.origin`); every bad field is
one :class:`~laser_corners.errors.InputError` line naming the file and the field.

:class:`OccupancyGrid` holds cells the way ``nav_msgs/OccupancyGrid`` does: row 0 is the
bottom (smallest y), values ``-1`` unknown or 0..100 percent occupied.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import yaml
from numpy.typing import NDArray

from laser_corners.errors import InputError
from laser_corners.io.base import PartialOutput

__all__ = [
    "FREE_PERCENT",
    "FREE_PIXEL",
    "OCCUPIED_PERCENT",
    "OCCUPIED_PIXEL",
    "UNKNOWN_PIXEL",
    "OccupancyGrid",
    "read_map",
    "write_map",
]

OCCUPIED_PIXEL, FREE_PIXEL, UNKNOWN_PIXEL = 0, 254, 205
"""The PGM values map_saver writes for occupied, free and unknown cells."""
OCCUPIED_PERCENT, FREE_PERCENT = 65, 25
"""A cell of occupancy >= 65 % is written occupied, <= 25 % free (map_saver's thresholds)."""
OCCUPIED_THRESH, FREE_THRESH = 0.65, 0.196
"""The thresholds written in ``map.yaml`` (map_saver's)."""


@dataclass(frozen=True)
class OccupancyGrid:
    """A 2D occupancy grid.

    Attributes
    ----------
    occupancy : ndarray of int8, shape (H, W)
        ``-1`` unknown, else percent occupied (0..100); row 0 is the bottom of the map.
    resolution : float
        Cell size, metres.
    origin : tuple of float
        Pose ``(x, y, yaw)`` of the lower-left corner of cell ``[0, 0]`` in the map frame.
    """

    occupancy: NDArray[np.int8]
    resolution: float
    origin: tuple[float, float, float]

    @property
    def shape(self) -> tuple[int, int]:
        """``(rows, cols)``."""
        return (int(self.occupancy.shape[0]), int(self.occupancy.shape[1]))

    @property
    def extent(self) -> tuple[float, float, float, float]:
        """``(left, right, bottom, top)`` in metres (for ``imshow``; yaw ignored)."""
        rows, cols = self.shape
        x0, y0, _ = self.origin
        return (x0, x0 + cols * self.resolution, y0, y0 + rows * self.resolution)

    def cell(self, x: float, y: float) -> tuple[int, int]:
        """``(row, col)`` of the cell holding the point ``(x, y)`` (yaw 0 maps)."""
        return (
            math.floor((y - self.origin[1]) / self.resolution),
            math.floor((x - self.origin[0]) / self.resolution),
        )

    def pixels(self) -> NDArray[np.uint8]:
        """The PGM image (top row first) with map_saver's three values."""
        occ = self.occupancy
        image = np.full(occ.shape, UNKNOWN_PIXEL, dtype=np.uint8)
        image[occ >= OCCUPIED_PERCENT] = OCCUPIED_PIXEL
        image[(occ >= 0) & (occ <= FREE_PERCENT)] = FREE_PIXEL
        return image[::-1]


def write_map(grid: OccupancyGrid, yaml_path: str | Path) -> tuple[Path, Path]:
    """Write ``grid`` as ``NAME.pgm`` + ``NAME.yaml`` (``yaml_path`` names the YAML).

    Each file is written under a temporary name and renamed when complete.

    Returns
    -------
    (yaml, pgm) : tuple of Path

    Raises
    ------
    OutputError
        A file cannot be written.
    """
    yaml_path = Path(yaml_path)
    pgm_path = yaml_path.with_suffix(".pgm")
    image = grid.pixels()
    rows, cols = image.shape
    header = f"P5\n# CREATOR: laser-corners {grid.resolution:.3f} m/pix\n{cols} {rows}\n255\n"
    pgm = PartialOutput(pgm_path, overwrite=True)
    with pgm.writing() as temporary:
        temporary.write_bytes(header.encode("ascii") + image.tobytes())
    meta = {
        "image": pgm_path.name,
        "resolution": float(grid.resolution),
        "origin": [float(v) for v in grid.origin],
        "negate": 0,
        "occupied_thresh": OCCUPIED_THRESH,
        "free_thresh": FREE_THRESH,
    }
    partial = PartialOutput(yaml_path, overwrite=True)
    with partial.writing() as temporary:
        temporary.write_text(yaml.safe_dump(meta, sort_keys=False, default_flow_style=None))
    return yaml_path, pgm_path


def _pgm_tokens(data: bytes, path: Path) -> tuple[list[int], int]:
    """Width, height, maxval of a P5 header and the offset of the pixels."""
    tokens: list[int] = []
    pos = 2
    while len(tokens) < 3:
        while pos < len(data) and data[pos : pos + 1].isspace():
            pos += 1
        if data[pos : pos + 1] == b"#":
            end = data.find(b"\n", pos)
            pos = len(data) if end < 0 else end + 1
            continue
        start = pos
        while pos < len(data) and not data[pos : pos + 1].isspace():
            pos += 1
        if start == pos:
            raise InputError(f"{path}: truncated PGM header")
        try:
            tokens.append(int(data[start:pos]))
        except ValueError:
            field = data[start:pos][:20]
            raise InputError(f"{path}: PGM header field {field!r} is not a number") from None
    return tokens, pos + 1  # one whitespace byte ends the header


def _read_pgm(path: Path) -> NDArray[np.uint8]:
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise InputError(f"{path}: cannot read ({exc.strerror})") from None
    if data[:2] != b"P5":
        raise InputError(f"{path}: not a binary PGM (P5) image")
    (cols, rows, maxval), offset = _pgm_tokens(data, path)
    if maxval != 255:
        raise InputError(f"{path}: only 8-bit PGM (maxval 255) is read, got maxval {maxval}")
    pixels = np.frombuffer(data, dtype=np.uint8, count=-1, offset=offset)
    if pixels.size < rows * cols:
        raise InputError(f"{path}: {rows}x{cols} pixels declared, {pixels.size} bytes found")
    return pixels[: rows * cols].reshape(rows, cols)


MODES = ("trinary", "scale", "raw")
"""The ``mode`` values of a map_server YAML (default ``trinary``)."""


def _field(meta: dict[str, object], key: str, path: Path) -> object:
    if key not in meta:
        raise InputError(f"{path}: missing field {key!r}")
    return meta[key]


def _positive(meta: dict[str, object], key: str, path: Path) -> float:
    value = _field(meta, key, path)
    number = value if isinstance(value, (int, float)) and not isinstance(value, bool) else None
    if number is None or not math.isfinite(number) or number <= 0:
        raise InputError(f"{path}: field {key!r}: must be a number > 0, got {value!r}")
    return float(number)


def _origin(meta: dict[str, object], path: Path) -> tuple[float, float, float]:
    value = _field(meta, "origin", path)
    if not isinstance(value, (list, tuple)) or len(value) != 3:
        raise InputError(f"{path}: field 'origin': expected [x, y, yaw], got {value!r}")
    try:
        origin = tuple(float(v) for v in value)
    except (TypeError, ValueError):
        raise InputError(
            f"{path}: field 'origin': [x, y, yaw] must be numbers, got {value!r}"
        ) from None
    if not all(math.isfinite(v) for v in origin):
        raise InputError(f"{path}: field 'origin': [x, y, yaw] must be finite, got {value!r}")
    return origin  # type: ignore[return-value]


def _threshold(meta: dict[str, object], key: str, default: float, path: Path) -> float:
    value = meta.get(key, default)
    ok = isinstance(value, (int, float)) and not isinstance(value, bool)
    if not ok or not 0.0 <= float(value) <= 1.0:  # type: ignore[arg-type]
        raise InputError(f"{path}: field {key!r}: must be in [0, 1], got {value!r}")
    return float(value)  # type: ignore[arg-type]


@dataclass(frozen=True)
class _Fields:
    """The checked fields of a map_server YAML."""

    image: Path
    resolution: float
    origin: tuple[float, float, float]
    mode: str
    negate: bool
    occupied: float
    free: float


def _fields(meta: dict[str, object], path: Path) -> _Fields:
    """Every field checked; a bad one is an :class:`InputError` naming it."""
    image = _field(meta, "image", path)
    if not isinstance(image, str) or not image.strip():
        raise InputError(f"{path}: field 'image': expected a file name, got {image!r}")
    mode = meta.get("mode", "trinary")
    if mode not in MODES:
        raise InputError(f"{path}: field 'mode': {mode!r} is not one of {', '.join(MODES)}")
    negate = meta.get("negate", 0)
    if negate not in (0, 1):  # True / False compare equal to 1 / 0
        raise InputError(f"{path}: field 'negate': must be 0 or 1, got {negate!r}")
    occupied = _threshold(meta, "occupied_thresh", OCCUPIED_THRESH, path)
    free = _threshold(meta, "free_thresh", FREE_THRESH, path)
    if free >= occupied:
        raise InputError(
            f"{path}: field 'free_thresh' ({free}) must be below occupied_thresh ({occupied})"
        )
    image_path = Path(image) if Path(image).is_absolute() else path.parent / image
    return _Fields(
        image_path,
        _positive(meta, "resolution", path),
        _origin(meta, path),
        str(mode),
        bool(negate),
        occupied,
        free,
    )


def _occupancy(pixels: NDArray[np.uint8], f: _Fields) -> NDArray[np.int8]:
    """Cell values (image rows, top first) of ``pixels`` as map_server's ``mode`` makes them."""
    value = 255 - pixels.astype(np.int64) if f.negate else pixels.astype(np.int64)
    occupancy = np.full(pixels.shape, -1, dtype=np.int8)
    if f.mode == "raw":
        raw = value <= 100
        occupancy[raw] = value[raw]
        return occupancy
    p = (255.0 - value) / 255.0
    if f.mode == "scale":
        between = (p >= f.free) & (p <= f.occupied)
        ratio = (p[between] - f.free) / (f.occupied - f.free)
        occupancy[between] = (1.0 + 98.0 * ratio).astype(np.int8)
    occupancy[p > f.occupied] = 100
    occupancy[p < f.free] = 0
    return occupancy


def read_map(yaml_path: str | Path) -> OccupancyGrid:
    """Read a map_server map (``map.yaml`` and the image it names, a P5 PGM) as map_server does.

    ``mode`` (default ``trinary``) as ROS map_server reads it, after ``negate`` (a pixel
    ``p`` becomes ``255 - p``): *trinary*: occupancy ``(255 - p) / 255`` above
    ``occupied_thresh`` reads 100, below ``free_thresh`` 0, else -1; *scale*: the same,
    with the values between the thresholds ``1 + 98 * (occ - free) / (occupied - free)``;
    *raw*: the pixel value itself where it is 0..100, else -1 (unknown).

    Raises
    ------
    InputError
        A missing file, a YAML without the map_server fields or with a bad one (named:
        ``resolution`` not > 0, an unknown ``mode``, ``negate`` not 0/1, thresholds outside
        [0, 1] or not ordered, ``origin`` not three numbers), or an image that is not P5.
    """
    yaml_path = Path(yaml_path)
    if not yaml_path.is_file():
        raise InputError(f"{yaml_path}: no such file")
    try:
        meta = yaml.safe_load(yaml_path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, yaml.YAMLError) as exc:
        raise InputError(f"{yaml_path}: not a map YAML ({str(exc).splitlines()[0]})") from None
    if not isinstance(meta, dict):
        raise InputError(f"{yaml_path}: not a map YAML (a mapping of fields is expected)")
    f = _fields(meta, yaml_path)
    if not f.image.is_file():
        raise InputError(f"{yaml_path}: field 'image': its image {f.image} does not exist")
    occupancy = _occupancy(_read_pgm(f.image), f)
    return OccupancyGrid(occupancy[::-1].copy(), f.resolution, f.origin)
