"""The map's corner keypoints as a place index: where could this query be, in milliseconds.

Global (re)localisation used to search the whole map with a correlative matcher, every
position and heading (0.3-2.5 s an attempt). The index turns it around: *keypoints propose,
something denser disposes*.

1. **Index.** Every keyframe's corner keypoints (the paper's detector, ``auto`` preset by
   default) with their ``csc`` descriptors (:mod:`laser_corners.matching.descriptors`: a
   rotation-invariant corner context in the bisector's frame), kept in the keyframe's base
   frame (:class:`Corners`), so the index follows the keyframes' estimates as SLAM moves
   them; map-frame positions are derived when asked.
2. **Query.** The corners of the last scans (the last ``query_travel`` metres chained by
   odometry, :class:`QueryBuffer`), merged where several scans saw one corner. Each query
   corner's ``matches`` nearest map corners by descriptor (L1, opening angles within
   ``max_opening_diff``; one numba pass over the index, no Python loop per pair) each
   propose one SE(2) pose: the bisectors give the heading, the positions the translation.
3. **Consensus.** Every proposed pose moves all query corners into the map; its votes are
   the query corners that land within ``consensus_radius`` of a map corner with a bisector
   within ``consensus_yaw`` (a k-d tree over the map corners, vectorised over poses and
   corners). The ``checked`` best-voted distinct poses with at least ``min_votes`` votes go on.
4. **Dense check** (:func:`dense_check`). Each candidate is scored by a bounded correlative
   search of the query's scan points on a likelihood grid of the map (``check_xy`` /
   ``check_yaw`` around it): the corners place it, the walls confirm it; the ``candidates``
   best scores are the candidates. Votes alone rank badly where corners are few or alike
   (aces: the right pose with 1 vote at rank 21-38 behind poses with 3-5, for 3 m of travel;
   the dense check put it first from 0.8 m). What to accept is
   the caller's: the localiser follows the candidates as hypotheses, the SLAM verifies them
   as loop closures.

Cost: the descriptor pass is O(Q·M·D) (Q query corners, M map corners compared: at most
:data:`~laser_corners.registration.corner_grid.VIEWS_PER_CORNER` views of each physical
corner, D = 61), about 2 ms for 40 query corners against fr079's 4,283 compared; the consensus
O(H·Q) grid lookups for the H ≤ Q·``matches`` proposals; the choice of distinct poses
O(H·``checked``) (compiled); the dense check O(``checked`` · window cells · points). Q is at
most ``max_query`` (the corners nearest the robot), so an attempt's work is bounded by the
options whatever the map: none of it grows with the map's area, only (linearly, in the
descriptor pass) with its number of corners. :attr:`PlaceIndex.work` tells the last query's.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import ClassVar, Literal

import numpy as np
from numpy.typing import NDArray
from pydantic import Field

from laser_corners.options import Options
from laser_corners.pose import between_many, compose_many, distinct_poses, invert_many
from laser_corners.registration.corner_grid import CornerGrid
from laser_corners.registration.corners import (
    Corners,
    corner_detector,
    merge_close,
    nearest_corners,
    scan_corners,
)
from laser_corners.registration.correlative import ScoreGrid, search
from laser_corners.scan import LaserScan

__all__ = [
    "PLACES_VERSION",
    "Candidate",
    "PlaceIndex",
    "PlaceOptions",
    "QueryWork",
    "build_index",
    "dense_check",
    "index_arrays",
    "index_from_arrays",
]

PLACES_VERSION = 1
"""Version of the index's arrays in a map folder; another version is not read (the map then
has no index until it is made again)."""


class PlaceOptions(Options):
    """Options of the place index (see the module notes).

    Attributes
    ----------
    enabled : bool
        Propose global candidates from the index (else the exhaustive correlative search).
    detector_preset : {"auto", "paper", "robust"}
        Corner detector of the index and of its queries.
    matches : int
        Nearest map corners (by descriptor) each query corner proposes a pose with.
    max_query : int
        Query corners used at most (after merging): the ``max_query`` nearest the robot.
        The query's work grows with them (the descriptor pass linearly, the consensus as
        their square: each proposes ``matches`` poses that every one votes on), so a
        corner-rich stretch would cost several times the usual attempt (fr079: up to 115
        corner observations in 3 m, more than 40 once merged; a median 10). 40 is some
        three times what one scan of a corner-rich room sees, and the nearest are those the
        newest scans saw from closest, on the shortest odometry chain.
    max_descriptor_distance : float
        Largest descriptor distance (csc L1) of a proposing match.
    max_opening_diff : float
        Largest difference of opening angles (degrees) of a proposing match.
    consensus_radius : float
        A query corner votes for a pose when it lands this close (m) to a map corner...
    consensus_yaw : float
        ... whose bisector is within this angle (rad) of its own.
    min_votes : int
        Votes a candidate needs (distinct query corners, the proposing one included): 2 by
        default, 1 for the localiser (``LocaliseOptions.places``), whose hypotheses dispose of
        weak proposals.
    checked : int
        Best-voted distinct poses given to the dense check.
    candidates : int
        Candidates returned at most (best dense score first) out of the ``checked``.
    query_travel : float
        Odometry travel (m) of the scans whose corners form a query.
    check_xy, check_yaw : float
        Half-widths (m, rad) of the dense check's correlative search around a candidate.
    fallback_travel : float
        Travel (m) of a search without a fix after which the exhaustive correlative search
        runs beside the index (too few corners where the robot is).
    """

    title: ClassVar[str] = "PlaceOptions"

    enabled: bool = True
    detector_preset: Literal["auto", "paper", "robust"] = "auto"
    matches: int = Field(8, ge=1, le=100)
    max_query: int = Field(40, ge=1, le=1000)
    max_descriptor_distance: float = Field(0.6, gt=0.0, le=10.0)
    max_opening_diff: float = Field(20.0, gt=0.0, le=180.0)
    consensus_radius: float = Field(0.3, gt=0.0, le=5.0)
    consensus_yaw: float = Field(0.35, gt=0.0, le=3.2)
    min_votes: int = Field(2, ge=1, le=100)
    checked: int = Field(64, ge=1, le=1000)
    candidates: int = Field(8, ge=1, le=100)
    query_travel: float = Field(3.0, ge=0.0, le=100.0)
    check_xy: float = Field(0.3, ge=0.0, le=5.0)
    check_yaw: float = Field(0.1, ge=0.0, le=3.2)
    fallback_travel: float = Field(1.0, ge=0.0, le=1000.0)


@dataclass
class Candidate:
    """A candidate pose of the query's frame in the map.

    Attributes
    ----------
    pose : ndarray, shape (3,)
    votes : int
        Distinct query corners that agree with it.
    score : float
        The dense check's mean likelihood (NaN before :func:`dense_check`).
    """

    pose: NDArray[np.float64]
    votes: int
    score: float = math.nan


@dataclass(frozen=True)
class QueryWork:
    """The work of one :meth:`PlaceIndex.candidates` call, bounded by the options.

    Attributes
    ----------
    corners : int
        Query corners used (at most ``max_query``).
    proposals : int
        Poses proposed and voted on (at most ``corners * matches``).
    checked : int
        Distinct poses returned for the dense check (at most ``checked``).
    """

    corners: int = 0
    proposals: int = 0
    checked: int = 0


@dataclass
class PlaceIndex:
    """The corners of a map's keyframes (base frames), and queries against them.

    Keyframes are added as they are made (:meth:`add`); :meth:`candidates` takes the
    keyframes' current poses, so a SLAM whose estimates move keeps one index.
    """

    options: PlaceOptions = field(default_factory=PlaceOptions)
    keyframe: NDArray[np.int64] = field(default_factory=lambda: np.zeros(0, np.int64))
    corners: Corners = field(default_factory=Corners.empty)
    _parts: list[tuple[int, Corners]] = field(default_factory=list, init=False, repr=False)
    _cache: tuple[bytes, CornerGrid | None] | None = field(default=None, init=False, repr=False)
    work: QueryWork = field(default_factory=QueryWork, init=False, repr=False)
    """The work of the last :meth:`candidates` call."""

    def __len__(self) -> int:
        self._flush()
        return len(self.corners)

    def add(self, keyframe: int, corners: Corners) -> None:
        """Keyframe ``keyframe``'s corners (its base frame)."""
        if len(corners):
            self._parts.append((keyframe, corners))

    def _flush(self) -> None:
        if not self._parts:
            return
        ids = [np.full(len(c), k, dtype=np.int64) for k, c in self._parts]
        self.keyframe = np.concatenate([self.keyframe, *ids])
        self.corners = Corners.joined([self.corners, *[c for _, c in self._parts]])
        self._parts = []

    def map_corners(self, poses: NDArray[np.float64], upto: int | None = None) -> Corners:
        """The corners in the map frame, keyframes at ``poses`` (rows by keyframe index);
        with ``upto``, only those of keyframes before it."""
        self._flush()
        keep = self.keyframe < (len(poses) if upto is None else upto)
        c = self.corners
        if not keep.any():
            return Corners.empty(c.descriptor.shape[1])
        xyt = compose_many(
            poses[self.keyframe[keep]], np.column_stack([c.xy[keep], c.orientation[keep]])
        )
        return Corners(xyt[:, :2], xyt[:, 2], c.opening[keep], c.descriptor[keep])

    def keyframe_corners(
        self, keyframes: NDArray[np.int64], poses: NDArray[np.float64], frame: NDArray[np.float64]
    ) -> Corners:
        """The corners of ``keyframes`` (at ``poses``, rows by keyframe index) in the frame
        whose origin is at ``frame`` (map frame): a query made of keyframes."""
        self._flush()
        keep = np.isin(self.keyframe, keyframes)
        c = self.corners
        if not keep.any():
            return Corners.empty(c.descriptor.shape[1])
        rel = between_many(frame, poses[self.keyframe[keep]])
        xyt = compose_many(rel, np.column_stack([c.xy[keep], c.orientation[keep]]))
        return Corners(xyt[:, :2], xyt[:, 2], c.opening[keep], c.descriptor[keep])

    def _grid(self, poses: NDArray[np.float64], upto: int | None) -> CornerGrid | None:
        """The map corners at ``poses`` (before keyframe ``upto``) bucketed for the consensus;
        remade only when the poses, ``upto``, the corners or the consensus options (the
        grid's radius and yaw; a caller may replace :attr:`options`) changed."""
        self._flush()
        opt = self.options
        made_of = (upto, len(self.keyframe), opt.consensus_radius, opt.consensus_yaw)
        key = np.asarray(poses, dtype=np.float64).tobytes() + repr(made_of).encode()
        if self._cache is None or self._cache[0] != key:
            mapped = self.map_corners(poses, upto)
            grid = (
                CornerGrid.build(mapped, opt.consensus_radius, opt.consensus_yaw)
                if len(mapped)
                else None
            )
            self._cache = (key, grid)
        return self._cache[1]

    def candidates(
        self, query: Corners, poses: NDArray[np.float64], upto: int | None = None
    ) -> list[Candidate]:
        """The distinct poses (query frame in the map frame) the query's corners agree on,
        most votes first (see the module notes); only keyframes before ``upto`` count."""
        opt = self.options
        self.work = QueryWork()
        if len(query) < opt.min_votes:
            return []
        query = merge_close(query, 0.5 * opt.consensus_radius, opt.consensus_yaw)
        query = nearest_corners(query, opt.max_query)
        grid = self._grid(poses, upto)
        if grid is None or len(query) < opt.min_votes:
            return []
        mapped = grid.corners
        found = grid.nearest(query, opt.max_opening_diff, opt.max_descriptor_distance, opt.matches)
        q_idx, rank = np.nonzero(found >= 0)
        self.work = QueryWork(len(query), int(q_idx.size), 0)
        if q_idx.size == 0:
            return []
        m_idx = found[q_idx, rank]
        at_map = np.column_stack([mapped.xy[m_idx], mapped.orientation[m_idx]])
        at_query = np.column_stack([query.xy[q_idx], query.orientation[q_idx]])
        poses_h = compose_many(at_map, invert_many(at_query))  # the bisectors aligned
        votes = grid.votes(poses_h, query, opt.consensus_radius, opt.consensus_yaw)
        out = _distinct(poses_h, votes, opt)
        self.work = QueryWork(len(query), int(q_idx.size), len(out))
        return out


