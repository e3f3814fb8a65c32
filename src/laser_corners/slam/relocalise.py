"""Global relocalisation when the front end is lost: a search of the whole map with no prior.

The front end declares itself lost (:meth:`~laser_corners.slam.Slam.add`) when a scan does
not fit the local map after the correlative rescue and, at the odometry's prediction, sees
through the local map's walls (more than :data:`LOST_CONFLICT` of its beams: a kidnapped
robot, an odometry jump; new ground does not contradict the map), or when a time jump was
not bridged. The keyframe made there starts a new segment under a weak prior (the graph is cut,
the estimate dead-reckons on), and every keyframe of the segment tries to put the segment
back into the map built before it (:class:`Relocaliser`):

1. **Search**: the corners of the segment's keyframes within ``places.query_travel`` (in the
   current keyframe's frame) ask the SLAM's place index
   (:mod:`~laser_corners.registration.place_index`) where they could be among the old
   keyframes; each candidate is moved by a bounded correlative check of the segment's last
   keyframes' points on a likelihood grid of the old map; the :data:`CANDIDATES` best are
   verified. Only when the index has nothing to propose (too few corners), on the first
   :data:`FALLBACK_FIRST` attempts of a segment, the exhaustive search starts instead: the
   best distinct poses of the points on the likelihood grid, every heading, at positions
   within :data:`CENTER_WINDOW` of an old keyframe (thinned to :data:`CENTER_SPACING`), as
   scoring them all would find them, by the whole-map branch and bound
   (:class:`~laser_corners.registration.global_search.SlicedSearch`, its pooled grids made
   at the old map's first exhaustive search). It runs in slices of ``SLICE_NODES`` nodes,
   one a scan (:meth:`Relocaliser.advance`), so no scan waits on it; its answers, for the
   keyframe it searched, are carried by the segment's estimate to the keyframes of the next
   :data:`FALLBACK_FIRST` attempts and verified there.
2. **Verify** each: the loop-closure verification (:func:`~laser_corners.slam.loops.verify`:
   a narrow correlative search and ICP against the nearest old keyframe's submap, overlap,
   degeneracy), then the share of the query on the whole old map (at least
   :data:`MIN_SHARE`), and free-space consistency: at most :data:`MAX_CONFLICT` of the
   query's beams may pass through an old wall (:func:`free_space_conflict`). Two verified
   poses that differ and score within :data:`AMBIGUITY` of each other: no answer (a
   symmetric building).
3. **Agree**: a verified pose is accepted when the next attempt (the next keyframe of the
   segment) implies the same correction of the segment (within :data:`AGREE_XY` /
   :data:`AGREE_YAW`); both become loop closures under the robust model.

Until then the segment dead-reckons (odometry and scan alignment among its own keyframes).
Nothing of this runs while the front end is not lost, so on logs where it never is, results
are those of the loop closure alone.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from laser_corners.pose import (
    compose,
    compose_many,
    invert,
    poses_apart,
    relative_pose,
)
from laser_corners.registration.align import PointMap, match_share
from laser_corners.registration.correlative import ScoreGrid
from laser_corners.registration.global_search import (
    SLICE_NODES,
    Lattice,
    Pyramid,
    SlicedSearch,
    carried,
)
from laser_corners.registration.place_index import PlaceIndex, dense_check
from laser_corners.registration.points import ScanPoints, transform
from laser_corners.slam.counts import SlamCounts
from laser_corners.slam.loops import query_points, thin_points, verify
from laser_corners.slam.options import SlamOptions
from laser_corners.slam.result import LoopClosure

__all__ = [
    "LOST_CONFLICT",
    "OldMap",
    "Relocaliser",
    "free_space_conflict",
    "occupancy_keys",
    "scan_conflict",
]

LOST_CONFLICT = 0.25
"""A failed alignment whose scan, at the predicted pose, sees through the local map's walls
with more than this share of its steep beams (:func:`scan_conflict`): the scan is not where
the estimate says (lost); new ground seen for the first time does not contradict the map."""
GRID_RESOLUTION = 0.15
"""Cell (m) of the global search's likelihood grid."""
GRID_SIGMA = 0.2
"""Width (m) of the global search's likelihood."""
CENTER_SPACING = 1.4
"""Old keyframe positions closer than this (m) share one search window."""
CENTER_WINDOW = 1.0
"""Half-width (m) of the search window around each centre."""
QUERY_KEYFRAMES = 3
"""Keyframes of the segment (the current one and its predecessors) forming the query."""
QUERY_POINTS = 150
"""Points of the query used by the global search at most."""
CANDIDATES = 3
"""Distinct best poses of the global search that are verified."""
DISTINCT_XY = 1.0
"""Two poses of the search at least this far apart (m)..."""
DISTINCT_YAW = 0.3
"""... or turned by at least this (rad) are distinct answers."""
MIN_SHARE = 0.8
"""Share of the query's points within the inlier distance of the old map to accept a pose."""
MAX_CONFLICT = 0.05
"""Share of the query's beams that may pass through an old wall."""
AMBIGUITY = 0.1
"""Two verified distinct poses whose shares differ by less: no answer."""
AGREE_XY = 0.3
"""Two attempts agree when their corrections of the segment differ by less (m)..."""
AGREE_YAW = 0.1
"""... and by less than this (rad)."""
FALLBACK_FIRST = 4
"""The exhaustive search (no candidate from the place index) starts on the first this many
attempts of a lost segment only (a segment still lost after them is mapping new ground, or
lies where the map has no corners: it is left to the index and the ordinary loop closure);
its answers are verified on this many attempts after it ends."""
SEARCH_YAW_STEP = 0.02
"""Heading step (rad) of the exhaustive search (its candidates are verified by a finer search)."""


