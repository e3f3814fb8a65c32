"""laser-corners: corner-like keypoints in 2D laser scans.

Implements the line fitting-based corner-like detector of Sousa, Sobreira, Silva and Moreira
(ICARA 2024, doi:10.1109/ICARA60736.2024.10553006) with a numba kernel, plus readers, a
simulator and evaluation tools.

Examples
--------
>>> from laser_corners import CornerDetector, DetectorParams, LaserScan
"""

from laser_corners.detector import CornerDetector, ScaleTable
from laser_corners.errors import (
    ClusterError,
    InputError,
    InvalidParamsError,
    InvalidScanError,
    LaserCornersError,
    MissingDependencyError,
    OutputError,
)
from laser_corners.keypoints import Keypoints
from laser_corners.params import PAPER_SCALES, DetectorParams
from laser_corners.scan import LaserScan, Pose2D

__version__ = "0.1.0"

__all__ = [
    "PAPER_SCALES",
    "ClusterError",
    "CornerDetector",
    "DetectorParams",
    "InputError",
    "InvalidParamsError",
    "InvalidScanError",
    "Keypoints",
    "LaserCornersError",
    "LaserScan",
    "MissingDependencyError",
    "OutputError",
    "Pose2D",
    "ScaleTable",
    "__version__",
]
