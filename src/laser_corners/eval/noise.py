"""Range-noise estimation: moved to :mod:`laser_corners.noise` (the core); re-exported here.

Examples
--------
>>> from laser_corners.eval.noise import estimate_range_noise
>>> estimate_range_noise.__module__
'laser_corners.noise'
"""

from laser_corners.noise import estimate_range_noise

__all__ = ["estimate_range_noise"]