@dataclass
class OldMap:
    """The map before the lost segment: points in the map frame, a likelihood grid, a point
    map for the share, an occupancy set for free space, the search centres."""

    grid: ScoreGrid
    points: PointMap
    occupied: NDArray[np.int64]
    centres: NDArray[np.float64]
    index: tuple[Pyramid, Lattice] | None = None
    """The grid's pooled levels and the search positions (:meth:`lattice`), made at the
    first :meth:`search`."""

    @classmethod
    def build(
        cls,
        points: list[ScanPoints],
        estimate: NDArray[np.float64],
        end: int,
        prior: tuple[int, NDArray[np.int64]] | None = None,
    ) -> OldMap:
        """The map of keyframes ``0 .. end - 1`` at ``estimate``. ``prior``: the first ``n``
        keyframes are a prior map's whose occupancy (:func:`occupancy_keys`) is given, from
        its occupancy grid (people and doors seen once are cleared there; its keyframes'
        points keep them, and beams of a later visit would cross them)."""
        parts = [transform(points[i].xy, estimate[i]) for i in range(end)]
        xy = thin_points(np.concatenate(parts), 0.05)
        occupied = occupancy_keys(xy)
        if prior is not None and prior[0] <= end:
            n, keys = prior
            rest = [transform(points[i].xy, estimate[i]) for i in range(n, end)]
            own = occupancy_keys(np.concatenate(rest)) if rest else keys[:0]
            occupied = np.union1d(keys, own)
        centres: list[NDArray] = []
        for p in estimate[:end, :2]:
            if all(math.hypot(*(p - q)) >= CENTER_SPACING for q in centres):
                centres.append(p)
        return cls(
            ScoreGrid.build(xy, GRID_RESOLUTION, GRID_SIGMA, CENTER_WINDOW + 1.0),
            PointMap.build(xy, np.zeros_like(xy)),
            occupied,
            np.array(centres),
        )

    def lattice(self) -> Lattice:
        """The search positions: the grid's cells within :data:`CENTER_WINDOW` (a square) of a
        search centre."""
        res = self.grid.resolution
        rows, cols = self.grid.score.shape
        n = math.ceil(CENTER_WINDOW / res)
        allowed = np.zeros((rows, cols), dtype=bool)
        for i, j in np.floor((self.centres - self.grid.origin) / res).astype(np.int64)[:, ::-1]:
            allowed[max(i - n, 0) : i + n + 1, max(j - n, 0) : j + n + 1] = True
        return Lattice(self.grid.origin.copy(), 1, allowed)

    def search(self, query: NDArray[np.float64]) -> list[tuple[float, NDArray[np.float64]]]:
        """The :data:`CANDIDATES` best distinct poses of ``query`` (base frame) over the whole
        map, with their mean likelihood, best first."""
        return [(score, pose) for pose, score in self.slices(query).finish()]

    def slices(self, query: NDArray[np.float64]) -> SlicedSearch:
        """:meth:`search`, to be run in slices."""
        pts = query[np.linspace(0, len(query) - 1, min(len(query), QUERY_POINTS)).astype(int)]
        if self.index is None:
            self.index = (Pyramid.build(self.grid), self.lattice())
        yaws = np.arange(-math.pi, math.pi, SEARCH_YAW_STEP)
        return SlicedSearch(*self.index, pts, yaws, CANDIDATES, (DISTINCT_XY, DISTINCT_YAW))


OCCUPANCY_CELL = 0.05
"""Cell (m) of the old map's occupancy for the free-space check."""


def _steep_beams(points: ScanPoints, mount: NDArray) -> NDArray[np.float64]:
    """The points (base frame) of the beams that hit a line within 60 degrees of its normal:
    a beam grazing a wall runs along the wall's cells before its end, and would count as a
    conflict wherever it is."""
    d = points.xy - np.asarray(mount[:2])
    unit = d / np.maximum(np.hypot(d[:, 0], d[:, 1]), 1e-9)[:, None]
    steep = points.has_normal & (np.abs(np.sum(unit * points.normals, axis=1)) > 0.5)
    return points.xy[steep]


