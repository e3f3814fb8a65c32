"""Maps that grow: a SLAM run that starts in a map folder of an earlier run (``prior_map``).

The prior map's keyframes come first in the run's keyframe store, place index and pose graph
(:meth:`~.keyframer.Keyframer.seed`), linked by the map's own pose graph (its ``graph.g2o``:
the odometry / scan-matching links and the loop closures, these robust as the back end makes
them) under the one-run SLAM's priors only (the first keyframe's holds the map's frame): the
new session's closures bend the old map as a one-run SLAM would. A folder without
``graph.g2o`` (an older map) keeps the map put instead: each keyframe held by a strong prior
(:data:`PRIOR_SIGMAS`) and linked to the one before as the map has them. The new session's
keyframes follow. Without an initial pose the first
new keyframe starts a lost segment (:mod:`.relocalise`), searched for in the prior map with
its place index until two attempts agree; with one (the first scan's base pose in the map's
frame) it starts there under a prior of :data:`INITIAL_SIGMAS`. Loop closure then searches
every keyframe, old and new. A session that never finds itself stays its own segment (its
frame: the odometry's), with a warning and the count ``grow_unjoined``.

A prior map keeps only its keyframes' thinned points (``keyframes.npz``), not their scans: the
occupancy grid of the grown map ray-casts the old keyframes from scans remade from those points
(:func:`prior_scans`, one beam per :data:`BEAM_STEP` around the sensor).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from laser_corners.errors import InputError
from laser_corners.io.occupancy import OccupancyGrid
from laser_corners.pose import invert_many
from laser_corners.registration.mapfolder import SavedMap, load_map, read_pose_graph
from laser_corners.registration.points import ScanPoints, transform
from laser_corners.scan import LaserScan
from laser_corners.slam.relocalise import occupancy_keys
from laser_corners.slam.result import LoopClosure

__all__ = [
    "BEAM_STEP",
    "INITIAL_SIGMAS",
    "LOST_SIGMAS",
    "PRIOR_SIGMAS",
    "grid_occupancy",
    "join_warning",
    "load_prior_map",
    "prior_points",
    "prior_scans",
]

PRIOR_SIGMAS = (0.01, 0.01, 0.001)
"""Standard deviations (m, m, rad) of the prior holding each keyframe of a prior map without
``graph.g2o`` (with the links between them): the map stays put (its keyframes move by
millimetres). Such fixed maps scored aces 1.16x and intel 1.13x the one-run SLAM; softer
priors, 0.1 m / 0.01 rad, aces 1.11x but intel 1.33x; the map's own graph is what bends it
right (``docs/benchmarks/grow.md``)."""
INITIAL_SIGMAS = (0.5, 0.5, 0.2)
"""Standard deviations (m, m, rad) of the prior on the first new keyframe at a given initial
pose (loop closures with the prior map then place it)."""
LOST_SIGMAS = (10.0, 10.0, 3.0)
"""Standard deviations (m, m, rad) of the prior on the first new keyframe without an initial
pose (a lost segment; weaker, iSAM2 found the system indeterminate beside the strong
:data:`PRIOR_SIGMAS`)."""
BEAM_STEP = math.radians(0.25)
"""Angle (rad) between the beams of a scan remade from a prior keyframe's points."""
OCCUPIED = 65
"""Percent at which a cell of a prior map's grid is occupied (``map_server``'s default)."""
FRAME = "prior_map"
"""``frame_id`` of a remade scan."""


def load_prior_map(path: str | Path | SavedMap) -> SavedMap:
    """The map folder a run grows (:func:`~laser_corners.registration.mapfolder.load_map`)
    with its pose graph (``SavedMap.graph``,
    :func:`~laser_corners.registration.mapfolder.read_pose_graph`; None without
    ``graph.g2o``), refusing a map of another package (a ``map_server`` YAML has no keyframe
    points to keep).

    Raises
    ------
    InputError
        As ``load_map``, a ``map_server`` map, or a ``graph.g2o`` that is unreadable or not
        of the folder's keyframes (one line saying so).
    """
    saved = path if isinstance(path, SavedMap) else load_map(path)
    if saved.virtual_scans is not None:
        raise InputError(
            f"{saved.folder}: a map_server map has no keyframe scans to grow; give a map "
            "folder written by `laser-corners slam -o`"
        )
    if saved.graph is None:
        saved.graph = read_pose_graph(saved.folder, saved.poses)
    return saved


def grid_occupancy(grid: OccupancyGrid, threshold: int = OCCUPIED) -> NDArray[np.int64]:
    """The occupied cells (at least ``threshold`` percent) of an occupancy grid, as the
    free-space check's keys (:func:`~.relocalise.occupancy_keys` of their centres)."""
    rows, cols = np.nonzero(grid.occupancy >= threshold)
    local = np.column_stack([cols + 0.5, rows + 0.5]) * grid.resolution
    return occupancy_keys(transform(local, np.asarray(grid.origin, dtype=np.float64)))


def prior_points(saved: SavedMap) -> list[ScanPoints]:
    """Each keyframe's points, normals and ``has_normal`` (base frame) of a saved map."""
    out = []
    for a, b in zip(saved.offsets[:-1], saved.offsets[1:], strict=True):
        out.append(
            ScanPoints(
                np.ascontiguousarray(saved.points[a:b]),
                np.ascontiguousarray(saved.normals[a:b]),
                saved.has_normal[a:b].copy(),
            )
        )
    return out


def prior_scans(
    points: list[ScanPoints], mount: NDArray[np.float64], range_max: float
) -> list[LaserScan]:
    """360° scans remade from keyframe points (base frame) for a sensor at ``mount``: each
    beam (:data:`BEAM_STEP`) the range of the nearest point in it, a gap where none is (range
    0: not a beam that saw nothing, which the grid could clear free space along)."""
    n = round(2.0 * math.pi / BEAM_STEP)
    undo = invert_many(np.asarray(mount, dtype=np.float64))
    scans = []
    for p in points:
        ranges = np.zeros(n)
        if len(p.xy):
            xy = transform(p.xy, undo)
            rng = np.hypot(xy[:, 0], xy[:, 1])
            beam = np.round((np.arctan2(xy[:, 1], xy[:, 0]) + math.pi) / BEAM_STEP).astype(int) % n
            order = np.argsort(-rng)  # the nearest written last
            ranges[beam[order]] = rng[order]
        scans.append(
            LaserScan(ranges, -math.pi, BEAM_STEP, 0.0, float(range_max) + 1.0, frame_id=FRAME)
        )
    return scans


def join_warning(closures: list[LoopClosure], first: int, placed: bool) -> str | None:
    """The warning of a session (keyframes from ``first`` on) that never joined the prior map
    (keyframes before ``first``): no accepted closure between the two, and not ``placed`` by
    an initial pose; None when it joined."""
    if placed or any(c.accepted and c.match < first <= c.query for c in closures):
        return None
    return (
        f"the new session never found itself in the prior map ({first} keyframes): it is "
        "kept as its own segment, in its odometry's frame (give --initial-pose?)"
    )
