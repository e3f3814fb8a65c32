"""Keypoint matching: descriptors, nearest-neighbour matching, verification, SE(2) registration.

>>> from laser_corners.matching import register
>>> # reg = register(scan_a, scan_b); reg.accepted, reg.n_inliers, reg.pose, reg.cov, reg.inliers

See :mod:`laser_corners.matching.registration` for the pipeline,
:mod:`laser_corners.matching.verify` for the scan check (``MatchOptions(verify_scan=True)``),
:mod:`laser_corners.matching.batch` for place recognition over many scans
(:func:`register_many`, :func:`register_pairs`, :data:`PLACE_RECOGNITION`) and
``docs/matching.md``.
"""

from laser_corners.matching.batch import (
    BatchResult,
    KeypointBank,
    register_many,
    register_pairs,
)
from laser_corners.matching.descriptors import (
    DESCRIPTORS,
    DescriptorParams,
    Descriptors,
    describe,
    describe_points,
)
from laser_corners.matching.registration import (
    PLACE_RECOGNITION,
    MatchOptions,
    Registration,
    register,
    register_keypoints,
)

__all__ = [
    "DESCRIPTORS",
    "PLACE_RECOGNITION",
    "BatchResult",
    "DescriptorParams",
    "Descriptors",
    "KeypointBank",
    "MatchOptions",
    "Registration",
    "describe",
    "describe_points",
    "register",
    "register_keypoints",
    "register_many",
    "register_pairs",
]
