"""Polygon worlds (walls, pillars) with round obstacles (legs) and known corners."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

from laser_corners.pose import wrap_angle
from laser_corners.scan import LaserScan
from laser_corners.sim.checks import check_number
from laser_corners.sim.raycast import cast_circles, cast_ranges
from laser_corners.sim.sensors import UST_10LX, SensorProfile

__all__ = ["World", "corner_scan", "finish_scan", "rectangular_room"]

CORNER_MIN_TURN_DEG = 10.0
"""A polygon vertex is a corner when the outline turns there by more than this (degrees)."""


def _rotation(theta: float) -> NDArray[np.float64]:
    c, s = math.cos(theta), math.sin(theta)
    return np.array([[c, -s], [s, c]])


@dataclass
class World:
    """A 2D world of closed polygons (walls, pillars) and circles (legs, poles).

    The polygon vertices where the outline turns by more than
    :data:`CORNER_MIN_TURN_DEG` are the ground-truth corners; circles have none. By convention
    the first polygon is the enclosure (the room): :meth:`is_free` treats its inside as free
    space and the inside of every other polygon as occupied.

    Attributes
    ----------
    polygons : list of ndarray (V, 2)
        Closed polygons, vertices in order (the last connects back to the first).
    circles : ndarray, shape (M, 3)
        Circles ``cx, cy, radius``.
    name : str
        What the world is (``"room"``, ``"corridor"``...), for reports.
    """

    polygons: list[NDArray[np.float64]] = field(default_factory=list)
    circles: NDArray[np.float64] = field(default_factory=lambda: np.zeros((0, 3)))
    name: str = "world"

    def add_polygon(self, vertices: ArrayLike) -> World:
        """Add a closed polygon; returns ``self`` for chaining."""
        self.polygons.append(np.asarray(vertices, dtype=np.float64).reshape(-1, 2))
        return self

    def add_circle(self, center: tuple[float, float], radius: float) -> World:
        """Add a round obstacle (a leg, a pole); returns ``self`` for chaining."""
        row = np.array([[center[0], center[1], radius]], dtype=np.float64)
        self.circles = np.vstack([np.asarray(self.circles).reshape(-1, 3), row])
        return self

    @property
    def segments(self) -> NDArray[np.float64]:
        """All wall segments, shape (S, 4): ``x1, y1, x2, y2``."""
        parts = [np.hstack([p, np.roll(p, -1, axis=0)]) for p in self.polygons]
        return np.vstack(parts) if parts else np.zeros((0, 4))

    def _corner_table(self) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
        """Corners with their previous and next vertices, each shape (C, 2)."""
        verts, prevs, nexts = [], [], []
        for poly in self.polygons:
            prev = np.roll(poly, 1, axis=0)
            nxt = np.roll(poly, -1, axis=0)
            a = np.arctan2(poly[:, 1] - prev[:, 1], poly[:, 0] - prev[:, 0])
            b = np.arctan2(nxt[:, 1] - poly[:, 1], nxt[:, 0] - poly[:, 0])
            turn = np.abs(wrap_angle(b - a))
            keep = turn > math.radians(CORNER_MIN_TURN_DEG)
            verts.append(poly[keep])
            prevs.append(prev[keep])
            nexts.append(nxt[keep])
        if not verts:
            empty = np.zeros((0, 2))
            return empty, empty, empty
        return np.vstack(verts), np.vstack(prevs), np.vstack(nexts)

    @property
    def corners(self) -> NDArray[np.float64]:
        """The ground-truth corners (world frame), shape (C, 2)."""
        return self._corner_table()[0]

    @property
    def corner_angles_deg(self) -> NDArray[np.float64]:
        """Opening angle between the two walls at each corner of :attr:`corners`, degrees."""
        v, a, b = self._corner_table()
        u = a - v
        w = b - v
        cos = np.sum(u * w, axis=1) / (np.hypot(u[:, 0], u[:, 1]) * np.hypot(w[:, 0], w[:, 1]))
        return np.degrees(np.arccos(np.clip(cos, -1.0, 1.0)))

    def cast(self, pose: tuple[float, float, float], angles: ArrayLike) -> NDArray[np.float64]:
        """Exact range along each beam angle (sensor frame) to the first wall or circle."""
        return np.minimum(
            cast_ranges(self.segments, pose, angles), cast_circles(self.circles, pose, angles)
        )

    def visible_corner_mask(
        self,
        pose: tuple[float, float, float],
        sensor: SensorProfile = UST_10LX,
        probe: float = 0.1,
        min_beams: float = 0.0,
    ) -> NDArray[np.bool_]:
        """Which of :attr:`corners` are seen from ``pose`` (mask, shape (C,)).

        A corner is seen when it lies in the field of view and range, is not occluded, and
        both of its walls are seen near it: the points ``probe`` metres along each wall from
        the corner (and halfway there) are in view, in range and not occluded, which drops
        silhouette corners of convex obstacles (one wall hidden). With ``min_beams`` > 0 each
        of those wall pieces must also span at least ``min_beams`` beam spacings, so a
        corner whose walls are seen at a grazing angle, or so far that only a beam or two
        land near it, is not counted as seen.
        """
        v, a, b = self._corner_table()
        n = v.shape[0]
        if n == 0:
            return np.zeros(0, dtype=bool)
        px, py, th = pose
        pts = [v]
        for w in (a, b):
            d = w - v
            length = np.hypot(d[:, 0], d[:, 1])[:, None]
            step = np.minimum(probe, 0.5 * length) / length
            pts.append(v + d * step)
            pts.append(v + d * 0.5 * step)
        probes = np.stack(pts, axis=1)  # (C, 5, 2): vertex, far/mid on wall a, far/mid on b
        local = (probes - np.array([px, py])) @ _rotation(th)
        dist = np.hypot(local[..., 0], local[..., 1])
        bearing = np.arctan2(local[..., 1], local[..., 0])
        hit = self.cast(pose, bearing.ravel()).reshape(dist.shape)
        ok = (
            sensor.in_fov(bearing)
            & (dist > sensor.range_min)
            & (dist < sensor.range_max)
            & (hit >= dist - 1e-6 * (1.0 + dist))
        ).all(axis=1)
        if min_beams > 0.0:
            for far in (1, 3):
                span = np.abs(wrap_angle(bearing[:, far] - bearing[:, 0]))
                ok &= span >= min_beams * sensor.angle_increment
        return ok

    def visible_corners(
        self,
        pose: tuple[float, float, float],
        sensor: SensorProfile = UST_10LX,
        probe: float = 0.1,
        min_beams: float = 0.0,
    ) -> NDArray[np.float64]:
        """True corners seen from ``pose``, in the sensor frame, shape (C, 2).

        See :meth:`visible_corner_mask` for what "seen" means.
        """
        mask = self.visible_corner_mask(pose, sensor, probe, min_beams)
        return self.to_sensor_frame(self.corners[mask], pose)

    @staticmethod
    def to_sensor_frame(points: ArrayLike, pose: tuple[float, float, float]) -> NDArray[np.float64]:
        """World-frame points -> sensor frame of ``pose``, shape (P, 2)."""
        p = np.asarray(points, dtype=np.float64).reshape(-1, 2)
        return (p - np.array(pose[:2])) @ _rotation(pose[2])

    def is_free(self, points: ArrayLike, clearance: float = 0.0) -> NDArray[np.bool_]:
        """Whether each point is in free space, at least ``clearance`` from every obstacle.

        Free: inside the first polygon (the enclosure), outside every other polygon and circle.
        """
        p = np.asarray(points, dtype=np.float64).reshape(-1, 2)
        if not self.polygons:
            return np.ones(p.shape[0], dtype=bool)
        free = _inside(self.polygons[0], p)
        for poly in self.polygons[1:]:
            free &= ~_inside(poly, p)
        seg = self.segments
        if clearance > 0.0 and seg.shape[0]:
            free &= _distance_to_segments(p, seg).min(axis=1) >= clearance
        circ = np.asarray(self.circles).reshape(-1, 3)
        if circ.shape[0]:
            d = np.hypot(p[:, None, 0] - circ[None, :, 0], p[:, None, 1] - circ[None, :, 1])
            free &= (d - circ[None, :, 2]).min(axis=1) >= clearance
        return free

    def scan(
        self,
        pose: tuple[float, float, float],
        sensor: SensorProfile = UST_10LX,
        noise_sigma: float = 0.0,
        rng: np.random.Generator | None = None,
        stamp: float | None = None,
    ) -> LaserScan:
        """Simulate one scan from ``pose``.

        Ranges are exact (ray casting) plus Gaussian range noise of ``noise_sigma`` metres;
        beams with no hit within ``sensor.range_max`` return ``inf``.

        Raises
        ------
        InvalidParamsError
            ``noise_sigma`` is negative or not finite.
        """
        ranges = self.cast(pose, sensor.angles)
        return finish_scan(ranges, sensor, noise_sigma, rng, stamp, pose)


def finish_scan(
    ranges: NDArray[np.float64],
    sensor: SensorProfile,
    noise_sigma: float,
    rng: np.random.Generator | None,
    stamp: float | None,
    pose: tuple[float, float, float] | None,
) -> LaserScan:
    """A ``LaserScan`` of ``sensor`` from exact ``ranges`` (modified in place): Gaussian range
    noise of ``noise_sigma`` metres, then the sensor's limits applied."""
    noise_sigma = check_number("noise_sigma", noise_sigma)
    if noise_sigma > 0.0:
        rng = rng if rng is not None else np.random.default_rng()
        finite = np.isfinite(ranges)
        ranges[finite] += rng.normal(0.0, noise_sigma, int(finite.sum()))
    ranges[ranges >= sensor.range_max] = np.inf
    return LaserScan(
        ranges=ranges,
        angle_min=sensor.angle_min,
        angle_increment=sensor.angle_increment,
        range_min=sensor.range_min,
        range_max=sensor.range_max,
        stamp=stamp,
        frame_id="laser",
        pose=pose,
    )


