"""The phases of :func:`laser_corners.eval.real.evaluate_real`, each a function of plain data.

clean scans (no-return sentinels) -> detect + observability maps + persistent features ->
association distance -> repeatability of every method -> evidence warnings.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from laser_corners.detector import CornerDetector
from laser_corners.eval.association import (
    AssociationStats,
    association_stats,
    observation_table,
    order_by_first_seen,
    pair_distance_std,
)
from laser_corners.eval.grid import bounded_grid
from laser_corners.eval.methods import DetectLoop, detect_all, method_factories
from laser_corners.eval.no_return import no_return_range, without_no_returns
from laser_corners.eval.observability import ObservabilityMap, observability_map
from laser_corners.eval.pairs import choose_pairs
from laser_corners.eval.persistent import (
    PersistentFeatures,
    persistent_features,
    refine_positions,
    take,
)
from laser_corners.eval.poses import Relation
from laser_corners.eval.real_config import RealEvalConfig
from laser_corners.eval.repeatability import RepeatabilityResult, repeatability
from laser_corners.keypoints import Keypoints
from laser_corners.scan import LaserScan

__all__ = [
    "AssociationPhase",
    "MapsPhase",
    "Phases",
    "association_phase",
    "clean_scans",
    "evidence_warnings",
    "maps_phase",
    "repeatability_phase",
]


class Phases:
    """Timings, progress and the detect loop of the phases.

    ``step(phase, done, total)`` goes to ``step`` when given; otherwise, with ``say``, a
    ``phase: done / total`` message at most every ``every`` seconds.
    """

    def __init__(
        self,
        say: Callable[[str], None] | None,
        step: Callable[[str, int, int], None] | None,
        every: float = 5.0,
        detect: DetectLoop = detect_all,
    ) -> None:
        self.detect = detect
        self.say = say if say is not None else (lambda message: None)
        self._step = step
        self._every = every
        self._last = time.perf_counter()
        self.seconds: dict[str, float] = {}

    def stepper(self, phase: str) -> Callable[[int, int], None]:
        """A ``(done, total)`` callback for one phase."""

        def report(done: int, total: int) -> None:
            if self._step is not None:
                self._step(phase, done, total)
            elif time.perf_counter() - self._last >= self._every and done < total:
                self._last = time.perf_counter()
                self.say(f"{phase}: {done} / {total}")

        return report

    def timed(self, phase: str, t0: float) -> None:
        """Add the time since ``t0`` to ``phase``."""
        self.seconds[phase] = self.seconds.get(phase, 0.0) + time.perf_counter() - t0


def clean_scans(scans: list[LaserScan]) -> tuple[list[LaserScan], float | None, list[str]]:
    """Make "no return" sentinel readings gaps (:mod:`laser_corners.eval.no_return`)."""
    limit = no_return_range(scans)
    if limit is None:
        return scans, None, []
    n = sum(int(np.count_nonzero(s.valid & (s.ranges >= limit))) for s in scans)
    note = (
        f"{n} readings at {limit:.2f} m or more are a 'no return' value of the scanner "
        "(repeated on many beams), not echoes: treated as gaps"
    )
    return without_no_returns(scans, limit), limit, [note]


@dataclass
class MapsPhase:
    """Keypoints of the maps' detector, map-frame points and the observability map."""

    keypoints: list[Keypoints]
    posed: list[int]
    map_kps: list[NDArray[np.float64]]
    all_map_kps: NDArray[np.float64]
    trajectory_xy: NDArray[np.float64]
    scan_points: NDArray[np.float64]
    obs: ObservabilityMap
    features: PersistentFeatures
    notes: list[str] = field(default_factory=list)

    def report_fields(self) -> dict[str, Any]:
        """This phase's fields of :class:`~laser_corners.eval.real.RealEvaluation`."""
        return {
            "n_scans_with_pose": len(self.posed),
            "obs": self.obs,
            "keypoints_map_xy": self.all_map_kps,
            "scan_points_map_xy": self.scan_points,
            "trajectory_xy": self.trajectory_xy,
        }


