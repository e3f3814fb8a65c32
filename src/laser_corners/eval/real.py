"""Section IV of the paper on real recordings: ``laser-corners evaluate real INPUT``.

The evaluation reads a recording with sensor poses (corrected CARMEN logs, bags with
``/odom``+``/tf``, or any recording plus a TUM trajectory), detects keypoints, moves them into
the map frame and computes

* the observability map and its N8 version (:mod:`~laser_corners.eval.observability`);
* persistent features, picked automatically (:mod:`~laser_corners.eval.persistent`);
* the association distance between persistent features (:mod:`~laser_corners.eval.association`);
* the repeatability of several methods (:mod:`~laser_corners.eval.methods`) over scan pairs with
  known relative pose (:mod:`~laser_corners.eval.pairs`, :mod:`~laser_corners.eval.repeatability`).

"No return" readings stored as a number are found and made gaps first
(:mod:`~laser_corners.eval.no_return`), the map's extent and cell count are bounded
(:func:`~laser_corners.eval.grid.bounded_grid`), and every result resting on too little evidence
is named in :attr:`RealEvaluation.warnings`. :func:`evaluate_real` returns data only; the report
with its figures is written by :func:`laser_corners.viz.report.write_real_report`.

References
----------
.. [1] R. B. Sousa, H. M. Sobreira, M. F. Silva, A. P. Moreira, "Line Fitting-Based Corner-Like
   Detector for 2D Laser Scanners Data", 2024 10th International Conference on Automation,
   Robotics and Applications (ICARA), Athens, Greece, pp. 210-216,
   doi:10.1109/ICARA60736.2024.10553006.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from itertools import islice
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from laser_corners.detector import CornerDetector
from laser_corners.errors import InputError
from laser_corners.eval.association import AssociationStats
from laser_corners.eval.methods import DetectLoop, detect_all
from laser_corners.eval.observability import ObservabilityMap
from laser_corners.eval.pairs import default_relations, pairs_from_poses, pairs_from_relations
from laser_corners.eval.persistent import PersistentFeatures
from laser_corners.eval.poses import Relation, interpolate_poses, read_tum, with_poses
from laser_corners.eval.real_config import RealEvalConfig
from laser_corners.eval.real_phases import (
    Phases,
    association_phase,
    clean_scans,
    evidence_warnings,
    maps_phase,
    repeatability_phase,
)
from laser_corners.eval.repeatability import RepeatabilityResult
from laser_corners.io import open_scans
from laser_corners.params import DetectorParams
from laser_corners.pipeline.recording import no_scan_error
from laser_corners.scan import LaserScan

__all__ = [
    "ODOMETRY_POSES",
    "PERSISTENCE_LEVELS",
    "RealEvalConfig",
    "RealEvaluation",
    "default_relations",
    "evaluate_real",
    "load_scans",
    "pairs_from_poses",
    "pairs_from_relations",
]

PERSISTENCE_LEVELS: tuple[float, ...] = (0.5, 0.75, 1.0)
"""N8 observability levels counted for the persistent features, as in the paper."""


@dataclass
class RealEvaluation:
    """Everything :func:`evaluate_real` computed (see :mod:`laser_corners.eval.real_summary`).

    ``warnings`` says, in plain sentences, which results rest on too little evidence (or on
    none); ``notes`` records what the evaluation changed or left out (no-return readings made
    gaps, keypoints beyond the map, coarser cells, skipped relations).
    """

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
    maps_label: str = ""
    no_return_range: float | None = None
    notes: list[str] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)
    seconds: dict[str, float] = field(default_factory=dict)

    def persistence_counts(self) -> dict[float, int]:
        """Persistent features with N8 observability >= each of :data:`PERSISTENCE_LEVELS`."""
        return {level: self.features.count_at_least(level) for level in PERSISTENCE_LEVELS}


ODOMETRY_POSES = "/odom + /tf"
"""The pose source :func:`load_scans` names for a bag's odometry on ``/odom`` (raw, drifting:
not ground truth); another Odometry topic is named the same way (``/wheel_odom + /tf``), the
odometry of ``/tf`` alone ``/tf``: every bag odometry ends with ``/tf``."""


def load_scans(
    path: Path,
    topic: str | None = None,
    max_scans: int | None = None,
    trajectory: Path | None = None,
    odom_topic: str | None = None,
) -> tuple[list[LaserScan], str]:
    """Read the scans (at most ``max_scans``) and attach poses; returns them and the pose source.

    A bag's poses come from its odometry ``odom_topic`` (an Odometry topic or ``"tf"``;
    default: the only one, see :func:`laser_corners.io.open_scans`).

    Raises
    ------
    InputError
        No scans, or no scan with a pose and no trajectory to give them one.
    """
    source = open_scans(path, topic=topic, odom_topic=odom_topic)
    scans = list(islice(iter(source), max_scans))
    if not scans:
        raise no_scan_error(source)
    if trajectory is not None:
        traj = read_tum(trajectory)
        stamps = [s.stamp if s.stamp is not None else math.nan for s in scans]
        scans = with_poses(scans, interpolate_poses(traj, stamps))
        pose_source = f"TUM trajectory {trajectory.name}"
    elif source.kind == "carmen":
        pose_source = "laser poses of the log"
    elif source.kind in ("ros1", "ros2", "mcap"):
        odometry = getattr(source, "odom_topic", None)
        pose_source = "/tf" if odometry in (None, "/tf") else f"{odometry} + /tf"
    else:
        pose_source = "poses of the recording"
    if not any(s.pose is not None for s in scans):
        raise InputError(
            f"{path}: no scan has a sensor pose; give a trajectory "
            "(TUM format: t x y z qx qy qz qw)"
        )
    return scans, pose_source


def evaluate_real(
    scans: Sequence[LaserScan],
    config: RealEvalConfig | None = None,
    relations: Sequence[Relation] | None = None,
    params: DetectorParams | None = None,
    source: str = "",
    pose_source: str = "",
    progress: Callable[[str], None] | None = None,
    step: Callable[[str, int, int], None] | None = None,
    detect_loop: DetectLoop = detect_all,
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
        the repeatability table, ``custom``); default: ``config.detector`` resolved against
        the first scan.
    source, pose_source : str
        Names recorded in the report.
    progress : callable, optional
        Called with one-line messages at the end of each phase (and, without ``step``, every
        few seconds during long phases).
    step : callable, optional
        Called as ``step(phase, done, total)`` during long phases (detection, observability,
        repeatability), e.g. to drive a progress bar.
    detect_loop : callable, optional
        How a method's detector runs over scans, ``detect_loop(detector, scans, step)``:
        :func:`~laser_corners.eval.methods.detect_all` by default; the place for a shared
        detect loop (threads, chunks) to plug in.

    Returns
    -------
    RealEvaluation

    Raises
    ------
    InputError
        No scan has a pose.
    """
    cfg = config if config is not None else RealEvalConfig()
    phases = Phases(progress, step, detect=detect_loop)
    scans, no_return, notes = clean_scans(list(scans))
    if not any(s.pose is not None for s in scans):
        raise InputError(f"{source or 'recording'}: no scan has a sensor pose")
    params, maps_label = _maps_params(params, cfg, scans[0])
    maps = maps_phase(scans, CornerDetector(params), cfg, phases)
    notes += maps.notes
    assoc = association_phase(maps, cfg, phases)
    table, n_pairs, pairs_source, pair_notes = repeatability_phase(
        scans, maps.keypoints, maps_label, cfg, relations, pose_source, phases
    )
    notes += pair_notes
    warnings = evidence_warnings(assoc.features, assoc.stats, table, n_pairs, cfg)
    return RealEvaluation(
        source=source,
        config=cfg,
        params=params,
        n_scans=len(scans),
        pose_source=pose_source,
        pairs_source=pairs_source,
        n_pairs=n_pairs,
        repeatability=table,
        maps_label=maps_label,
        no_return_range=no_return,
        notes=notes,
        warnings=warnings,
        seconds=phases.seconds,
        **maps.report_fields(),
        **assoc.report_fields(),
    )


def _maps_params(
    params: DetectorParams | None, cfg: RealEvalConfig, first: LaserScan
) -> tuple[DetectorParams, str]:
    """The maps' detector parameters and their label: given (``custom``), or the config's
    choice resolved against the first scan."""
    if params is None:
        return cfg.detector.resolve(first), cfg.detector.label
    return params, "custom"
