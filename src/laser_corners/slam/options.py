"""Options of :mod:`laser_corners.slam`: one validated, frozen object, one set of defaults.

The field names are the vocabulary of the Python API, of YAML files (a ``slam:`` table, or the
fields at the top) and of the CLI's ``--set key=value``; options of one concern form a group
reached by a dotted key (``icp.max_distance``:
:class:`~laser_corners.registration.align.IcpOptions`; ``odometry.sigma_xy``:
:class:`~laser_corners.registration.odometry.OdometryNoise`; ``loop.radius``:
:class:`LoopOptions`; ``places.*``).
:class:`SlamOptions` is an :class:`~laser_corners.options.Options`, the package's one form of
an options object. The
defaults were chosen from the sensors and the robots (range noise of a few centimetres,
walking-speed platforms, indoor rooms of a few metres), not from the relation errors of any
log; see ``docs/slam.md``.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any, ClassVar, Literal

from pydantic import Field

from laser_corners.errors import InputError, InvalidParamsError
from laser_corners.options import MountValue, Options, read_config
from laser_corners.registration.align import IcpOptions
from laser_corners.registration.odometry import OdometryNoise
from laser_corners.registration.place_index import PlaceOptions

__all__ = ["FLAT_NAMES", "LoopOptions", "SlamOptions", "map_options"]


class LoopOptions(Options):
    """The loop closure's settings (:mod:`~laser_corners.slam.closing`): the ``loop`` group of
    :class:`SlamOptions` (``--set loop.radius=5``, a YAML ``loop:`` table, the ROS 2 parameter
    ``loop.radius``). The refinement pass (:mod:`~laser_corners.slam.refine`), which adds
    closures after the final optimisation, uses the same radius, submaps, score and noise;
    the localiser's smoothing weighs the SLAM's closures by ``sigma_xy`` / ``sigma_yaw``.

    Attributes
    ----------
    enabled : bool
        Search and verify loop closures against older keyframes.
    radius : float
        Keyframes within this distance (m) of the current estimate are loop candidates.
    recent_distance : float
        Keyframes reached less than this travelled distance (m) ago are not loop candidates.
    search_xy, search_yaw : float
        Half-widths (m, rad) of the correlative search window of a loop closure at least.
    drift : float
        Expected drift per metre since the last closure, widening the yaw search window.
    min_score : float
        Share of points within ``inlier_distance`` of the submap to accept a closure.
    submap_keyframes : int
        Keyframes on each side of a candidate that form its submap.
    query_keyframes : int
        Keyframes (the current one and its predecessors) whose points form a loop query.
    every : int
        Loop search on every n-th keyframe.
    candidates : int
        Candidates verified per loop search (nearest first, from different submaps).
    sigma_xy, sigma_yaw : float
        Noise (m, rad) of a loop closure factor (under the Huber kernel of
        :func:`~laser_corners.registration.graph.robust_noise`).

    Examples
    --------
    >>> LoopOptions().with_overrides(["radius=5", "enabled=false"]).radius
    5.0
    """

    title: ClassVar[str] = "LoopOptions"
    what: ClassVar[str] = "option"

    enabled: bool = True
    radius: float = Field(4.0, ge=0.1, le=100.0)
    recent_distance: float = Field(10.0, ge=0.0, le=1000.0)
    search_xy: float = Field(1.0, ge=0.0, le=10.0)
    search_yaw: float = Field(0.25, ge=0.0, le=3.2)
    drift: float = Field(0.03, ge=0.0, le=1.0)
    min_score: float = Field(0.55, ge=0.0, le=1.0)
    submap_keyframes: int = Field(10, ge=1, le=200)
    query_keyframes: int = Field(1, ge=1, le=100)
    every: int = Field(5, ge=1, le=1000)
    candidates: int = Field(2, ge=1, le=20)
    sigma_xy: float = Field(0.03, ge=1e-4, le=10.0)
    sigma_yaw: float = Field(0.005, ge=1e-5, le=1.0)


class SlamOptions(Options):
    """Options of :class:`~laser_corners.slam.Slam` and :func:`~laser_corners.slam.run_slam`.

    Examples
    --------
    >>> SlamOptions().with_overrides(["keyframe_distance=0.5", "mount=-0.04,0,0"]).mount
    (-0.04, 0.0, 0.0)
    """

    what: ClassVar[str] = "option"
    section: ClassVar[str] = "slam"
    tuple_hints: ClassVar[dict[str, str]] = {"mount": "x,y,yaw (three numbers)"}

    keyframe_distance: float = Field(0.4, ge=0.01, le=10.0)
    """Travelled distance (m) after which the next scan becomes a keyframe (a graph node)."""
    keyframe_angle: float = Field(0.3, ge=0.01, le=3.2)
    """Turn (rad) after which the next scan becomes a keyframe."""
    keyframe_max_interval: float = Field(10.0, ge=0.1, le=1e6)
    """Time (s) after which the next scan becomes a keyframe even when standing still."""
    local_map_keyframes: int = Field(20, ge=1, le=500)
    """Recent keyframes whose points form the local map each scan is aligned to."""
    scan_alignment: bool = True
    """Align scans to the local map (point-to-line ICP) when ``front_end`` uses the scan;
    off: odometry prediction only, whatever ``front_end`` says."""
    front_end: Literal["scan", "corners", "both"] = "scan"
    """How a scan is registered before the keyframe graph: ``scan`` point-to-line ICP
    against the local map; ``corners`` corner registration
    (:func:`~laser_corners.matching.register_keypoints`) against the last keyframe, the
    odometry prediction where it fails (no scan alignment at all); ``both`` the corner
    registration as ICP's first guess where it succeeds, the prediction elsewhere."""
    landmarks: bool = False
    """Corner keypoints of keyframes associated into landmarks ``L(i)`` of the graph, each
    observation a bearing-range factor weighted by ``Keypoints.cov`` (Huber). Off by default:
    on fr079, aces and intel (bag mountings) it lowered the relation error slightly, but fr079
    with the log's mounting lost a long loop with it (0.07 -> 1.45 m; docs/slam.md, ablation)."""
    landmark_min_observations: int = Field(3, ge=2, le=100)
    """Keyframes that must see a corner before it enters the graph as a landmark."""
    landmark_gate: float = Field(3.0, ge=0.5, le=10.0)
    """Mahalanobis gate (standard deviations, keypoint covariance + pose uncertainty) of an
    association between a keypoint and a landmark."""
    landmark_window: int = Field(20, ge=0, le=100000)
    """Only landmarks seen within this many keyframes are associated (0: all): a corner seen
    again after a loop starts a new landmark, so a wrong association across a loop (poses
    off by the drift) cannot bend the map; loops are closed by the scan alignment."""
    landmark_sigma_floor: float = Field(0.03, ge=0.0, le=1.0)
    """Standard deviation (m) added in quadrature to each keypoint's covariance (the
    detector's covariance leaves out a corner's shape seen from different places)."""
    relocalisation: bool = True
    """When a scan fits nothing of the local map (kidnapped, an odometry jump) or a time jump
    is not bridged: cut the graph there and search the whole map with no prior until the new
    segment is found in it (:mod:`~laser_corners.slam.relocalise`)."""
    final_optimisation: bool = True
    """Run a batch Levenberg-Marquardt optimisation of the whole graph at the end."""
    refine_final: bool = False
    """After the final optimisation, re-align every ``refine_every``-th keyframe by ICP from
    its final estimate to the submaps of its spatial neighbours (within ``loop.radius``, at
    any time), add the alignments that pass the loop closure's checks as robust relative-pose
    factors and solve once more (:mod:`~laser_corners.slam.refine`; needs
    ``final_optimisation``). Off by default: with ``rescan_final`` it lowered intel's relation
    error (0.0187 -> 0.0180 m) but raised fr079's with the bag's mounting (0.0619 -> 0.0630 m)
    and aces' (0.0339 -> 0.0342 m; docs/slam.md, "Every scan re-registered")."""
    rescan_final: bool = True
    """After the final optimisation (and the refinement pass), re-register every scan by the
    front end's ICP against the keyframes around it at their final estimates
    (``local_map_keyframes``, half before and half after), from its blended pose; kept when
    it passes the tracking's and the closures' checks (:mod:`~laser_corners.slam.rescan`).
    Keeps every scan's thinned points (float32, about 1 KB a scan) for it. Only with the front end's
    ICP (``scan_alignment``, ``front_end`` ``scan`` or ``both``). On: it lowered the relation
    error on every Freiburg log (docs/slam.md, "Every scan re-registered")."""
    refine_every: int = Field(1, ge=1, le=1000)
    """The refinement pass re-aligns every n-th keyframe."""
    refine_candidates: int = Field(3, ge=1, le=20)
    """Submaps (nearest first) each keyframe is re-aligned to in the refinement pass."""
    refine_min_travel: float = Field(0.0, ge=0.0, le=1000.0)
    """Travel (m) between a keyframe and a submap's anchor below which the refinement pass
    does not link them (a submap never holds the keyframe itself)."""
    mount: tuple[MountValue, MountValue, MountValue] | None = None
    """Base -> laser transform ``(x, y, yaw)``, overriding the recording's (``/tf_static``)."""
    detector_preset: Literal["paper", "auto", "robust"] = "paper"
    """Corner detector preset for keypoints (landmarks, corner front end); ``auto`` and
    ``robust`` adapt to the first scan's sensor."""
    max_range: float = Field(30.0, ge=0.5, le=1000.0)
    """Beams longer than this (m) are not used for alignment (long beams: large angular error)."""
    min_range: float = Field(0.1, ge=0.0, le=10.0)
    """Beams shorter than this (m) are not used (the robot itself)."""
    point_spacing: float = Field(0.05, ge=0.0, le=1.0)
    """Minimum spacing (m) between the points kept from one scan (voxel thinning)."""
    icp: IcpOptions = IcpOptions(max_distance=0.15, iterations=20)
    """The ICP of the front end, the loop closures and the final passes: a 0.15 m gate
    (``icp.max_distance``: five times the 3 cm point noise; a prediction farther off is caught
    by the second start and the correlative rescue of the front end, not by a wider gate) and
    20 iterations (``icp.iterations``). The SLAM aligns to its own recent keyframes; the
    localiser, aligning to a map made another day, has its own (``LocaliseOptions.icp``)."""
    min_overlap: float = Field(0.4, ge=0.0, le=1.0)
    """Share of a scan's points that must match the map for an alignment to be trusted."""
    odometry: OdometryNoise = OdometryNoise()
    """Odometry noise weighing predictions and factors (``odometry.sigma_xy``: m per metre
    travelled, on 0.1 m more; ``odometry.sigma_yaw``: rad per radian turned, plus the same
    per metre travelled)."""
    match_sigma_xy: float = Field(0.02, ge=1e-4, le=10.0)
    """Noise (m) of a keyframe-to-keyframe relative pose from scan alignment."""
    match_sigma_yaw: float = Field(0.005, ge=1e-5, le=1.0)
    """Noise (rad) of a keyframe-to-keyframe relative pose from scan alignment."""
    loop: LoopOptions = LoopOptions()
    """Search and verification of loop closures against older keyframes (``loop.enabled``,
    ``loop.radius``, ...); the refinement pass (``refine_final``) reuses its radius, submaps,
    score and noise."""
    inlier_distance: float = Field(0.1, ge=0.01, le=1.0)
    """Distance (m) within which a point counts as explained by a map: the tracking's overlap
    and its lost check, the loop closures' score, relocalisation, the refinement and rescan
    passes (the localiser's ``inlier_distance``)."""
    agree_xy: float = Field(0.15, ge=0.0, le=10.0)
    """A correction of a pose by less than this (m) agrees with the map: a verified loop
    closure is accepted at once (a larger one needs a second closure implying the same
    correction within this distance), a refinement link or a rescanned pose is kept (a larger
    move is a wrong match, the map being consistent already)."""
    agree_yaw: float = Field(0.035, ge=0.0, le=3.2)
    """As ``agree_xy``, for the rotation (rad, 2 degrees)."""
    time_jump: float = Field(5.0, ge=0.1, le=1e6)
    """A gap (s) between scan stamps (either way) longer than this is a time jump: the scan
    becomes a keyframe, its alignment gets a weak odometry prior, and when it does not align
    the graph is cut there (a new segment under a weak prior)."""
    places: PlaceOptions = PlaceOptions()
    """The place index: corner keypoints and descriptors of the map's keyframes, which propose
    global (re)localisation candidates in milliseconds (``places.enabled=false``: the
    exhaustive correlative search alone; see ``registration/place_index.py``)."""