def _distinct(poses: NDArray, votes: NDArray, opt: PlaceOptions) -> list[Candidate]:
    """The best-voted poses at least 1 m or 0.3 rad apart, at most ``opt.checked``."""
    order = np.argsort(-votes, kind="stable")
    order = order[votes[order] >= opt.min_votes]
    chosen = distinct_poses(poses, order, opt.checked, 1.0, 0.3)
    return [Candidate(poses[i].copy(), int(votes[i])) for i in chosen]


def dense_check(
    candidates: list[Candidate],
    grid: ScoreGrid,
    points: NDArray[np.float64],
    options: PlaceOptions,
) -> list[Candidate]:
    """Each candidate moved to the best pose of a correlative search of ``points`` (query
    frame) on ``grid`` within ``check_xy`` / ``check_yaw`` of it, with that pose's mean
    likelihood as ``score``; the best ``candidates``, best score first.

    The candidates are searched in their order (best voted first) and each search only looks
    for poses beating the ``candidates``-th best score so far (its ``floor``): a window that
    cannot enter the best is left early, and the answer is that of searching every window
    in full. The cost is at most ``checked`` full searches; the floor saves little where the
    windows score alike (149 attempts of fr079, timed again in one process: 4.7 -> 4.3 ms)."""
    kept: list[Candidate] = []
    floor = -1.0
    for cand in candidates:
        score, pose = search(
            grid, points, cand.pose, options.check_xy, options.check_yaw, None, floor
        )
        if score <= floor:
            continue  # nothing in this window enters the best
        kept.append(Candidate(pose, cand.votes, score))
        kept.sort(key=lambda c: -c.score)
        del kept[options.candidates :]
        if len(kept) == options.candidates:
            floor = kept[-1].score
    return kept


