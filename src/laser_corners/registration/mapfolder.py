"""The map folder that ``slam`` writes and ``localise`` reads: ``keyframes.npz`` and friends.

``keyframes.npz`` (numpy archive, no pickles) holds what localisation needs beyond the
occupancy grid:

=================  ==========================================================================
``format_version`` int, :data:`FORMAT_VERSION`; an older file is refused by :func:`load_map`
``poses``          (K, 3) keyframe base poses in the map frame (final estimate)
``stamps``         (K,) keyframe stamps (s)
``scan_index``     (K,) index of each keyframe among the mapped scans
``offsets``        (K + 1,) keyframe ``k``'s points are rows ``offsets[k]:offsets[k + 1]``
``points``         (M, 2) scan points in the keyframe's base frame (mount applied, thinned as
                   :func:`~laser_corners.registration.points.scan_points` makes them)
``normals``        (M, 2) their unit line normals (base frame), zero where ``has_normal`` is
                   False
``has_normal``     (M,) bool
``mount``          (3,) base -> laser transform of the map's run
``places_*``       the place index (:mod:`~laser_corners.registration.place_index`): every
                   keyframe's corner keypoints (base frame) and descriptors, with
                   ``places_version``; absent in maps made before it (no index then)
=================  ==========================================================================

The whole folder (the table of :data:`MAP_FILES`; ``graph.g2o``: the final pose graph, which
:func:`read_pose_graph` reads back for a map that grows) is written by :func:`write_map_folder`
from plain data (:class:`MapContents`; the pictures rendered by the caller, :data:`Render`):
every file into a staging folder ``.NAME.XXXXXXXX.partial`` renamed into place, so a killed
run leaves the previous folder or the new one, never a mix. ``summary.json`` lists the files
and the :data:`FORMAT_VERSION`. :func:`load_map` reads a folder into a :class:`SavedMap`; every
problem is one :class:`~laser_corners.errors.InputError` line naming the folder: another
format version, a staging folder (a run still writing, or killed while writing), a file the
summary lists missing. A *partial* map (its run stopped early: ``"partial": true``) loads,
and says so in :attr:`SavedMap.partial_reason` (``localise`` warns of it).

A ``map_server`` YAML path (a map made by another package) becomes a :class:`SavedMap` of
*virtual keyframes* over the grid's free space (:mod:`laser_corners.registration.gridmap`),
their points made as a real keyframe's, their 360° scans kept in
:attr:`SavedMap.virtual_scans`, a zero mount.
"""

from __future__ import annotations

import json
import os
import shutil
import zipfile
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from laser_corners.errors import InputError, OutputError, first_line
from laser_corners.io.base import PartialOutput
from laser_corners.io.occupancy import OccupancyGrid, read_map, write_map
from laser_corners.io.partial import PARTIAL_SUFFIX, publish_folder, staging_folder
from laser_corners.io.trajectory import write_tum
from laser_corners.registration.graph import PoseGraph, read_g2o_edges
from laser_corners.registration.gridmap import virtual_keyframes
from laser_corners.registration.place_index import (
    PlaceIndex,
    PlaceOptions,
    build_index,
    index_arrays,
    index_from_arrays,
)
from laser_corners.registration.points import scan_points
from laser_corners.scan import LaserScan

__all__ = [
    "FORMAT_VERSION",
    "GRAPH_FILE",
    "KEYFRAMES_FILE",
    "LANDMARK_COLUMNS",
    "MAP_FILES",
    "MapContents",
    "SavedMap",
    "check_map_folder",
    "load_map",
    "read_pose_graph",
    "save_map_data",
    "write_landmarks",
    "write_map_folder",
]

FORMAT_VERSION = 1
"""Version of the map folder (``keyframes.npz``'s ``format_version``, ``summary.json``'s);
:func:`load_map` refuses other versions."""
KEYFRAMES_FILE = "keyframes.npz"
GRAPH_FILE = "graph.g2o"
"""The final pose graph of the run (g2o ``VERTEX_SE2`` / ``EDGE_SE2``, vertex ``k`` keyframe
``k``); :func:`read_pose_graph` reads its edges."""
GRAPH_TOLERANCE = 0.01
"""Largest difference (m, rad) between a ``graph.g2o`` vertex and its keyframe's pose in
``keyframes.npz`` (the g2o text keeps 6 significant digits); more: files of two runs."""
_ARRAYS = ("poses", "stamps", "scan_index", "offsets", "points", "normals", "has_normal", "mount")


