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

:func:`save_map_data` writes it from a :class:`~laser_corners.slam.SlamResult`;
:func:`load_map` reads a folder (``keyframes.npz``, ``map.yaml`` + ``map.pgm`` and
``landmarks.csv`` when present) into a :class:`SavedMap`. Every problem of a folder is one
:class:`~laser_corners.errors.InputError` line naming the folder and what is wrong.

Complete and partial folders: ``slam`` writes its folder whole (a staging folder
``.NAME.XXXXXXXX.partial`` renamed into place), and its ``summary.json`` lists the files
written. :func:`load_map` refuses a staging folder (a run still writing, or killed while
writing) and a folder missing a file its summary lists (incomplete: copied or edited by hand).
A *partial* map, one whose run stopped early (Ctrl-C, SIGTERM, an error; ``"partial": true``
in its summary), is complete as far as it goes: it loads, and says so in
:attr:`SavedMap.partial_reason` (``localise`` warns of it).

:func:`load_map` also reads a map made by another package: a ``map_server`` YAML (``.yaml`` /
``.yml`` path) becomes a :class:`SavedMap` of *virtual keyframes* placed over the grid's
free space (:mod:`laser_corners.registration.gridmap`), their points made as a real
keyframe's, their 360° scans kept in :attr:`SavedMap.virtual_scans`, a zero mount.
"""

from __future__ import annotations

import json
import zipfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from laser_corners.errors import InputError, first_line
from laser_corners.io.base import PartialOutput
from laser_corners.io.occupancy import OccupancyGrid, read_map
from laser_corners.registration.graph import require_gtsam
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

try:
    import gtsam
except ImportError:  # pragma: no cover - the "slam" extra is missing
    gtsam = None

__all__ = [
    "FORMAT_VERSION",
    "GRAPH_FILE",
    "KEYFRAMES_FILE",
    "PoseGraph",
    "SavedMap",
    "load_map",
    "read_pose_graph",
    "save_map_data",
]

FORMAT_VERSION = 1
"""Version of ``keyframes.npz``; :func:`load_map` refuses other versions."""
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


@dataclass(frozen=True)
class PoseGraph:
    """The relative-pose factors between a map's keyframes (its ``graph.g2o``).

    Attributes
    ----------
    pairs : ndarray of int, shape (E, 2)
        Keyframes ``a, b`` of each edge (``X(a)^-1 X(b) = relative``).
    relative : ndarray, shape (E, 3)
        The measured relative poses (x, y, yaw).
    sigmas : ndarray, shape (E, 3)
        Their standard deviations (square roots of the covariance's diagonal).
    """

    pairs: NDArray[np.int64]
    relative: NDArray[np.float64]
    sigmas: NDArray[np.float64]

    def chain(self) -> NDArray[np.bool_]:
        """Which edges link a keyframe to the one before (the first such edge of each
        keyframe: the odometry / scan-matching chain); the others are loop closures."""
        out = np.zeros(len(self.pairs), dtype=bool)
        seen: set[int] = set()
        for i, (a, b) in enumerate(self.pairs):
            if b == a + 1 and b not in seen:
                out[i] = True
                seen.add(int(b))
        return out


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
    if not path.is_file():
        return None
    require_gtsam()
    try:
        graph, values = gtsam.readG2o(str(path), False)
        found = gtsam.utilities.extractPose2(values).reshape(-1, 3)
    except (RuntimeError, ValueError, IndexError) as exc:
        raise InputError(f"{path}: unreadable ({first_line(exc)})") from None
    keys = np.array(sorted(values.keys()), dtype=np.int64)
    k = len(poses)
    if len(keys) != k or not np.array_equal(keys, np.arange(k)):
        raise InputError(f"{path}: {len(keys)} vertices, {KEYFRAMES_FILE} has {k} keyframes")
    gap = np.abs(found - poses)
    gap[:, 2] = np.abs(np.angle(np.exp(1j * gap[:, 2])))
    if gap.size and gap.max() > GRAPH_TOLERANCE:
        raise InputError(
            f"{path}: vertex {int(gap.max(axis=1).argmax())} is not at its keyframe's pose "
            f"in {KEYFRAMES_FILE} (files of two runs?)"
        )
    return _edges(graph)


def _edges(graph: Any) -> PoseGraph:
    """The ``BetweenFactorPose2`` edges of a graph ``readG2o`` gave."""
    pairs, relative, sigmas = [], [], []
    for i in range(graph.size()):
        factor = graph.at(i)
        if not isinstance(factor, gtsam.BetweenFactorPose2):
            continue
        rel = factor.measured()
        cov = np.linalg.inv(factor.noiseModel().R().T @ factor.noiseModel().R())
        pairs.append(list(factor.keys()))
        relative.append((rel.x(), rel.y(), rel.theta()))
        sigmas.append(np.sqrt(np.diag(cov)))
    return PoseGraph(
        np.asarray(pairs, dtype=np.int64).reshape(-1, 2),
        np.asarray(relative, dtype=np.float64).reshape(-1, 3),
        np.asarray(sigmas, dtype=np.float64).reshape(-1, 3),
    )


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