def _inside(poly: NDArray[np.float64], p: NDArray[np.float64]) -> NDArray[np.bool_]:
    """Even-odd point-in-polygon test, vectorised over points."""
    x, y = p[:, 0:1], p[:, 1:2]
    x1, y1 = poly[None, :, 0], poly[None, :, 1]
    nxt = np.roll(poly, -1, axis=0)
    x2, y2 = nxt[None, :, 0], nxt[None, :, 1]
    crosses = (y1 > y) != (y2 > y)
    with np.errstate(divide="ignore", invalid="ignore"):
        x_at = x1 + (y - y1) * (x2 - x1) / (y2 - y1)
    return (np.count_nonzero(crosses & (x < x_at), axis=1) % 2) == 1


def _distance_to_segments(p: NDArray[np.float64], seg: NDArray[np.float64]) -> NDArray[np.float64]:
    """Distance from each point to each segment, shape (P, S)."""
    a = seg[None, :, 0:2]
    e = seg[None, :, 2:4] - a
    w = p[:, None, :] - a
    length2 = np.maximum(np.sum(e * e, axis=2), 1e-300)
    u = np.clip(np.sum(w * e, axis=2) / length2, 0.0, 1.0)
    d = w - u[..., None] * e
    return np.hypot(d[..., 0], d[..., 1])


