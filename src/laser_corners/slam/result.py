"""What a SLAM run gives: :class:`SlamResult` (trajectory, keyframes, landmarks, closures)."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from laser_corners.errors import OutputError
from laser_corners.pose import compose_many
from laser_corners.registration.place_index import PlaceIndex
from laser_corners.registration.points import ScanPoints
from laser_corners.scan import LaserScan
from laser_corners.slam.counts import COUNT_KEYS
from laser_corners.slam.options import SlamOptions

__all__ = ["COUNT_KEYS", "Landmarks", "LoopClosure", "SlamResult"]


@dataclass
class LoopClosure:
    """One loop-closure attempt between two keyframes.

    Attributes
    ----------
    query, match : int
        Keyframe indices (the new one and the older one).
    relative : tuple of float
        Measured pose of ``query`` in the frame of ``match`` (x, y, yaw), base frame.
    accepted : bool
        Whether it went into the graph.
    reason : str
        Why it was accepted or rejected (``"ok"``, ``"low score 0.41"``...).
    """

    query: int
    match: int
    relative: tuple[float, float, float]
    accepted: bool
    reason: str


@dataclass
class Landmarks:
    """Corner landmarks in the map frame (empty when landmarks are off)."""

    xy: NDArray[np.float64] = field(default_factory=lambda: np.zeros((0, 2)))
    cov: NDArray[np.float64] = field(default_factory=lambda: np.zeros((0, 2, 2)))
    n_obs: NDArray[np.int64] = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    first_stamp: NDArray[np.float64] = field(default_factory=lambda: np.zeros(0))
    last_stamp: NDArray[np.float64] = field(default_factory=lambda: np.zeros(0))

    def __len__(self) -> int:
        return int(self.xy.shape[0])


@dataclass
class SlamResult:
    """The result of a SLAM run over N scans with K keyframes.

    Attributes
    ----------
    stamps : ndarray, shape (N,)
        Scan stamps (s), one per scan fed (skipped scans are not in it).
    poses : ndarray, shape (N, 3)
        Base (odometry child frame) pose in the map frame, final estimate (with
        ``rescan_final``, re-registered against the final map: a keyframe's scan pose differs
        from its ``keyframe_poses`` row, on intel and aces by 7 mm median, 3 cm at the 95th
        percentile).
    odometry : ndarray, shape (N, 3)
        Raw odometry base pose.
    keyframes : ndarray of int, shape (K,)
        Scan indices (into ``stamps``) of the keyframes; -1 for the ``prior_keyframes``
        first ones.
    keyframe_poses : ndarray, shape (K, 3)
        Final keyframe base poses in the map frame.
    scans : list of LaserScan
        Keyframe scans (sensor frame).
    mount : ndarray, shape (3,)
        Base -> laser transform used.
    landmarks : Landmarks
    closures : list of LoopClosure
        Every verified loop-closure attempt (accepted or rejected).
    ms_per_scan : ndarray, shape (N,)
        Processing time of each scan (ms).
    options : SlamOptions
    counts : dict of str to int
        The run's counters (:meth:`.counts.SlamCounts.as_dict`, names :data:`COUNT_KEYS`):
        ``scans, keyframes, skipped_no_odometry, time_jumps, closures_proposed,
        closures_accepted, closures_rejected, alignment_failures, landmarks`` ...
    interrupted : bool
        The run was stopped (Ctrl-C, SIGTERM, an error) before the end of the recording.
    partial_reason : str or None
        Why it stopped early (``"interrupted (Ctrl-C)"``, ``"terminated (SIGTERM)"``, the error
        at a scan); None when the whole recording was mapped.
    warnings : list of str
        What the run recovered from (an indeterminate optimiser update, a failed batch
        optimisation, see :mod:`.backend`), one line each.
    graph : object
        The final gtsam ``NonlinearFactorGraph`` (for :meth:`write_g2o`).
    values : object
        The final gtsam ``Values``.
    places : PlaceIndex or None
        The keyframes' corners and descriptors (``options.places``), written into the map
        folder for global relocalisation.
    cuts : ndarray of int
        Indices (into ``stamps``) of the scans that start a new segment of the graph: a gap
        the alignment did not bridge, or a scan that fit nothing (the step from the scan
        before is not measured).
    skipped : dict of str to int
        Records the reader skipped (damaged chunks, broken rows), by reason (``ScanSource``).
    prior_keyframes : int
        The first this many keyframes are a prior map's (a run that grows a map,
        :mod:`.grow`): no scan of this run; their ``scans`` are remade from their points.
    prior_map : str or None
        The map folder the run grew (None: a map of its own).
    keyframe_stamps : ndarray, shape (K,), optional
        Every keyframe's stamp (None: ``stamps[keyframes]``).
    keyframe_points : list of ScanPoints, optional
        Every keyframe's thinned points (base frame) as mapped (None: remade from ``scans``).
    """

    stamps: NDArray[np.float64]
    poses: NDArray[np.float64]
    odometry: NDArray[np.float64]
    keyframes: NDArray[np.int64]
    keyframe_poses: NDArray[np.float64]
    scans: list[LaserScan]
    mount: NDArray[np.float64]
    landmarks: Landmarks
    closures: list[LoopClosure]
    ms_per_scan: NDArray[np.float64]
    options: SlamOptions
    counts: dict[str, int]
    interrupted: bool = False
    partial_reason: str | None = None
    warnings: list[str] = field(default_factory=list)
    graph: object = None
    values: object = None
    cuts: NDArray[np.int64] = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    places: PlaceIndex | None = None
    skipped: dict[str, int] = field(default_factory=dict)
    prior_keyframes: int = 0
    prior_map: str | None = None
    keyframe_stamps: NDArray[np.float64] | None = None
    keyframe_points: list[ScanPoints] | None = None

    @property
    def laser_poses(self) -> NDArray[np.float64]:
        """Laser (sensor) poses in the map frame, shape (N, 3)."""
        return compose_many(self.poses, self.mount)

    def write_g2o(self, path: str | Path) -> None:
        """Write the final pose graph (``VERTEX_SE2``/``EDGE_SE2``; landmarks as ``VERTEX_XY``)."""
        import gtsam

        path = Path(path)
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
            graph = self.graph if self.graph is not None else gtsam.NonlinearFactorGraph()
            values = self.values if self.values is not None else gtsam.Values()
            gtsam.writeG2o(_gaussian_graph(graph), values, str(path))
        except (OSError, RuntimeError) as exc:
            raise OutputError(f"{path}: cannot write the graph ({exc})") from None


def _gaussian_graph(graph: object) -> object:
    """``graph`` with each robust (Huber) noise model replaced by its Gaussian base: g2o
    stores an information matrix per edge, and gtsam's ``writeG2o`` refuses robust models."""
    import gtsam

    out = gtsam.NonlinearFactorGraph()
    for i in range(graph.size()):
        factor = graph.at(i)
        if factor is None:
            continue
        model = factor.noiseModel() if hasattr(factor, "noiseModel") else None
        if isinstance(factor, gtsam.BetweenFactorPose2) and isinstance(
            model, gtsam.noiseModel.Robust
        ):
            keys = factor.keys()
            factor = gtsam.BetweenFactorPose2(keys[0], keys[1], factor.measured(), model.noise())
        out.add(factor)
    return out