def occupancy_keys(xy: NDArray[np.float64]) -> NDArray[np.int64]:
    """Sorted keys of the :data:`OCCUPANCY_CELL` cells holding a point of ``xy``."""
    return np.unique(_keys(np.floor(xy / OCCUPANCY_CELL).astype(np.int64)))


def _keys(cells: NDArray[np.int64]) -> NDArray[np.int64]:
    return cells[..., 0] * 1_000_003 + cells[..., 1]


def free_space_conflict(
    occupied: NDArray[np.int64], origin: NDArray, xy: NDArray, margin: float = 0.3
) -> float:
    """Share of the beams from ``origin`` (map frame, x, y) to the points ``xy`` (map frame)
    that pass through an occupied cell (``occupied``: :func:`occupancy_keys`) more than
    ``margin`` before their end: beams seeing through walls of the map (the pose is wrong)."""
    if len(xy) == 0 or len(occupied) == 0:
        return 0.0
    d = xy - origin[:2]
    rng = np.hypot(d[:, 0], d[:, 1])
    steps = np.arange(0.2, max(float(rng.max()) - margin, 0.2), OCCUPANCY_CELL)
    if steps.size == 0:
        return 0.0
    unit = d / np.maximum(rng, 1e-9)[:, None]
    samples = origin[None, None, :2] + steps[None, :, None] * unit[:, None, :]
    valid = steps[None, :] < (rng - margin)[:, None]
    keys = _keys(np.floor(samples / OCCUPANCY_CELL).astype(np.int64))
    hit = np.isin(keys, occupied, assume_unique=False) & valid
    return float(hit.any(axis=1).mean())


def scan_conflict(
    occupied: NDArray[np.int64], points: ScanPoints, pose: NDArray, mount: NDArray
) -> float:
    """:func:`free_space_conflict` of a scan's steep beams (:func:`_steep_beams`) at the base
    pose ``pose`` against the map cells ``occupied``."""
    own = _steep_beams(points, mount)
    world = compose_many(pose, np.column_stack([own, np.zeros(len(own))]))
    return free_space_conflict(occupied, np.asarray(compose(pose, mount)), world[:, :2])


