"""Range-noise estimation: moved to :mod:`laser_corners.noise` (the core); re-exported here."""

from laser_corners.noise import estimate_range_noise

__all__ = ["estimate_range_noise"]
