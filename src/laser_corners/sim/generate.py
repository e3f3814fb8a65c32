"""Random worlds (rooms, L-shaped rooms, corridors with doors), poses and trajectories."""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from laser_corners.errors import InvalidParamsError
from laser_corners.pose import wrap_angle
from laser_corners.sim.checks import check_number
from laser_corners.sim.worlds import World, _distance_to_segments, _rotation

__all__ = ["WORLD_KINDS", "random_poses", "random_world", "trajectory"]

WORLD_KINDS: tuple[str, ...] = ("room", "l_room", "corridor")
"""Kinds of world :func:`random_world` builds."""


def _room(rng: np.random.Generator) -> NDArray[np.float64]:
    w, d = rng.uniform(4.0, 9.0), rng.uniform(3.0, 7.0)
    return np.array([[0.0, 0.0], [w, 0.0], [w, d], [0.0, d]])


def _l_room(rng: np.random.Generator) -> NDArray[np.float64]:
    w, d = rng.uniform(5.0, 9.0), rng.uniform(4.0, 7.0)
    cw, cd = rng.uniform(0.3, 0.6) * w, rng.uniform(0.3, 0.6) * d
    return np.array([[0.0, 0.0], [w, 0.0], [w, d - cd], [w - cw, d - cd], [w - cw, d], [0.0, d]])


def _wall_with_doors(
    x0: float, x1: float, y: float, outward: float, rng: np.random.Generator
) -> list[list[float]]:
    """Vertices of a wall from x0 to x1 at height y with recessed doors (depth ``outward``)."""
    step = 1.0 if x1 > x0 else -1.0
    out: list[list[float]] = []
    x = x0 + step * rng.uniform(0.8, 2.0)
    while step * (x1 - x) > 2.0:  # room left for a door and the wall after it
        width = rng.uniform(0.8, 1.0)
        depth = rng.uniform(0.15, 0.3)
        out += [
            [x, y],
            [x, y + outward * depth],
            [x + step * width, y + outward * depth],
            [x + step * width, y],
        ]
        x += step * (width + rng.uniform(1.2, 3.5))
    return out


def _corridor(rng: np.random.Generator) -> NDArray[np.float64]:
    length, width = rng.uniform(8.0, 14.0), rng.uniform(1.6, 2.6)
    verts: list[list[float]] = [[0.0, 0.0]]
    verts += _wall_with_doors(0.0, length, 0.0, -1.0, rng)
    verts += [[length, 0.0], [length, width]]
    verts += _wall_with_doors(length, 0.0, width, 1.0, rng)
    verts += [[0.0, width]]
    return np.array(verts)


def _pillar(rng: np.random.Generator, center: NDArray[np.float64]) -> NDArray[np.float64]:
    if rng.uniform() < 0.7:
        a, b = rng.uniform(0.3, 0.9), rng.uniform(0.3, 0.9)
        shape = np.array([[-a, -b], [a, -b], [a, b], [-a, b]]) / 2.0
    else:  # pentagon or hexagon: corners of 108 or 120 degrees
        k = int(rng.choice([5, 6]))
        radius = rng.uniform(0.25, 0.45)
        t = 2 * np.pi * np.arange(k) / k
        shape = radius * np.column_stack([np.cos(t), np.sin(t)])
    return shape @ _rotation(rng.uniform(0, 2 * np.pi)).T + center


def random_world(
    rng: np.random.Generator, kind: str | None = None, max_obstacles: int = 4
) -> World:
    """A random world: a room, an L-shaped room or a corridor with recessed doors.

    Rooms get up to ``max_obstacles`` pillars (rectangles, pentagons, hexagons) and pairs of
    legs (circles of radius 3-6 cm, 15-25 cm apart); corridors get legs only.

    Parameters
    ----------
    rng : numpy.random.Generator
        Source of randomness (the world is a function of its state).
    kind : str, optional
        One of :data:`WORLD_KINDS`; random when omitted.
    max_obstacles : int
        Upper bound on the number of pillars plus pairs of legs.
    """
    kind = kind if kind is not None else str(rng.choice(WORLD_KINDS))
    builders = {"room": _room, "l_room": _l_room, "corridor": _corridor}
    if kind not in builders:
        raise InvalidParamsError(f"unknown world kind {kind!r}; choose one of: {WORLD_KINDS}")
    world = World(name=kind)
    world.add_polygon(builders[kind](rng))
    lo, hi = world.polygons[0].min(axis=0), world.polygons[0].max(axis=0)
    placed: list[tuple[NDArray[np.float64], float]] = []
    n_obstacles = int(rng.integers(0, max_obstacles + 1))
    for _ in range(n_obstacles):
        is_pillar = kind != "corridor" and rng.uniform() < 0.6
        radius = 0.7 if is_pillar else 0.3
        for _attempt in range(30):
            center = rng.uniform(lo + 0.8, hi - 0.8)
            if not world.is_free(center[None], clearance=radius + 0.3)[0]:
                continue
            if any(np.hypot(*(center - c)) < radius + r + 0.6 for c, r in placed):
                continue
            placed.append((center, radius))
            if is_pillar:
                world.add_polygon(_pillar(rng, center))
            else:
                gap = rng.uniform(0.15, 0.25)
                heading = rng.uniform(0, 2 * np.pi)
                offset = 0.5 * gap * np.array([math.cos(heading), math.sin(heading)])
                for sign in (-1.0, 1.0):
                    c = center + sign * offset
                    world.add_circle((float(c[0]), float(c[1])), float(rng.uniform(0.03, 0.06)))
            break
    return world


