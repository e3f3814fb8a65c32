"""What the map knows to be free, occupied or never seen: :class:`FreeSpace` (issue 20).

A global search that scores only how many scan points land on map points cannot tell a
look-alike place from the right one when the robot is somewhere the map never covered: the
scan's corridor fits a corridor of the map. The free-space grid adds what the map *excludes*:
at load every keyframe ray is walked (numba, half-cell steps) from the keyframe's sensor to
each of its points, counting per cell the rays that end in it (hits) and those that cross it
(misses). Only what the map is **sure** of is used, so that clutter seen once, a person, a
door open once or a wall drawn twice does not make a right pose look wrong:

* a cell is *known* when any ray reached it (else *unknown*);
* *free* only when at least ``FREE_MISSES`` rays crossed it within ``FREE_REACH`` of their
  sensor and none ended in it (farther out a ray's place is not sure to a cell: the map's
  fringe, seen only from afar, is not surely free);
* a *wall* only when at least ``WALL_HITS`` rays ended in it and no more crossed it.

:meth:`FreeSpace.support` then tests a hypothesised pose on a subsample of the scan's beams:

* **outside**: the beam's end point falls where the map saw nothing (no known cell within one
  cell): the scan is partly outside the map;
* **conflict**: the beam's end point lies in a free cell with no cell any ray ended in within
  one cell, or its ray passes through a wall cell more than ``clear`` before its end (the
  scan sees through a wall of the map).

The same pass also gives the **loose** conflict, on any evidence: a cell is *occupied* when
the rays ending in it are at least ``OCCUPIED_RATIO`` of those crossing it, else free when
crossed. Every sure conflict is a loose one. Both are shares of the tested beams. A pose where
the map and the scan contradict each other is not the robot's pose, however many points
agree. Measured on the later-visit runs of aces and intel (issue 20), the right poses'
conflict per scan was median 0.17-0.22, 95th percentile 0.36 on any evidence, median
0.04-0.07, 95th percentile 0.13-0.14 on the sure rules; but two 180° look-alikes of intel
had a sure conflict of 0.05-0.2 and a loose one of 0.4-0.7, so the localiser uses both.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba
import numpy as np
from numpy.typing import NDArray

from laser_corners.registration.mapfolder import SavedMap

__all__ = ["FreeSpace", "Support"]

KNOWN, HIT, FREE, WALL, OCCUPIED = 1, 2, 4, 8, 16
"""Bit flags of a cell of :attr:`FreeSpace.state` (0: unknown)."""
CELL = 0.1
"""Cell (m) of the free-space grid."""
CLEAR = 0.3
"""A ray's last metres (m) before its end point are not tested for walls (noise, grazing
angles, walls one cell thick)."""
FREE_MISSES = 5
"""Rays that must cross a cell, none ending in it, for the cell to be surely free."""
WALL_HITS = 3
"""Rays that must end in a cell, and at least as many as cross it, for a wall: what a person
walking by or a door open once leaves in the map (hit once, crossed by many rays) is not."""
OCCUPIED_RATIO = 0.3
"""The *any-evidence* test: a cell is occupied when the rays ending in it are at least this
share of those crossing it, else free when any ray crossed it."""
FREE_REACH = 10.0
"""Only the first metres (m) of a ray make a cell *surely free*: farther out, a keyframe heading
error of 0.01 rad moves the ray by more than a cell, and thin or glass structures are missed
at grazing angles. At the map's fringe (space the mapping robot saw only from afar) right
poses of aces' later visit contradicted rays 10-30 m long on 0.2-0.3 of their beams."""
BEAMS = 90
"""Beams tested per pose at most (evenly subsampled)."""


@numba.njit(cache=True)
def _carve(
    hits: NDArray[np.int32],
    misses: NDArray[np.int32],
    near: NDArray[np.int32],
    origin: NDArray[np.float64],
    res: float,
    sensors: NDArray[np.float64],
    owner: NDArray[np.int64],
    xy: NDArray[np.float64],
    reach: float,
) -> None:
    """Count, per cell, the rays ending in it (hits), crossing it (misses) and crossing it
    within ``reach`` of their sensor (near misses)."""
    ny, nx = hits.shape
    for k in range(xy.shape[0]):
        sx, sy = sensors[owner[k], 0], sensors[owner[k], 1]
        dx, dy = xy[k, 0] - sx, xy[k, 1] - sy
        length = math.hypot(dx, dy)
        steps = int(max(length - res, 0.0) / (0.5 * res))
        last_x, last_y = -1, -1
        for j in range(steps):
            t = j * 0.5 * res / max(length, 1e-9)
            ix = math.floor((sx + t * dx - origin[0]) / res)
            iy = math.floor((sy + t * dy - origin[1]) / res)
            if (ix != last_x or iy != last_y) and 0 <= ix < nx and 0 <= iy < ny:
                misses[iy, ix] += 1
                if j * 0.5 * res <= reach:
                    near[iy, ix] += 1
            last_x, last_y = ix, iy
        ix = math.floor((xy[k, 0] - origin[0]) / res)
        iy = math.floor((xy[k, 1] - origin[1]) / res)
        if 0 <= ix < nx and 0 <= iy < ny:
            hits[iy, ix] += 1


@numba.njit(cache=True)
def _around(state: NDArray[np.int8], ix: int, iy: int) -> tuple[bool, bool, bool]:
    """Whether the 3 x 3 cells around ``(ix, iy)`` hold a known cell, a cell hit by a ray
    and an occupied cell (any evidence)."""
    ny, nx = state.shape
    known = False
    hit = False
    occupied = False
    for y in range(iy - 1, iy + 2):
        for x in range(ix - 1, ix + 2):
            if 0 <= x < nx and 0 <= y < ny:
                v = state[y, x]
                known = known or (v & KNOWN) != 0
                hit = hit or (v & HIT) != 0
                occupied = occupied or (v & OCCUPIED) != 0
    return known, hit, occupied