def _useful_reach(scans: Sequence[LaserScan], max_range: float | None) -> float:
    """99th percentile of the valid ranges (the far edge of what the scans measured)."""
    ranges = np.concatenate([s.ranges[s.valid] for s in scans] or [np.zeros(0)])
    reach = float(np.quantile(ranges, 0.99)) if ranges.size else 1.0
    return min(reach, max_range) if max_range is not None else reach


def maps_phase(
    scans: list[LaserScan], detector: CornerDetector, cfg: RealEvalConfig, phases: Phases
) -> MapsPhase:
    """Detect on every scan, build the bounded observability map, pick persistent features."""
    t0 = time.perf_counter()
    keypoints = phases.detect(detector, scans, phases.stepper("detection"))
    phases.timed("detection", t0)
    posed = [i for i, s in enumerate(scans) if s.pose is not None]
    phases.say(
        f"{len(scans)} scans ({len(posed)} with a pose), "
        f"{np.mean([len(k) for k in keypoints]):.2f} keypoints per scan"
    )
    map_kps = [keypoints[i].transformed(scans[i].pose).xy for i in posed]  # type: ignore[arg-type]
    all_map_kps = np.concatenate(map_kps) if map_kps else np.zeros((0, 2))
    trajectory_xy = np.array([scans[i].pose[:2] for i in posed]).reshape(-1, 2)  # type: ignore[index]
    posed_scans = [scans[i] for i in posed]
    t0 = time.perf_counter()
    reach = _useful_reach(posed_scans, cfg.max_range)
    grid, notes = bounded_grid(all_map_kps, trajectory_xy, reach, cfg.resolution, cfg.max_cells)
    obs = observability_map(
        posed_scans,
        map_kps,
        grid,
        occlusion=cfg.occlusion,
        tolerance=cfg.view_tolerance,
        max_range=cfg.max_range,
        step=phases.stepper("observability"),
    )
    features = persistent_features(obs, cfg.min_ratio, cfg.min_views, cfg.nms_radius)
    if len(features) > cfg.max_features:
        notes.append(f"{len(features)} persistent features, the best {cfg.max_features} kept")
        features = take(features, np.arange(cfg.max_features))
    features = refine_positions(features, all_map_kps, cfg.association_radius)
    phases.timed("observability", t0)
    phases.say(
        f"observability map {grid.shape[1]}x{grid.shape[0]} cells of "
        f"{grid.resolution:.3g} m, {len(features)} persistent features"
    )
    return MapsPhase(
        keypoints,
        posed,
        map_kps,
        all_map_kps,
        trajectory_xy,
        _map_points(posed_scans, 200_000),
        obs,
        features,
        notes,
    )


@dataclass
class AssociationPhase:
    """Features (renumbered by when they were seen) and their pair-distance statistics."""

    features: PersistentFeatures
    observations: NDArray[np.float64]
    pair_std: NDArray[np.float64]
    together: NDArray[np.int64]
    stats: AssociationStats

    def report_fields(self) -> dict[str, Any]:
        """This phase's fields of :class:`~laser_corners.eval.real.RealEvaluation`."""
        return {
            "features": self.features,
            "observations": self.observations,
            "pair_std": self.pair_std,
            "pair_together": self.together,
            "association": self.stats,
        }


def association_phase(maps: MapsPhase, cfg: RealEvalConfig, phases: Phases) -> AssociationPhase:
    """Associate keypoints to the features and measure every pair's distance std."""
    t0 = time.perf_counter()
    observations = observation_table(maps.map_kps, maps.features.xy, cfg.association_radius)
    order = order_by_first_seen(observations)
    observations = observations[:, order]
    pair_std, together = pair_distance_std(observations)
    stats = association_stats(pair_std, together, cfg.std_threshold)
    phases.timed("association", t0)
    return AssociationPhase(take(maps.features, order), observations, pair_std, together, stats)