@dataclass
class SavedMap:
    """A map folder as :func:`load_map` reads it.

    Attributes
    ----------
    folder : Path
        The map folder, or the ``map_server`` YAML of a foreign map.
    poses : ndarray, shape (K, 3)
        Keyframe base poses in the map frame.
    stamps : ndarray, shape (K,)
    scan_index : ndarray of int, shape (K,)
    offsets : ndarray of int, shape (K + 1,)
    points, normals : ndarray, shape (M, 2)
        Keyframe points and normals in their keyframe's base frame.
    has_normal : ndarray of bool, shape (M,)
    mount : ndarray, shape (3,)
    grid : OccupancyGrid or None
        ``map.yaml`` + ``map.pgm`` when present.
    landmarks : ndarray, shape (L, 2)
        Landmark positions from ``landmarks.csv`` (empty when absent or header only).
    places : PlaceIndex or None
        The keyframes' corners and descriptors (global relocalisation), None for a map made
        before the index.
    partial_reason : str or None
        Why the run that made the map stopped early (its ``summary.json``); None for a map
        of the whole recording, or a folder without a summary.
    virtual_scans : list of LaserScan or None
        A foreign map's (a ``map_server`` YAML): keyframe ``k``'s virtual 360° scan, taken at
        ``poses[k]`` (:mod:`laser_corners.registration.gridmap`); None for a map folder.
    graph : PoseGraph or None
        The edges of ``graph.g2o`` (:func:`read_pose_graph`), read by a run that grows the
        map; None until then, or when the folder has no graph.
    """

    folder: Path
    poses: NDArray[np.float64]
    stamps: NDArray[np.float64]
    scan_index: NDArray[np.int64]
    offsets: NDArray[np.int64]
    points: NDArray[np.float64]
    normals: NDArray[np.float64]
    has_normal: NDArray[np.bool_]
    mount: NDArray[np.float64]
    grid: OccupancyGrid | None = None
    landmarks: NDArray[np.float64] | None = None
    places: PlaceIndex | None = None
    partial_reason: str | None = None
    virtual_scans: list[LaserScan] | None = None
    graph: PoseGraph | None = None

    def __len__(self) -> int:
        return int(self.poses.shape[0])

    def world_points(self) -> tuple[NDArray, NDArray, NDArray]:
        """Every keyframe point and normal moved into the map frame, with ``has_normal``."""
        owner = np.repeat(np.arange(len(self)), np.diff(self.offsets))
        pose = self.poses[owner]
        c, s = np.cos(pose[:, 2]), np.sin(pose[:, 2])
        p, n = self.points, self.normals
        xy = np.column_stack(
            [c * p[:, 0] - s * p[:, 1] + pose[:, 0], s * p[:, 0] + c * p[:, 1] + pose[:, 1]]
        )
        nrm = np.column_stack([c * n[:, 0] - s * n[:, 1], s * n[:, 0] + c * n[:, 1]])
        return xy, nrm, self.has_normal


def read_pose_graph(folder: str | Path, poses: NDArray[np.float64]) -> PoseGraph | None:
    """The edges of a map folder's ``graph.g2o`` between its keyframes ``poses`` (K, 3);
    None when the folder has no graph (a map written before it, or whose graph the writer
    refused).

    Raises
    ------
    InputError
        ``graph.g2o`` is unreadable, or its vertices are not the keyframes (another count,
        a vertex away from its keyframe's pose: files of two runs), one line.
    """
    path = Path(folder) / GRAPH_FILE
    return read_g2o_edges(path, poses, GRAPH_TOLERANCE) if path.is_file() else None


