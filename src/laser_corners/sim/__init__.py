"""Laser simulator: polygon worlds, sensor profiles and exact, vectorised ray casting."""

from laser_corners.sim.raycast import cast_ranges
from laser_corners.sim.sensors import UST_10LX, SensorProfile
from laser_corners.sim.worlds import World, corner_scan, rectangular_room

__all__ = [
    "UST_10LX",
    "SensorProfile",
    "World",
    "cast_ranges",
    "corner_scan",
    "rectangular_room",
]