@numba.njit(cache=True)
def _support(
    state: NDArray[np.int8],
    origin: NDArray[np.float64],
    res: float,
    sensor: NDArray[np.float64],
    ends: NDArray[np.float64],
    clear: float,
) -> tuple[int, int, int]:
    """Beams ending outside the known map, beams contradicting what it is sure of, and beams
    contradicting any of its evidence (see the module)."""
    outside = 0
    conflict = 0
    loose = 0
    ny, nx = state.shape
    for k in range(ends.shape[0]):
        ex, ey = ends[k, 0], ends[k, 1]
        ix, iy = math.floor((ex - origin[0]) / res), math.floor((ey - origin[1]) / res)
        known, hit, occupied = _around(state, ix, iy)
        bad = not hit and 0 <= ix < nx and 0 <= iy < ny and (state[iy, ix] & FREE) != 0
        bad_any = known and not occupied
        if not known:
            outside += 1
        dx, dy = ex - sensor[0], ey - sensor[1]
        length = math.hypot(dx, dy)
        steps = int(max(length - clear, 0.0) / (0.5 * res))
        for j in range(steps):
            if bad and bad_any:
                break
            t = j * 0.5 * res / max(length, 1e-9)
            ix = math.floor((sensor[0] + t * dx - origin[0]) / res)
            iy = math.floor((sensor[1] + t * dy - origin[1]) / res)
            if 0 <= ix < nx and 0 <= iy < ny:
                bad = bad or (state[iy, ix] & WALL) != 0
                bad_any = bad_any or (state[iy, ix] & OCCUPIED) != 0
        conflict += bad
        loose += bad_any
    return outside, conflict, loose


@dataclass(frozen=True)
class Support:
    """How a scan at a pose fits what the map knows: shares of the tested beams."""

    outside: float
    """Share of beams ending where the map saw nothing."""
    conflict: float
    """Share of beams ending in the map's sure free space or seeing through its sure walls."""
    loose: float = 0.0
    """The same on any evidence (a cell crossed by one ray is free, hit by one ray for three
    crossings occupied): more false conflicts at right poses (clutter, double walls), but
    it also sees the look-alikes the sure test misses."""


@dataclass
class FreeSpace:
    """Free / occupied / unknown grid of a saved map (see the module notes)."""

    state: NDArray[np.int8]
    origin: NDArray[np.float64]
    resolution: float
    mount: NDArray[np.float64]

    @classmethod
    def build(cls, saved: SavedMap, resolution: float = CELL) -> FreeSpace:
        """Walk every keyframe ray of ``saved`` (sensor at the keyframe pose ∘ mount)."""
        xy, _, _ = saved.world_points()
        mount = np.asarray(saved.mount, dtype=np.float64).reshape(3)
        if len(xy) == 0:
            return cls(np.zeros((1, 1), np.int8), np.zeros(2), resolution, mount)
        poses = saved.poses
        c, s = np.cos(poses[:, 2]), np.sin(poses[:, 2])
        sensors = np.column_stack(
            [
                poses[:, 0] + c * mount[0] - s * mount[1],
                poses[:, 1] + s * mount[0] + c * mount[1],
            ]
        )
        lo = np.minimum(xy.min(axis=0), sensors.min(axis=0)) - 1.0
        hi = np.maximum(xy.max(axis=0), sensors.max(axis=0)) + 1.0
        shape = (np.ceil((hi - lo) / resolution).astype(int) + 1)[::-1]
        hits = np.zeros(shape, dtype=np.int32)
        misses = np.zeros(shape, dtype=np.int32)
        near = np.zeros(shape, dtype=np.int32)
        owner = np.repeat(np.arange(len(saved)), np.diff(saved.offsets)).astype(np.int64)
        _carve(
            hits, misses, near, lo, resolution, np.ascontiguousarray(sensors), owner, xy, FREE_REACH
        )
        state = np.where(hits + misses > 0, KNOWN, 0)
        state |= np.where(hits > 0, HIT, 0)
        state |= np.where((near >= FREE_MISSES) & (hits == 0), FREE, 0)
        state |= np.where((hits >= WALL_HITS) & (hits >= misses), WALL, 0)
        state |= np.where((hits > 0) & (hits >= OCCUPIED_RATIO * misses), OCCUPIED, 0)
        return cls(state.astype(np.int8), lo, resolution, mount)

    def support(
        self, pose: NDArray[np.float64], points: NDArray[np.float64], mount: NDArray[np.float64]
    ) -> Support:
        """Outside and conflict shares of ``points`` (base frame) seen from base ``pose`` by a
        sensor at ``mount`` (base -> laser)."""
        if len(points) == 0:
            return Support(1.0, 0.0, 0.0)
        if len(points) > BEAMS:
            points = points[np.linspace(0, len(points) - 1, BEAMS).astype(int)]
        c, s = math.cos(pose[2]), math.sin(pose[2])
        ends = np.column_stack(
            [
                c * points[:, 0] - s * points[:, 1] + pose[0],
                s * points[:, 0] + c * points[:, 1] + pose[1],
            ]
        )
        m = mount
        sensor = np.array([pose[0] + c * m[0] - s * m[1], pose[1] + s * m[0] + c * m[1]])
        outside, conflict, loose = _support(
            self.state, self.origin, self.resolution, sensor, ends, CLEAR
        )
        n = len(points)
        return Support(outside / n, conflict / n, loose / n)
