"""laser-corners: corner-like keypoints in 2D laser scans.

Implements the line fitting-based corner-like detector of R. B. Sousa, H. M. Sobreira,
M. F. Silva and A. P. Moreira (ICARA 2024, pp. 210-216, doi:10.1109/ICARA60736.2024.10553006)
with a numba kernel, plus readers, a simulator, evaluation tools and keypoint matching.

The package is lazy: ``import laser_corners`` loads nothing heavy, and each public name below
imports its module (numba and the kernels for :class:`CornerDetector`) on first use, so the
command line's ``--help`` answers at once (scikit-image's pattern, with a module
``__getattr__``).

Examples
--------
>>> from laser_corners import CornerDetector, DetectorParams, LaserScan
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

from laser_corners.kernel_cache import use_keyed_cache

use_keyed_cache()  # numba's cache folder, keyed by the kernel sources: before any kernel loads

if TYPE_CHECKING:  # the names as type checkers and readers see them
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

_LAZY: dict[str, str] = {
    "CITATION": "citation",
    "ClusterError": "errors",
    "CornerDetector": "detector",
    "DetectorParams": "params",
    "InputError": "errors",
    "InvalidParamsError": "errors",
    "InvalidScanError": "errors",
    "Keypoints": "keypoints",
    "LaserCornersError": "errors",
    "LaserScan": "scan",
    "MissingDependencyError": "errors",
    "OutputError": "errors",
    "PAPER_SCALES": "params",
    "Pose2D": "scan",
    "ScaleTable": "detector",
}
"""Public name -> the submodule that defines it (imported on first access)."""

__all__ = [*sorted(_LAZY), "__version__"]


def __getattr__(name: str) -> Any:
    """Import the submodule that defines ``name`` on first access (PEP 562)."""
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module 'laser_corners' has no attribute {name!r}")
    value = getattr(importlib.import_module(f"laser_corners.{module}"), name)
    globals()[name] = value  # later accesses skip this function
    return value


def __dir__() -> list[str]:
    return sorted({*globals(), *_LAZY})
