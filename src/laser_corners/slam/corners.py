"""The corner front end: a scan's corners registered to the last keyframe's.

:func:`~laser_corners.matching.register_keypoints` (descriptors ``csc``, RANSAC, the scan
check on) gives the pose of the scan's sensor in the keyframe's sensor frame; moved through
the mount it is the base pose relative to the keyframe. ``front_end=corners`` uses it as the
scan's pose, ``front_end=both`` as the first guess of the point-to-line ICP.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from laser_corners.keypoints import Keypoints
from laser_corners.matching import MatchOptions, describe, register_keypoints
from laser_corners.matching.descriptors import Descriptors
from laser_corners.pose import compose, invert
from laser_corners.scan import LaserScan

__all__ = ["CornerRegistrar"]

MATCH = MatchOptions(verify_scan=True)
"""Matcher options of the front end: the scan check on, so a registration the two scans
contradict is refused."""


class CornerRegistrar:
    """Registers scans to the last keyframe by their corners.

    Parameters
    ----------
    mount : ndarray, shape (3,)
        Base -> laser transform.
    """

    def __init__(self, mount: NDArray[np.float64]) -> None:
        self.mount = tuple(float(v) for v in mount)
        self._unmount = invert(self.mount)
        self._ref: tuple[Keypoints, Descriptors, LaserScan] | None = None
        self.attempts = 0
        self.accepted = 0

    def set_reference(self, scan: LaserScan, kp: Keypoints) -> None:
        """Make ``scan`` (a new keyframe, keypoints ``kp``) the reference."""
        self._ref = (kp, describe(scan, kp, "csc"), scan)

    def register(self, scan: LaserScan, kp: Keypoints) -> NDArray[np.float64] | None:
        """The base pose of ``scan`` in the reference keyframe's base frame, or None when the
        registration is not accepted (too few corners, matches or inliers; scans disagree)."""
        if self._ref is None or len(kp) < 2 or len(self._ref[0]) < 2:
            return None
        self.attempts += 1
        kp_a, d_a, scan_a = self._ref
        reg = register_keypoints(kp_a, d_a, kp, describe(scan, kp, "csc"), MATCH, scan_a, scan)
        if not reg.accepted:
            return None
        self.accepted += 1
        return np.array(compose(compose(self.mount, reg.pose), self._unmount))
