"""laser-corners: corner-like keypoints in 2D laser scans.

Implements the line fitting-based corner-like detector of R. B. Sousa, H. M. Sobreira,
M. F. Silva and A. P. Moreira (ICARA 2024, pp. 210-216, doi:10.1109/ICARA60736.2024.10553006)
with a numba kernel, plus readers, a simulator, evaluation tools and keypoint matching.

Examples
--------
>>> from laser_corners import CornerDetector, DetectorParams, LaserScan
"""

from laser_corners.citation import CITATION
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
    "CITATION",
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