def keyframe_arrays(result: Any) -> dict[str, NDArray]:
    """The arrays of ``keyframes.npz`` from a SLAM result: its ``keyframe_points`` when it
    has them, else points remade from its keyframe scans with its own range limits and
    spacing."""
    opt = result.options
    pts = getattr(result, "keyframe_points", None)
    if pts is None:
        pts = [
            scan_points(s, result.mount, opt.min_range, opt.max_range, opt.point_spacing)
            for s in result.scans
        ]
    stamps = getattr(result, "keyframe_stamps", None)
    if stamps is None:
        stamps = np.asarray(result.stamps, dtype=np.float64)[result.keyframes]
    sizes = [len(p.xy) for p in pts]
    cat = np.concatenate if pts else (lambda _a: np.zeros((0, 2)))
    return {
        "format_version": np.int64(FORMAT_VERSION),
        "poses": np.asarray(result.keyframe_poses, dtype=np.float64).reshape(-1, 3),
        "stamps": np.asarray(stamps, dtype=np.float64),
        "scan_index": np.asarray(result.keyframes, dtype=np.int64),
        "offsets": np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64),
        "points": cat([p.xy for p in pts]).reshape(-1, 2),
        "normals": cat([p.normals for p in pts]).reshape(-1, 2),
        "has_normal": (np.concatenate([p.has_normal for p in pts]) if pts else np.zeros(0, bool)),
        "mount": np.asarray(result.mount, dtype=np.float64),
        **index_arrays(_places(result)),
    }


def _places(result: Any) -> PlaceIndex:
    """The result's place index (the SLAM builds it as it maps), else one made from its
    keyframe scans."""
    if getattr(result, "places", None) is not None:
        return result.places
    options = getattr(result.options, "places", PlaceOptions())
    return build_index(list(result.scans), np.asarray(result.mount, dtype=np.float64), options)


def save_map_data(result: Any, folder: str | Path) -> Path:
    """Write ``keyframes.npz`` of a SLAM result into ``folder`` (atomically).

    Raises
    ------
    OutputError
        The file cannot be written.
    """
    path = Path(folder) / KEYFRAMES_FILE
    arrays = keyframe_arrays(result)
    with PartialOutput(path, overwrite=True).writing() as temporary, temporary.open("wb") as f:
        np.savez_compressed(f, **arrays)
    return path


def _summary(folder: Path) -> str | None:
    """Check a map folder is complete (see the module notes); its partial reason, if any."""
    if folder.name.endswith(".partial"):
        raise InputError(
            f"{folder}: an incomplete map folder (being written, or left by a run killed "
            "while writing); use the folder without .partial"
        )
    path = folder / "summary.json"
    if not path.is_file():
        return None
    try:
        summary = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError) as exc:
        raise InputError(f"{path}: unreadable ({str(exc).splitlines()[0]})") from None
    if not isinstance(summary, dict):
        raise InputError(f"{path}: not a slam summary")
    version = summary.get("format_version", FORMAT_VERSION)
    if version != FORMAT_VERSION:
        raise InputError(
            f"{path}: format version {version}, this version reads {FORMAT_VERSION}; "
            "remake the map with `laser-corners slam`"
        )
    files = summary.get("files")
    missing = sorted(n for n in files.values() if not (folder / n).is_file()) if files else []
    if missing:
        raise InputError(f"{folder}: incomplete map folder, {', '.join(missing)} missing")
    if not summary.get("partial"):
        return None
    return str(summary.get("partial_reason") or "stopped early")


def _read_npz(folder: Path) -> dict[str, NDArray]:
    path = folder / KEYFRAMES_FILE
    if not folder.is_dir():
        raise InputError(f"{folder}: no such map folder")
    if not path.is_file():
        raise InputError(
            f"{folder}: not a map folder for localisation ({KEYFRAMES_FILE} missing; "
            "make it with `laser-corners slam INPUT -o DIR`)"
        )
    try:
        with np.load(path, allow_pickle=False) as data:
            arrays = {k: data[k] for k in data.files}
    except (OSError, ValueError, zipfile.BadZipFile, EOFError) as exc:
        raise InputError(f"{path}: unreadable ({str(exc).splitlines()[0]})") from None
    version = arrays.get("format_version")
    if version is None or int(version) != FORMAT_VERSION:
        found = "none" if version is None else int(version)
        raise InputError(
            f"{path}: format version {found}, this version reads {FORMAT_VERSION}; "
            "remake the map with `laser-corners slam`"
        )
    missing = [k for k in _ARRAYS if k not in arrays]
    if missing:
        raise InputError(f"{path}: incomplete, missing {', '.join(missing)}")
    return arrays