@dataclass
class Relocaliser:
    """The state of one lost segment: its first keyframe, the old map, a pending answer."""

    options: SlamOptions
    mount: NDArray[np.float64]
    places: PlaceIndex | None = None
    start: int | None = None
    attempts: int = 0
    old: OldMap | None = None
    pending: LoopClosure | None = None
    pending_shift: NDArray[np.float64] | None = None
    prior: tuple[int, NDArray[np.int64]] | None = None
    """A prior map's keyframe count and occupancy (:meth:`OldMap.build`), when it has a grid."""
    counts: SlamCounts = field(default_factory=SlamCounts)
    """Counts ``relocalisations_attempted``, ``_accepted`` and ``_exhaustive``."""
    running: tuple[SlicedSearch, int] | None = None
    """The exhaustive search under way and the keyframe whose query it searches."""
    answers: tuple[list[NDArray[np.float64]], int, int] | None = None
    """The last exhaustive search's poses, the keyframe they are of, attempts left to them."""

    @property
    def lost(self) -> bool:
        """Whether a lost segment is waiting to be put back into the map."""
        return self.start is not None

    def begin(self, k: int) -> None:
        """Keyframe ``k`` starts a lost segment (nothing to search in without older ones)."""
        if k == 0:
            return
        self.start, self.attempts, self.old, self.pending = k, 0, None, None
        self.running, self.answers = None, None

    def end(self) -> None:
        """The segment is back in the map (or closed by an ordinary loop closure)."""
        self.start, self.old, self.pending = None, None, None
        self.running, self.answers = None, None

    def advance(self) -> None:
        """A scan between keyframes: the exhaustive search under way, if any, goes on by
        :data:`~laser_corners.registration.global_search.SLICE_NODES` nodes."""
        if self.running is None:
            return
        search, at = self.running
        search.advance(SLICE_NODES)
        if search.done:
            self.running = None
            self.answers = ([p for p, _ in search.result()], at, FALLBACK_FIRST)

    def attempt(
        self, k: int, points: list[ScanPoints], estimate: NDArray[np.float64]
    ) -> list[LoopClosure]:
        """Search for keyframe ``k`` of the lost segment: the closures to add (two that agree),
        else none; every verified candidate is returned in ``self.tried``."""
        self.tried: list[LoopClosure] = []
        if self.start is None:
            return []
        self.attempts += 1
        self.counts.relocalisations_attempted += 1
        if self.old is None:
            self.old = OldMap.build(points, estimate, self.start, self.prior)
        query = query_points(k, points, estimate, min(QUERY_KEYFRAMES, k - self.start + 1))
        if len(query) < 20 or len(self.old.centres) == 0:
            return []
        best = self._best(k, query, points, estimate)
        if best is None:
            self.pending = None
            return []
        closure, pose = best
        shift = np.array(compose(pose, invert(estimate[k])))  # map-frame correction
        if self.pending is not None and self.pending_shift is not None:
            d = relative_pose(self.pending_shift, shift)
            if math.hypot(d[0], d[1]) <= AGREE_XY and abs(d[2]) <= AGREE_YAW:
                first = self.pending
                first.reason = closure.reason.replace("(", "(confirmed by the next keyframe, ", 1)
                self.counts.relocalisations_accepted += 1
                self.end()
                return [first, closure]
        closure.accepted = False
        closure.reason = "relocalisation: pending agreement"
        self.pending, self.pending_shift = closure, shift
        return []

    def _candidates(self, k: int, query: NDArray, estimate: NDArray) -> list[NDArray]:
        """Poses of keyframe ``k`` to verify: the place index's (dense-checked), else those of
        the exhaustive search (:meth:`_exhaustive`)."""
        assert self.old is not None and self.start is not None
        if self.places is not None and self.options.places.enabled:
            opt = self.options.places
            near = np.hypot(*(estimate[self.start : k + 1, :2] - estimate[k, :2]).T)
            own = self.start + np.flatnonzero(near <= opt.query_travel)
            corners = self.places.keyframe_corners(own, estimate, estimate[k])
            found = self.places.candidates(corners, estimate, upto=self.start)
            if found:
                self.running = None
                checked = dense_check(found, self.old.grid, query, opt)
                return [c.pose for c in checked[:CANDIDATES]]
        return self._exhaustive(k, query, estimate)

    def _exhaustive(self, k: int, query: NDArray, estimate: NDArray) -> list[NDArray]:
        """The exhaustive search's poses for keyframe ``k``: a search is started (on the
        query of ``k``) on the first :data:`FALLBACK_FIRST` attempts of a segment when none
        runs and no answers are left, and goes on by ``SLICE_NODES`` nodes a scan
        (:meth:`advance`); its answers, carried from the keyframe searched to ``k`` by the
        segment's estimate, are verified on the next :data:`FALLBACK_FIRST` attempts (the
        first and the one to agree with it among them)."""
        assert self.old is not None
        if self.running is None and self.answers is None and self.attempts <= FALLBACK_FIRST:
            self.counts.relocalisations_exhaustive += 1
            self.running = (self.old.slices(query), k)
        self.advance()
        if self.answers is None:
            return []
        poses, at, left = self.answers
        self.answers = (poses, at, left - 1) if left > 1 else None
        return carried(poses, estimate[at], estimate[k])

    def _best(
        self, k: int, query: NDArray, points: list[ScanPoints], estimate: NDArray
    ) -> tuple[LoopClosure, NDArray] | None:
        """The verified pose of keyframe ``k``, unambiguous, or None."""
        assert self.old is not None and self.start is not None
        opt = self.options
        verified: list[tuple[float, LoopClosure, NDArray]] = []
        old_est = estimate[: self.start]
        # the old keyframes always qualify for submaps, the segment's never
        travelled = np.where(np.arange(len(estimate)) < self.start, -1e9, 0.0)
        for pose in self._candidates(k, query, estimate):
            j = int(np.argmin(np.hypot(*(old_est[:, :2] - pose[:2]).T)))
            moved = estimate.copy()
            moved[k] = pose
            closure = verify(k, j, points, moved, travelled, (0.3, 0.15), opt)
            self.tried.append(closure)
            if not closure.accepted:
                continue
            found = np.array(compose(estimate[j], closure.relative))
            share = match_share(query, self.old.points, found, opt.inlier_distance)
            conflict = scan_conflict(self.old.occupied, points[k], found, self.mount)
            if share < MIN_SHARE or conflict > MAX_CONFLICT:
                closure.accepted = False
                closure.reason = f"relocalisation: share {share:.2f}, conflict {conflict:.2f}"
                continue
            if any(not poses_apart(found, p, DISTINCT_XY, DISTINCT_YAW) for _, _, p in verified):
                continue
            closure.reason = f"relocalisation (share {share:.2f}, conflict {conflict:.2f})"
            verified.append((share, closure, found))
        if not verified:
            return None
        verified.sort(key=lambda item: -item[0])
        if len(verified) > 1 and verified[0][0] - verified[1][0] < AMBIGUITY:
            for _, c, _ in verified:
                c.accepted = False
                c.reason = "relocalisation: ambiguous"
            return None
        return verified[0][1], verified[0][2]
