"""Polygon worlds with known corners."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

from laser_corners.scan import LaserScan
from laser_corners.sim.raycast import cast_ranges
from laser_corners.sim.sensors import UST_10LX, SensorProfile

__all__ = ["World", "corner_scan", "rectangular_room"]


@dataclass
class World:
    """A 2D world made of closed polygons (walls) with their corners as ground truth.

    Attributes
    ----------
    polygons : list of ndarray (V, 2)
        Closed polygons, vertices in order (the last connects back to the first).
    """

    polygons: list[NDArray[np.float64]] = field(default_factory=list)

    def add_polygon(self, vertices: ArrayLike) -> World:
        """Add a closed polygon; returns ``self`` for chaining."""
        self.polygons.append(np.asarray(vertices, dtype=np.float64).reshape(-1, 2))
        return self

    @property
    def segments(self) -> NDArray[np.float64]:
        """All wall segments, shape (S, 4): ``x1, y1, x2, y2``."""
        parts = [np.hstack([p, np.roll(p, -1, axis=0)]) for p in self.polygons]
        return np.vstack(parts) if parts else np.zeros((0, 4))

    @property
    def corners(self) -> NDArray[np.float64]:
        """All polygon vertices, shape (C, 2) (the ground-truth corners)."""
        return np.vstack(self.polygons) if self.polygons else np.zeros((0, 2))

    def visible_corners(
        self,
        pose: tuple[float, float, float],
        sensor: SensorProfile = UST_10LX,
        probe: float = 0.1,
    ) -> NDArray[np.float64]:
        """True corners seen from ``pose``, in the sensor frame, shape (C, 2).

        A corner is seen when it lies in the field of view and range, is not occluded, and
        both of its walls are seen near it: the points ``probe`` metres along each wall from
        the corner are in view and not occluded (this drops silhouette corners of convex
        obstacles, where one wall is hidden).
        """
        px, py, th = pose
        c, s = math.cos(th), math.sin(th)
        rot = np.array([[c, -s], [s, c]])
        segments = self.segments
        out = []
        for poly in self.polygons:
            prev = np.roll(poly, 1, axis=0)
            nxt = np.roll(poly, -1, axis=0)
            for v, a, b in zip(poly, prev, nxt, strict=True):
                probes = [v]
                for w in (a, b):
                    d = w - v
                    length = float(np.hypot(*d))
                    probes.append(v + d / length * min(probe, 0.5 * length))
                pts = (np.array(probes) - np.array([px, py])) @ rot
                dist = np.hypot(pts[:, 0], pts[:, 1])
                bearing = np.arctan2(pts[:, 1], pts[:, 0])
                ok = (
                    (np.abs(bearing) <= math.radians(sensor.fov_deg) / 2)
                    & (dist > sensor.range_min)
                    & (dist < sensor.range_max)
                    & (cast_ranges(segments, pose, bearing) >= dist - 1e-6)
                )
                if ok.all():
                    out.append(pts[0])
        return np.array(out).reshape(-1, 2)

    def scan(
        self,
        pose: tuple[float, float, float],
        sensor: SensorProfile = UST_10LX,
        noise_sigma: float = 0.0,
        rng: np.random.Generator | None = None,
        stamp: float | None = None,
    ) -> LaserScan:
        """Simulate one scan from ``pose``; beams with no hit in range return ``inf``."""
        ranges = cast_ranges(self.segments, pose, sensor.angles)
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


def rectangular_room(width: float = 6.0, depth: float = 4.0) -> World:
    """A ``width`` x ``depth`` room centred on the origin, with a square pillar inside."""
    w, d = width / 2.0, depth / 2.0
    world = World()
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
    world = World()
    world.add_polygon([[cx + 1.5 * sx, cy], [cx, cy], [cx, cy + 1.5 * sy]])
    # an open polyline: drop the closing segment back to the first vertex
    segments = world.segments[:2]
    ranges = cast_ranges(segments, (0.0, 0.0, 0.0), sensor.angles)
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
        frame_id="laser",
    )