def _places_of(path: Path, a: dict[str, NDArray]) -> PlaceIndex | None:
    """The place index stored in ``keyframes.npz`` (None for a map made before it)."""
    try:
        return index_from_arrays(a, PlaceOptions(), len(a["poses"]))
    except (KeyError, ValueError) as exc:
        raise InputError(f"{path}: {str(exc).strip(chr(39))} (a damaged file?)") from None


def _check(path: Path, a: dict[str, NDArray]) -> None:
    k = a["poses"].shape[0] if a["poses"].ndim == 2 else -1
    m = int(a["offsets"][-1]) if a["offsets"].size else -1
    ok = (
        a["poses"].shape == (k, 3)
        and a["stamps"].shape == (k,)
        and a["offsets"].shape == (k + 1,)
        and a["points"].shape == (m, 2)
        and a["normals"].shape == (m, 2)
        and a["has_normal"].shape == (m,)
        and a["mount"].shape == (3,)
    )
    if not ok:
        raise InputError(f"{path}: inconsistent array shapes (a damaged file?)")
    if k == 0:
        raise InputError(f"{path}: the map has no keyframe")


def _landmarks(folder: Path) -> NDArray[np.float64]:
    path = folder / "landmarks.csv"
    if not path.is_file():
        return np.zeros((0, 2))
    try:
        table = np.genfromtxt(path, delimiter=",", names=True, ndmin=1)
    except (OSError, ValueError) as exc:
        raise InputError(f"{path}: unreadable ({str(exc).splitlines()[0]})") from None
    names = table.dtype.names or ()
    if table.size == 0 or "x" not in names or "y" not in names:
        return np.zeros((0, 2))
    return np.column_stack([table["x"], table["y"]]).astype(np.float64)


def load_map(folder: str | Path) -> SavedMap:
    """Read a map folder written by ``laser-corners slam``, or a ``map_server`` YAML (a map
    made by another package, or our ``map.yaml`` alone) as virtual keyframes.

    Raises
    ------
    InputError
        The folder or ``keyframes.npz`` is missing, of another format version, incomplete or
        inconsistent; ``map.yaml`` is present but unreadable; the folder is a staging folder
        or misses a file its ``summary.json`` lists (see the module notes); a YAML map is
        unreadable, has a bad field or no free space to place a keyframe in.
    """
    folder = Path(folder)
    if not folder.is_dir() and folder.suffix.lower() in (".yaml", ".yml"):
        return _grid_map(folder)
    if folder.is_file():
        raise InputError(f"{folder}: not a map folder nor a map_server .yaml")
    a = _read_npz(folder)
    partial = _summary(folder)
    _check(folder / KEYFRAMES_FILE, a)
    grid = read_map(folder / "map.yaml") if (folder / "map.yaml").is_file() else None
    return SavedMap(
        folder=folder,
        poses=a["poses"].astype(np.float64),
        stamps=a["stamps"].astype(np.float64),
        scan_index=a["scan_index"].astype(np.int64),
        offsets=a["offsets"].astype(np.int64),
        points=a["points"].astype(np.float64),
        normals=a["normals"].astype(np.float64),
        has_normal=a["has_normal"].astype(bool),
        mount=a["mount"].astype(np.float64),
        grid=grid,
        landmarks=_landmarks(folder),
        places=_places_of(folder / KEYFRAMES_FILE, a),
        partial_reason=partial,
    )


def _grid_map(path: Path) -> SavedMap:
    """A ``map_server`` map as a :class:`SavedMap` of virtual keyframes."""
    grid = read_map(path)
    virtual = virtual_keyframes(grid)
    if not len(virtual):
        raise InputError(
            f"{path}: no free cell far enough from the walls to localise in "
            "(is the image a map_server occupancy map? see its 'negate' and thresholds)"
        )
    a = keyframe_arrays(virtual)
    return SavedMap(
        folder=path,
        grid=grid,
        landmarks=np.zeros((0, 2)),
        virtual_scans=virtual.scans,
        places=index_from_arrays(a, PlaceOptions()),
        **{k: a[k] for k in _ARRAYS},
    )