def rectangular_room(width: float = 6.0, depth: float = 4.0) -> World:
    """A ``width`` x ``depth`` room centred on the origin, with a square pillar inside."""
    w, d = width / 2.0, depth / 2.0
    world = World(name="rectangular room")
    world.add_polygon([[-w, -d], [w, -d], [w, d], [-w, d]])
    world.add_polygon([[1.0, 0.5], [1.5, 0.5], [1.5, 1.0], [1.0, 1.0]])
    return world


def corner_scan(
    corner: tuple[float, float] = (2.0, 1.0),
    sensor: SensorProfile = UST_10LX,
    noise_sigma: float = 0.0,
    rng: np.random.Generator | None = None,
) -> LaserScan:
    """A scan of one clean right-angle concave corner at ``corner`` seen from the origin.

    The two walls run 1.5 m from the corner, parallel to the axes, towards the sensor's side
    (so the sensor looks into the corner).
    """
    cx, cy = corner
    sx = -1.0 if cx >= 0 else 1.0
    sy = -1.0 if cy >= 0 else 1.0
    # an open polyline of two walls (no closing segment)
    segments = np.array([[cx + 1.5 * sx, cy, cx, cy], [cx, cy, cx, cy + 1.5 * sy]])
    ranges = cast_ranges(segments, (0.0, 0.0, 0.0), sensor.angles)
    scan = finish_scan(ranges, sensor, noise_sigma, rng, None, None)
    return scan