def random_poses(
    world: World, n: int, rng: np.random.Generator, clearance: float = 0.4
) -> NDArray[np.float64]:
    """``n`` random sensor poses ``(x, y, theta)`` in the world's free space, shape (n, 3).

    Positions are at least ``clearance`` metres from every wall and obstacle; headings are
    uniform.
    """
    lo, hi = world.polygons[0].min(axis=0), world.polygons[0].max(axis=0)
    found: list[NDArray[np.float64]] = []
    count = 0
    for _ in range(100):
        cand = rng.uniform(lo, hi, size=(max(4 * n, 16), 2))
        ok = cand[world.is_free(cand, clearance)]
        found.append(ok)
        count += ok.shape[0]
        if count >= n:
            break
    xy = np.vstack(found)[:n] if found else np.zeros((0, 2))
    if xy.shape[0] < n:
        raise InvalidParamsError(f"no room for {n} poses with clearance {clearance} m")
    return np.column_stack([xy, rng.uniform(-np.pi, np.pi, n)])


def trajectory(
    world: World,
    n_scans: int,
    rng: np.random.Generator,
    rate_hz: float = 40.0,
    speed: float = 0.5,
    clearance: float = 0.4,
) -> NDArray[np.float64]:
    """A drive through the world's free space sampled at ``rate_hz``: poses, shape (n, 3).

    The robot drives at ``speed`` m/s on straight legs between random collision-free
    waypoints, heading along its motion and turning smoothly (at most 90 deg/s) at waypoints.

    Raises
    ------
    InvalidParamsError
        ``speed`` or ``rate_hz`` is not a finite number > 0, ``clearance`` not one >= 0.
    """
    speed = check_number("speed", speed, positive=True)
    rate_hz = check_number("rate_hz", rate_hz, positive=True)
    clearance = check_number("clearance", clearance)
    dt = 1.0 / rate_hz
    pose = random_poses(world, 1, rng, clearance)[0]
    heading = pose[2]
    out = np.empty((n_scans, 3))
    target = pose[:2]
    max_turn = math.radians(90.0) * dt
    for i in range(n_scans):
        while np.hypot(*(target - pose[:2])) < speed * dt:
            target = _next_waypoint(world, pose[:2], rng, clearance)
        d = target - pose[:2]
        wanted = math.atan2(d[1], d[0])
        turn = float(wrap_angle(wanted - heading))
        heading += float(np.clip(turn, -max_turn, max_turn))
        if abs(turn) < math.radians(20.0):  # drive once roughly facing the waypoint
            step = min(speed * dt, float(np.hypot(*d)))
            pose[:2] = pose[:2] + step * np.array([math.cos(wanted), math.sin(wanted)])
        out[i] = (pose[0], pose[1], math.atan2(math.sin(heading), math.cos(heading)))
    return out


def _next_waypoint(
    world: World, start: NDArray[np.float64], rng: np.random.Generator, clearance: float
) -> NDArray[np.float64]:
    segments = world.segments
    for _ in range(200):
        goal = random_poses(world, 1, rng, clearance)[0, :2]
        if np.hypot(*(goal - start)) < 0.5:
            continue
        path = start + np.linspace(0.0, 1.0, 40)[:, None] * (goal - start)
        if world.is_free(path, 0.5 * clearance).all() and (
            _distance_to_segments(path, segments).min() >= 0.5 * clearance
        ):
            return goal
    raise InvalidParamsError("could not find a collision-free waypoint")