LANDMARK_COLUMNS = (
    "x",
    "y",
    "cov_xx",
    "cov_xy",
    "cov_yy",
    "observations",
    "first_stamp",
    "last_stamp",
)
"""Columns of ``landmarks.csv``."""
MAP_FILES = (
    "trajectory.tum",
    "odometry.tum",
    GRAPH_FILE,
    "landmarks.csv",
    KEYFRAMES_FILE,
    "map.pgm",
    "map.yaml",
    "map.png",
    "summary.json",
    "options.yaml",
    "report.md",
)
"""The files of a map folder (``map.png`` and ``report.md``: the pictures a caller renders,
:data:`Render`)."""


@dataclass
class MapContents:
    """Everything a map folder holds but its pictures, as plain data (the SLAM makes it from
    its result: :func:`laser_corners.slam.output.map_contents`).

    Attributes
    ----------
    source : str
        The recording, named in the trajectories' headers.
    keyframes : dict of str to ndarray
        The arrays of ``keyframes.npz`` (:func:`keyframe_arrays`).
    stamps : ndarray, shape (N,)
    poses, odometry : ndarray, shape (N, 3)
        Every scan's base pose in the map frame and its odometry (``trajectory.tum``,
        ``odometry.tum``).
    landmarks : ndarray, shape (L, 8)
        ``landmarks.csv``'s rows (:data:`LANDMARK_COLUMNS`).
    options_yaml : str
        ``options.yaml``.
    summary : dict
        ``summary.json``, JSON-safe (no NaN; the writer adds ``format_version``, ``files``
        and a warning for a graph it could not write).
    grid : OccupancyGrid or None
        ``map.yaml`` + ``map.pgm`` (None: no grid).
    write_graph : callable or None
        ``write_graph(path)`` writes ``graph.g2o`` (raising ``ValueError``, ``RuntimeError``
        or ``OutputError`` when it cannot); None: no graph.
    """

    source: str
    keyframes: dict[str, NDArray]
    stamps: NDArray[np.float64]
    poses: NDArray[np.float64]
    odometry: NDArray[np.float64]
    landmarks: NDArray[np.float64]
    options_yaml: str
    summary: dict[str, Any] = field(default_factory=dict)
    grid: OccupancyGrid | None = None
    write_graph: Callable[[Path], None] | None = None


Render = Callable[[Path, MapContents], dict[str, Path]]
"""``render(folder, contents)`` writes a map folder's pictures (``map.png``, ``report.md``)
into the folder being written and returns them by key; called before ``summary.json``."""


def write_landmarks(path: Path, table: NDArray[np.float64]) -> Path:
    """Write ``landmarks.csv`` (:data:`LANDMARK_COLUMNS`, rows of ``table``) atomically."""
    table = np.asarray(table, dtype=np.float64).reshape(-1, len(LANDMARK_COLUMNS))
    with PartialOutput(path, overwrite=True).writing() as temporary:
        np.savetxt(
            temporary,
            table,
            delimiter=",",
            header=",".join(LANDMARK_COLUMNS),
            comments="",
            fmt=["%.6f"] * 5 + ["%d"] + ["%.6f"] * 2,
        )
    return path


def check_map_folder(folder: Path) -> None:
    """Refuse an output folder :func:`write_map_folder` cannot replace whole: a file, a folder
    that cannot be written or is marked read-only (no owner write bit: also for root), or one
    holding files that are not a map folder's (they would be lost). A missing folder is fine
    (it is created).

    Raises
    ------
    OutputError
        Naming the folder and what is wrong, one line.
    """
    if not folder.exists():
        return
    if not folder.is_dir():
        raise OutputError(f"{folder}: is a file; the map output needs a folder")
    if not os.access(folder, os.W_OK | os.X_OK) or not folder.stat().st_mode & 0o200:
        raise OutputError(f"{folder}: cannot write into the folder (read-only)")
    other = sorted(
        p.name for p in folder.iterdir() if p.name not in MAP_FILES and PARTIAL_SUFFIX not in p.name
    )
    if other:
        shown = ", ".join(other[:3]) + (f" and {len(other) - 3} more" if len(other) > 3 else "")
        raise OutputError(
            f"{folder}: holds files that are not a slam result ({shown}); the map folder is "
            "replaced whole, so choose a new or empty folder"
        )