def map_options(folder: str | Path) -> SlamOptions:
    """The :class:`SlamOptions` a map folder was made with (its ``options.yaml``, which
    ``slam`` writes), or the defaults when the folder has none.

    Raises
    ------
    InputError
        ``options.yaml`` is there but unreadable or not valid options (named, one line).
    """
    path = Path(folder) / "options.yaml"
    if not path.is_file():
        return SlamOptions()
    try:
        data = _grouped(read_config(path, SlamOptions.what), path)
        return SlamOptions.from_mapping(data, source=str(path))
    except InvalidParamsError as exc:
        raise InputError(f"{exc} (the map's SLAM options)") from None


FLAT_NAMES: dict[str, tuple[str, ...]] = {
    "icp_max_distance": ("icp", "max_distance"),
    "icp_iterations": ("icp", "iterations"),
    "odometry_sigma_xy": ("odometry", "sigma_xy"),
    "odometry_sigma_yaw": ("odometry", "sigma_yaw"),
    "loop_closure": ("loop", "enabled"),
    "loop_radius": ("loop", "radius"),
    "loop_recent_distance": ("loop", "recent_distance"),
    "loop_search_xy": ("loop", "search_xy"),
    "loop_search_yaw": ("loop", "search_yaw"),
    "loop_drift": ("loop", "drift"),
    "loop_min_score": ("loop", "min_score"),
    "loop_submap_keyframes": ("loop", "submap_keyframes"),
    "loop_query_keyframes": ("loop", "query_keyframes"),
    "loop_every": ("loop", "every"),
    "loop_candidates": ("loop", "candidates"),
    "loop_sigma_xy": ("loop", "sigma_xy"),
    "loop_sigma_yaw": ("loop", "sigma_yaw"),
    "loop_inlier_distance": ("inlier_distance",),
    "loop_agree_xy": ("agree_xy",),
    "loop_agree_yaw": ("agree_yaw",),
}
"""The names an ``options.yaml`` had before the ``icp``, ``odometry`` and ``loop`` groups ->
their group and field (or their new name at the top): a map folder written then still loads
(:func:`map_options` only; ``--set``, ``--config`` and the ROS parameters take the new names
alone)."""


def _grouped(data: Any, path: Path) -> Any:
    """``data`` (a parsed ``options.yaml``) with the old names of :data:`FLAT_NAMES` moved to
    their new places; both spellings of one option: one line naming them."""
    if not isinstance(data, Mapping) or not FLAT_NAMES.keys() & data.keys():
        return data
    out = dict(data)
    for old, (*group, field) in FLAT_NAMES.items():
        if old not in out:
            continue
        table = out.get(group[0], {}) if group else out
        if not isinstance(table, Mapping):  # not a table: the validation names it
            continue
        if field in table:
            new = ".".join([*group, field])
            raise InvalidParamsError(f"{path}: both {old} (the old name) and {new}")
        value = out.pop(old)
        if group:
            out[group[0]] = {**table, field: value}
        else:
            out[field] = value
    return out
