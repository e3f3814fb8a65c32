"""Laser simulator: polygon worlds, sensor profiles and exact, vectorised ray casting."""

from laser_corners.sim import sensors
from laser_corners.sim.generate import WORLD_KINDS, random_poses, random_world, trajectory
from laser_corners.sim.raycast import cast_circles, cast_ranges
from laser_corners.sim.sensors import (
    HOKUYO_270_0352,
    SENSORS,
    SICK_LMS_05DEG,
    SICK_LMS_1DEG,
    UST_10LX,
    SensorProfile,
    get_sensor,
)
from laser_corners.sim.worlds import World, corner_scan, rectangular_room

__all__ = [
    *sensors.__all__,
    "WORLD_KINDS",
    "World",
    "cast_circles",
    "cast_ranges",
    "corner_scan",
    "random_poses",
    "random_world",
    "rectangular_room",
    "trajectory",
]