def build_index(
    scans: list[LaserScan], mount: NDArray[np.float64], options: PlaceOptions
) -> PlaceIndex:
    """The index of keyframe scans (keyframe ``k`` is ``scans[k]``); ``mount``: base -> laser."""
    index = PlaceIndex(options)
    detector = None
    for k, scan in enumerate(scans):
        detector = detector or corner_detector(options.detector_preset, scan)
        index.add(k, scan_corners(scan, detector, mount))
    return index


def index_arrays(index: PlaceIndex) -> dict[str, NDArray]:
    """The index as arrays for a map folder's ``keyframes.npz`` (keys ``places_*``)."""
    index._flush()
    c = index.corners
    return {
        "places_version": np.int64(PLACES_VERSION),
        "places_keyframe": index.keyframe,
        "places_xy": c.xy.reshape(-1, 2),
        "places_orientation": c.orientation,
        "places_opening": c.opening,
        "places_descriptor": np.asarray(c.descriptor, dtype=np.float32).reshape(len(c), -1)
        if len(c)
        else np.zeros((0, 0), np.float32),
    }


def index_from_arrays(
    arrays: dict[str, NDArray], options: PlaceOptions, n_keyframes: int | None = None
) -> PlaceIndex | None:
    """The index stored by :func:`index_arrays`; None when absent or of another version
    (a map made before the index, or by another version).

    Raises
    ------
    ValueError
        The arrays disagree in length, or name a keyframe outside ``0 .. n_keyframes - 1``.
    """
    if int(arrays.get("places_version", -1)) != PLACES_VERSION:
        return None
    keyframe = np.asarray(arrays["places_keyframe"]).astype(np.int64).reshape(-1)
    m = len(keyframe)
    corners = Corners(
        arrays["places_xy"].astype(np.float64).reshape(-1, 2),
        arrays["places_orientation"].astype(np.float64).reshape(-1),
        arrays["places_opening"].astype(np.float64).reshape(-1),
        np.ascontiguousarray(arrays["places_descriptor"], dtype=np.float32),
    )
    sizes = {len(corners.xy), len(corners.orientation), len(corners.opening)}
    outside = (
        n_keyframes is not None and m and (keyframe.min() < 0 or keyframe.max() >= n_keyframes)
    )
    if sizes != {m} or corners.descriptor.shape[0] != m or corners.descriptor.ndim != 2 or outside:
        raise ValueError("places_* arrays inconsistent")
    return PlaceIndex(options, keyframe, corners)