def repeatability_phase(
    scans: list[LaserScan],
    keypoints: list[Keypoints],
    maps_label: str,
    cfg: RealEvalConfig,
    relations: Sequence[Relation] | None,
    pose_source: str,
    phases: Phases,
) -> tuple[dict[str, RepeatabilityResult], int, str, list[str]]:
    """Repeatability of the maps' detector and of every method of ``cfg.methods``.

    Returns the table (method -> result), the number of pairs, their source and notes.
    """
    t0 = time.perf_counter()
    pairs, source, notes = choose_pairs(
        scans,
        relations,
        cfg.relations_mount,
        cfg.max_pairs,
        cfg.pair_min_motion,
        cfg.pair_min_turn_deg,
        pose_source,
    )
    needed = sorted({k for i, j, _ in pairs for k in (i, j)})
    sub_scans = [scans[k] for k in needed]
    position = {k: n for n, k in enumerate(needed)}
    sub_pairs = [(position[i], position[j], pose) for i, j, pose in pairs]
    table: dict[str, RepeatabilityResult] = {}
    runs: dict[str, Callable[[], list[Keypoints]]] = {
        maps_label: lambda: [keypoints[k] for k in needed]  # already detected on every scan
    }
    for name, factory in method_factories(cfg.methods).items():
        if name not in runs and sub_scans:
            detector = factory(sub_scans[0])
            runs[name] = lambda d=detector, n=name: phases.detect(d, sub_scans, phases.stepper(n))
    for name, run in runs.items():
        table[name] = repeatability(
            [k.xy for k in run()],
            sub_scans,
            sub_pairs,
            cfg.radii,
            cfg.view_tolerance,
            cfg.occlusion,
            cfg.max_range,
        )
        pairs_r = zip(cfg.radii, table[name].repeatability, strict=True)
        values = ", ".join(f"r={r:g} m {_pct(v)}" for r, v in pairs_r)
        phases.say(f"repeatability {name}: {values}")
    phases.timed("repeatability", t0)
    return table, len(pairs), source, notes


def _pct(value: float) -> str:
    return "n/a" if math.isnan(value) else f"{100 * value:.1f} %"


def evidence_warnings(
    features: PersistentFeatures,
    stats: AssociationStats,
    table: dict[str, RepeatabilityResult],
    n_pairs: int,
    cfg: RealEvalConfig,
) -> list[str]:
    """Plain sentences naming every result that rests on too little evidence."""
    out: list[str] = []
    if len(features) < 2:
        out.append(
            f"only {len(features)} persistent feature(s): no association distance "
            "(it needs pairs of features)"
        )
    elif stats.n_pairs_with_std == 0:
        out.append(
            "no pair of persistent features was seen together in 2 or more scans: "
            "no association distance"
        )
    elif stats.n_pairs_with_std < cfg.min_pairs:
        out.append(
            f"association distance rests on only {stats.n_pairs_with_std} feature "
            f"pairs (fewer than {cfg.min_pairs}): too little evidence"
        )
    if n_pairs == 0:
        out.append("no scan pair for repeatability")
    elif n_pairs < cfg.min_pairs:
        out.append(
            f"repeatability rests on only {n_pairs} scan pairs (fewer than "
            f"{cfg.min_pairs}): too little evidence"
        )
    for name, rep in table.items():
        if n_pairs and rep.n_visible < cfg.min_visible:
            out.append(
                f"repeatability of {name}: only {rep.n_visible} visible keypoints "
                f"(fewer than {cfg.min_visible}): too little evidence"
            )
    return out


def _map_points(scans: Sequence[LaserScan], max_points: int) -> NDArray[np.float64]:
    """Valid scan points of posed scans in the map frame, evenly thinned to ``max_points``."""
    chunks = []
    for scan in scans:
        xy, valid = scan.to_cartesian()
        px, py, th = scan.pose  # type: ignore[misc]
        c, s = math.cos(th), math.sin(th)
        chunks.append(xy[valid] @ np.array([[c, s], [-s, c]]) + np.array([px, py]))
    if not chunks:
        return np.zeros((0, 2))
    pts = np.concatenate(chunks)
    if len(pts) > max_points:
        pts = pts[np.linspace(0, len(pts) - 1, max_points).astype(int)]
    return pts
