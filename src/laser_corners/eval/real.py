"""Section IV of the paper on real recordings: ``laser-corners evaluate real INPUT``.

The pipeline reads a recording with sensor poses (corrected CARMEN logs, bags with
``/odom``+``/tf``, or any recording plus a TUM trajectory), detects keypoints, moves them into
the map frame and computes

* the observability map and its N8 version (:mod:`~laser_corners.eval.observability`);
* persistent features, picked automatically (peaks of the N8 map, non-maximum suppression);
* the association distance between persistent features (:mod:`~laser_corners.eval.association`);
* the repeatability of several detectors over scan pairs with known relative pose
  (:mod:`~laser_corners.eval.repeatability`), from a ``.relations`` file or from the poses.

:func:`evaluate_real` returns a :class:`RealEvaluation`; :func:`laser_corners.eval.report.
write_real_report` writes its figures, arrays and Markdown summary.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from laser_corners.errors import InputError
from laser_corners.eval.association import (
    AssociationStats,
    association_stats,
    observation_table,
    pair_distance_std,
)
from laser_corners.eval.observability import (
    Grid,
    ObservabilityMap,
    PersistentFeatures,
    observability_map,
    persistent_features,
    refine_positions,
)
from laser_corners.eval.poses import (
    Relation,
    compose,
    interpolate_poses,
    invert,
    read_tum,
    relative_pose,
    with_poses,
)
from laser_corners.eval.repeatability import RepeatabilityResult, repeatability
from laser_corners.keypoints import Keypoints
from laser_corners.params import DetectorParams
from laser_corners.scan import LaserScan, Pose2D

__all__ = [
    "RealEvalConfig",
    "RealEvaluation",
    "evaluate_real",
    "pairs_from_poses",
    "pairs_from_relations",
]

PERSISTENCE_LEVELS: tuple[float, ...] = (0.5, 0.75, 1.0)
"""N8 observability levels counted for the persistent features, as in the paper."""


@dataclass(frozen=True)
class RealEvalConfig:
    """Settings of :func:`evaluate_real` (CLI option names in brackets).

    Attributes
    ----------
    preset : str
        Detector preset for the maps and the association distance (``--preset``).
    overrides : tuple of str
        ``key=value`` overrides of that preset (``--set``).
    resolution : float
        Observability grid cell, metres (0.03 in the paper).
    association_radius : float
        Keypoint-feature association radius, metres (0.06 in the paper).
    std_threshold : float
        Pair-distance std threshold reported as a share, metres (0.03 in the paper).
    min_ratio, min_views, nms_radius : float, int, float
        Persistent feature selection, see
        :func:`~laser_corners.eval.observability.persistent_features`.
    radii : tuple of float
        Repeatability radii, metres.
    occlusion : bool
        Ray-cast against the scan in the visibility tests.
    view_tolerance : float
        How far beyond the measured range a point still counts as seen, metres.
    max_range : float or None
        Ignore cells/keypoints farther than this from the sensor (default: sensor range).
    max_scans : int or None
        Read at most this many scans (``--max-scans``).
    pair_min_motion, pair_min_turn_deg : float
        Without ``.relations``: scan A is paired with the first later scan whose pose moved at
        least this far or turned at least this much.
    max_pairs : int
        At most this many pairs (evenly subsampled).
    relations_mount : (x, y, theta)
        Sensor pose in the frame of the relations (robot base); the relative poses are
        converted to sensor-to-sensor ones with it.
    methods : tuple of str
        Repeatability table rows: preset names of our detector, ``baseline`` (split-and-merge)
        and ``falko``; names that are not available are skipped with a note.
    """

    preset: str = "paper"
    overrides: tuple[str, ...] = ()
    resolution: float = 0.03
    association_radius: float = 0.06
    std_threshold: float = 0.03
    min_ratio: float = 0.25
    min_views: int = 20
    nms_radius: float = 0.2
    radii: tuple[float, ...] = (0.05, 0.1)
    occlusion: bool = True
    view_tolerance: float = 0.06
    max_range: float | None = None
    max_scans: int | None = None
    pair_min_motion: float = 0.5
    pair_min_turn_deg: float = 15.0
    max_pairs: int = 1000
    relations_mount: Pose2D = (0.0, 0.0, 0.0)
    methods: tuple[str, ...] = ("paper", "auto", "baseline", "falko")


@dataclass
class RealEvaluation:
    """Everything :func:`evaluate_real` computed (see :mod:`laser_corners.eval.report`)."""

    source: str
    config: RealEvalConfig
    params: DetectorParams
    n_scans: int
    n_scans_with_pose: int
    pose_source: str
    obs: ObservabilityMap
    features: PersistentFeatures
    observations: NDArray[np.float64]
    pair_std: NDArray[np.float64]
    pair_together: NDArray[np.int64]
    association: AssociationStats
    pairs_source: str
    n_pairs: int
    repeatability: dict[str, RepeatabilityResult]
    keypoints_map_xy: NDArray[np.float64]
    scan_points_map_xy: NDArray[np.float64]
    trajectory_xy: NDArray[np.float64]
    notes: list[str] = field(default_factory=list)
    seconds: dict[str, float] = field(default_factory=dict)

    def persistence_counts(self) -> dict[float, int]:
        """Persistent features with N8 observability >= each of :data:`PERSISTENCE_LEVELS`."""
        return {level: self.features.count_at_least(level) for level in PERSISTENCE_LEVELS}


def pairs_from_poses(
    poses: Sequence[Pose2D | None],
    min_motion: float = 0.5,
    min_turn_deg: float = 15.0,
    max_pairs: int = 1000,
) -> list[tuple[int, int, Pose2D]]:
    """Scan pairs for repeatability from sensor poses in a common frame.

    Each scan ``i`` with a pose is paired with the first later scan ``j`` whose pose is at
    least ``min_motion`` metres away or turned at least ``min_turn_deg``; the pose of ``j`` in
    the frame of ``i`` is the ground truth. With more than ``max_pairs`` pairs, an evenly
    spaced subset is kept.
    """
    min_turn = math.radians(min_turn_deg)
    idx = [i for i, p in enumerate(poses) if p is not None]
    pairs: list[tuple[int, int, Pose2D]] = []
    for a_pos, i in enumerate(idx):
        pa = poses[i]
        assert pa is not None
        for j in idx[a_pos + 1 :]:
            pb = poses[j]
            assert pb is not None
            rel = relative_pose(pa, pb)
            if math.hypot(rel[0], rel[1]) >= min_motion or abs(rel[2]) >= min_turn:
                pairs.append((i, j, rel))
                break
    return _subsample(pairs, max_pairs)


def _subsample(pairs: list[Any], max_pairs: int) -> list[Any]:
    if len(pairs) <= max_pairs:
        return pairs
    keep = np.unique(np.linspace(0, len(pairs) - 1, max_pairs).round().astype(int))
    return [pairs[k] for k in keep]


def pairs_from_relations(
    stamps: Sequence[float | None],
    relations: Sequence[Relation],
    mount: Pose2D = (0.0, 0.0, 0.0),
    tolerance: float = 1e-3,
    max_pairs: int = 1000,
) -> list[tuple[int, int, Pose2D]]:
    """Scan pairs for repeatability from ground-truth relations matched to scan stamps.

    Parameters
    ----------
    stamps : sequence of float or None
        Scan stamps, seconds.
    relations : sequence of Relation
        Relative poses between stamps (robot frame).
    mount : (x, y, theta)
        Sensor pose in the robot frame; the relation ``T`` becomes ``mount⁻¹ ⊕ T ⊕ mount``.
    tolerance : float
        Largest stamp difference for a match, seconds.
    max_pairs : int
        At most this many pairs (evenly subsampled).
    """
    known = [(s, i) for i, s in enumerate(stamps) if s is not None]
    if not known:
        return []
    st = np.array([s for s, _ in known])
    order = np.argsort(st)
    st = st[order]
    index = np.array([i for _, i in known])[order]

    def find(t: float) -> int | None:
        k = int(np.searchsorted(st, t))
        best = None
        for c in (k - 1, k):
            if 0 <= c < len(st) and abs(st[c] - t) <= tolerance:
                if best is None or abs(st[c] - t) < abs(st[best] - t):
                    best = c
        return None if best is None else int(index[best])

    inv_mount = invert(mount)
    pairs = []
    for rel in relations:
        i, j = find(rel.t1), find(rel.t2)
        if i is None or j is None or i == j:
            continue
        pairs.append((i, j, compose(compose(inv_mount, rel.pose), mount)))
    return _subsample(pairs, max_pairs)


def _method_detectors(
    names: Sequence[str], sample: LaserScan, notes: list[str]
) -> dict[str, Callable[[list[LaserScan]], list[Keypoints]]]:
    """Detectors of the repeatability table by method name (unavailable ones noted).

    Preset names give our detector with that preset (adapted to ``sample``), ``baseline`` the
    split-and-merge detector of :mod:`laser_corners.eval.baselines`, ``falko``
    :class:`~laser_corners.eval.falko.FalkoDetector`.
    """
    from laser_corners.detector import CornerDetector
    from laser_corners.eval.falko import FalkoDetector
    from laser_corners.presets import PRESETS, get_preset

    out: dict[str, Callable[[list[LaserScan]], list[Keypoints]]] = {}
    for name in names:
        if name == "falko":
            out["FALKO-style"] = FalkoDetector().detect_many
        elif name == "baseline":
            try:
                from laser_corners.eval.baselines import SplitAndMergeDetector
            except ImportError:
                notes.append("split-and-merge baseline not available (eval/baselines.py)")
                continue
            out["split-and-merge"] = SplitAndMergeDetector().detect_many
        elif name in PRESETS:
            out[f"ours ({name})"] = _detect_all(CornerDetector(get_preset(name, sample)))
        else:
            notes.append(f"method {name!r} is not available (not a registered preset)")
    return out


def _detect_all(detector: Any) -> Callable[[list[LaserScan]], list[Keypoints]]:
    """``detect_many`` when the scans share one geometry, per-scan ``detect`` otherwise."""

    def run(scans: list[LaserScan]) -> list[Keypoints]:
        geometry = {(s.n_beams, s.angle_min, s.angle_increment, s.range_min, s.range_max)
                    for s in scans}  # fmt: skip
        if len(geometry) <= 1:
            return detector.detect_many(scans)
        return [detector.detect(s) for s in scans]

    return run


def load_scans(
    path: Path,
    topic: str | None = None,
    max_scans: int | None = None,
    trajectory: Path | None = None,
) -> tuple[list[LaserScan], str]:
    """Read the scans (at most ``max_scans``) and attach poses; returns them and the pose source.

    Raises
    ------
    InputError
        No scans, or no scan with a pose and no trajectory to give them one.
    """
    from itertools import islice

    from laser_corners.io import open_scans

    source = open_scans(path, topic=topic)
    scans = list(islice(iter(source), max_scans))
    if not scans:
        raise InputError(f"{path}: no scans")
    if trajectory is not None:
        traj = read_tum(trajectory)
        stamps = [s.stamp if s.stamp is not None else math.nan for s in scans]
        scans = with_poses(scans, interpolate_poses(traj, stamps))
        pose_source = f"TUM trajectory {trajectory.name}"
    else:
        pose_source = (
            "laser poses of the log"
            if source.kind == "carmen"
            else "/odom + /tf"
            if source.kind in ("ros1", "ros2", "mcap")
            else "poses of the recording"
        )
    if not any(s.pose is not None for s in scans):
        raise InputError(
            f"{path}: no scan has a sensor pose; give a trajectory with --trajectory FILE "
            "(TUM format: t x y z qx qy qz qw)"
        )
    return scans, pose_source


def default_relations(path: Path) -> Path | None:
    """``<name>.relations`` beside a bag ``<name>.bag`` (the Freiburg benchmark layout)."""
    candidate = path.with_suffix(".relations")
    return candidate if path.suffix == ".bag" and candidate.is_file() else None


def evaluate_real(
    scans: Sequence[LaserScan],
    config: RealEvalConfig | None = None,
    relations: Sequence[Relation] | None = None,
    params: DetectorParams | None = None,
    source: str = "",
    pose_source: str = "",
    progress: Callable[[str], None] | None = None,
) -> RealEvaluation:
    """Run the whole section-IV evaluation on scans that carry map-frame sensor poses.

    Parameters
    ----------
    scans : sequence of LaserScan
        The recording; scans without ``pose`` are skipped by the map metrics.
    config : RealEvalConfig, optional
        Settings.
    relations : sequence of Relation, optional
        Ground-truth relative poses for repeatability; default: pairs from the poses.
    params : DetectorParams, optional
        Our detector's parameters for the maps and the association distance (first row of
        the repeatability table, ``ours (custom)``); default: ``config.preset`` with
        ``config.overrides``.
    source, pose_source : str
        Names recorded in the report.
    progress : callable, optional
        Called with one-line progress messages.

    Returns
    -------
    RealEvaluation
    """
    from laser_corners.detector import CornerDetector
    from laser_corners.presets import get_preset

    cfg = config if config is not None else RealEvalConfig()
    say = progress if progress is not None else (lambda message: None)
    scans = list(scans)
    notes: list[str] = []
    seconds: dict[str, float] = {}
    if params is None:
        params = get_preset(cfg.preset, scans[0])
        if cfg.overrides:
            params = params.with_overrides(list(cfg.overrides))
        maps_label = f"ours ({cfg.preset})" + (" + overrides" if cfg.overrides else "")
    else:
        maps_label = "ours (custom)"

    t0 = time.perf_counter()
    keypoints = _detect_all(CornerDetector(params))(scans)
    seconds["detection"] = time.perf_counter() - t0
    posed = [i for i, s in enumerate(scans) if s.pose is not None]
    say(f"{len(scans)} scans ({len(posed)} with a pose), "
        f"{np.mean([len(k) for k in keypoints]):.2f} keypoints per scan")  # fmt: skip
    map_kps = [keypoints[i].transformed(scans[i].pose).xy for i in posed]  # type: ignore[arg-type]
    all_map_kps = np.concatenate(map_kps) if map_kps else np.zeros((0, 2))
    trajectory_xy = np.array([scans[i].pose[:2] for i in posed])  # type: ignore[index]
    scan_points = _map_points([scans[i] for i in posed], max_points=200_000)

    # --- observability
    t0 = time.perf_counter()
    grid = Grid.covering(np.concatenate([all_map_kps, trajectory_xy]), cfg.resolution, 1.0)
    obs = observability_map(
        [scans[i] for i in posed], map_kps, grid, occlusion=cfg.occlusion,
        tolerance=cfg.view_tolerance, max_range=cfg.max_range,
    )  # fmt: skip
    features = persistent_features(obs, cfg.min_ratio, cfg.min_views, cfg.nms_radius)
    features = refine_positions(features, all_map_kps, cfg.association_radius)
    seconds["observability"] = time.perf_counter() - t0
    say(f"observability map {grid.shape[1]}x{grid.shape[0]} cells, "
        f"{len(features)} persistent features")  # fmt: skip

    # --- association distance
    t0 = time.perf_counter()
    observations = observation_table(map_kps, features.xy, cfg.association_radius)
    # number the features by when they were seen (mean scan index): features seen together
    # get neighbouring numbers and the pair matrix shows blocks along its diagonal
    seen = np.all(np.isfinite(observations), axis=2)
    scan_index = np.arange(len(map_kps), dtype=np.float64)[:, None]
    with np.errstate(invalid="ignore"):
        when = (seen * scan_index).sum(axis=0) / seen.sum(axis=0)
    order = np.argsort(np.nan_to_num(when, nan=np.inf), kind="stable")
    features = PersistentFeatures(features.xy[order], features.ratio_n8[order],
                                  features.in_view_n8[order], features.cells[order])  # fmt: skip
    observations = observations[:, order]
    pair_std, together = pair_distance_std(observations)
    stats = association_stats(pair_std, together, cfg.std_threshold)
    seconds["association"] = time.perf_counter() - t0

    # --- repeatability
    t0 = time.perf_counter()
    if relations is not None:
        matched = pairs_from_relations(
            [s.stamp for s in scans], relations, cfg.relations_mount, max_pairs=len(relations)
        )
        pairs = _subsample(matched, cfg.max_pairs)
        pairs_source = (
            f"ground-truth relations: {len(relations)} in the file, {len(matched)} matched to "
            f"scan stamps, {len(pairs)} used"
        )
        if not pairs:
            notes.append("no relation matched two scan stamps; pairs taken from the poses")
    if relations is None or not pairs:
        found = pairs_from_poses(
            [s.pose for s in scans], cfg.pair_min_motion, cfg.pair_min_turn_deg, len(scans)
        )
        pairs = _subsample(found, cfg.max_pairs)
        pairs_source = (
            f"poses ({pose_source or 'recording'}): each scan with the next one >= "
            f"{cfg.pair_min_motion:g} m or {cfg.pair_min_turn_deg:g} deg away, {len(found)} "
            f"pairs, {len(pairs)} used"
        )
    needed = sorted({k for i, j, _ in pairs for k in (i, j)})
    sub_scans = [scans[k] for k in needed]
    position = {k: n for n, k in enumerate(needed)}
    sub_pairs = [(position[i], position[j], pose) for i, j, pose in pairs]
    table: dict[str, RepeatabilityResult] = {}
    detectors: dict[str, Callable[[list[LaserScan]], list[Keypoints]] | None] = {maps_label: None}
    for name, detect in _method_detectors(cfg.methods, scans[0], notes).items():
        detectors.setdefault(name, detect)
    for name, detect in detectors.items():
        # the maps' detector already ran on every scan
        kps = [keypoints[k] for k in needed] if detect is None else detect(sub_scans)
        table[name] = repeatability(
            [k.xy for k in kps], sub_scans, sub_pairs, cfg.radii, cfg.view_tolerance,
            cfg.occlusion, cfg.max_range,
        )  # fmt: skip
        say(f"repeatability {name}: " + ", ".join(
            f"r={r:g} m {v:.3f}" for r, v in zip(cfg.radii, table[name].repeatability,
                                                  strict=True)))  # fmt: skip
    seconds["repeatability"] = time.perf_counter() - t0

    return RealEvaluation(
        source=source,
        config=cfg,
        params=params,
        n_scans=len(scans),
        n_scans_with_pose=len(posed),
        pose_source=pose_source,
        obs=obs,
        features=features,
        observations=observations,
        pair_std=pair_std,
        pair_together=together,
        association=stats,
        pairs_source=pairs_source,
        n_pairs=len(pairs),
        repeatability=table,
        keypoints_map_xy=all_map_kps,
        scan_points_map_xy=scan_points,
        trajectory_xy=trajectory_xy,
        notes=notes,
        seconds=seconds,
    )


def _map_points(scans: Sequence[LaserScan], max_points: int) -> NDArray[np.float64]:
    """Valid scan points of posed scans in the map frame, evenly thinned to ``max_points``."""
    chunks = []
    for scan in scans:
        xy, valid = scan.to_cartesian()
        px, py, th = scan.pose  # type: ignore[misc]
        c, s = math.cos(th), math.sin(th)
        pts = xy[valid]
        chunks.append(pts @ np.array([[c, s], [-s, c]]) + np.array([px, py]))
    if not chunks:
        return np.zeros((0, 2))
    pts = np.concatenate(chunks)
    if len(pts) > max_points:
        pts = pts[np.linspace(0, len(pts) - 1, max_points).astype(int)]
    return pts