def write_map_folder(
    folder: Path, contents: MapContents, render: Render | None = None
) -> dict[str, Path]:
    """Write the map folder ``folder`` whole: every file into a new folder beside it
    (``.NAME.XXXXXXXX.partial``), which then replaces ``folder`` in one step
    (:func:`~laser_corners.io.partial.publish_folder`), so a run killed while writing leaves
    the previous folder (or none) under the name, never a mix of two or a truncated file.

    Returns
    -------
    dict of str to Path
        ``trajectory``, ``odometry``, ``graph``, ``landmarks``, ``keyframes``, ``map_yaml``,
        ``map_pgm``, what ``render`` wrote (``map_png``, ``report``), ``options``,
        ``summary``.

    Raises
    ------
    OutputError
        The folder is refused (:func:`check_map_folder`) or a file cannot be written
        (``graph.g2o`` excepted: a graph that cannot be written is a warning in the summary,
        the other files are still written); nothing is changed under ``folder`` then.
    """
    check_map_folder(folder)
    staging = staging_folder(folder)
    try:
        paths = _write_files(contents, staging, render)
    except BaseException:
        shutil.rmtree(staging, ignore_errors=True)
        raise
    publish_folder(staging, folder)
    return {key: folder / path.name for key, path in paths.items()}


def _write_files(contents: MapContents, folder: Path, render: Render | None) -> dict[str, Path]:
    """Every file into the (new, empty) ``folder``."""
    c = contents
    paths = {"trajectory": folder / "trajectory.tum", "odometry": folder / "odometry.tum"}
    write_tum(
        paths["trajectory"],
        c.stamps,
        c.poses,
        header=f"laser-corners slam {c.source}: base pose in the map frame, one line per scan",
    )
    write_tum(
        paths["odometry"],
        c.stamps,
        c.odometry,
        header=f"laser-corners slam {c.source}: odometry, one line per scan",
    )
    if c.write_graph is not None:
        _write_graph(c, folder / GRAPH_FILE, paths)
    paths["landmarks"] = write_landmarks(folder / "landmarks.csv", c.landmarks)
    paths["keyframes"] = folder / KEYFRAMES_FILE
    with (
        PartialOutput(paths["keyframes"], overwrite=True).writing() as temporary,
        temporary.open("wb") as f,
    ):
        np.savez_compressed(f, **c.keyframes)
    if c.grid is not None:
        paths["map_yaml"], paths["map_pgm"] = write_map(c.grid, folder / "map.yaml")
    if render is not None:
        paths.update(render(folder, c))
    paths["options"] = _write_text(folder / "options.yaml", c.options_yaml)
    summary = {**c.summary, "format_version": FORMAT_VERSION}
    summary["files"] = {k: p.name for k, p in paths.items()}
    text = json.dumps(summary, indent=2, allow_nan=False) + "\n"
    paths["summary"] = _write_text(folder / "summary.json", text)
    return paths


def _write_graph(contents: MapContents, path: Path, paths: dict[str, Path]) -> None:
    """``graph.g2o``; a graph the writer refuses is a warning in the summary, not the loss of
    every other file."""
    try:
        with PartialOutput(path, overwrite=True).writing() as temporary:
            contents.write_graph(temporary)
    except (ValueError, RuntimeError, OutputError) as exc:
        warnings = contents.summary.setdefault("warnings", [])
        warnings.append(f"{path.name} not written: {first_line(exc)}")
        path.unlink(missing_ok=True)
    else:
        paths["graph"] = path


def _write_text(path: Path, text: str) -> Path:
    with PartialOutput(path, overwrite=True).writing() as temporary:
        temporary.write_text(text, encoding="utf-8")
    return path
