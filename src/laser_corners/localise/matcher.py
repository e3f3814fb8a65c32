"""One scan against the saved map: :class:`MapMatcher`.

What both the tracking and the global search of :class:`~laser_corners.localise.Localiser` ask
of the map: the information of the odometry prediction (the prior of every alignment), ICP of
a scan's points against the map's points from a guess and the agreement of its result, and the
scan's free-space support at a pose (``localise.freespace``).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from laser_corners.localise.freespace import Support
from laser_corners.localise.mapmodel import MapModel
from laser_corners.localise.options import LocaliseOptions
from laser_corners.registration.align import Alignment, icp, match_share
from laser_corners.registration.odometry import odometry_information

__all__ = ["MapMatcher"]


class MapMatcher:
    """ICP, agreement and free-space support of scans against the saved map.

    Parameters
    ----------
    model : MapModel
        The map's points, lines, grids and free space.
    options : LocaliseOptions
    mount : ndarray, shape (3,)
        Base -> laser transform (the free-space test casts the beams from the laser).
    """

    def __init__(self, model: MapModel, options: LocaliseOptions, mount: NDArray) -> None:
        self.model = model
        self.options = options
        self.mount = mount

    def prior(self, delta: NDArray, jump: bool) -> NDArray[np.float64]:
        """Information of the odometry prediction of the step ``delta`` (a weak one across a
        jump): the one odometry noise model (``registration.odometry``)."""
        return odometry_information(delta, self.options.odometry, jump)

    def align(self, xy: NDArray, guess: NDArray, prior: NDArray) -> tuple[Alignment, float]:
        """ICP of ``xy`` (base frame) against the map from ``guess``, and the agreement of its
        result (the share of the points within ``inlier_distance`` of a map point)."""
        opt = self.options
        aligned = icp(
            xy,
            self.model.lines,
            guess,
            prior,
            opt.icp,
            inlier_distance=opt.inlier_distance,
            sigma=opt.match_sigma,
            overlap_map=self.model.every,
        )
        return aligned, aligned.overlap

    def agreement(self, pose: NDArray, xy: NDArray) -> float:
        """The share of the scan ``xy`` (base frame) at ``pose`` within ``inlier_distance`` of a
        map point (no alignment)."""
        return match_share(xy, self.model.every, pose, self.options.inlier_distance)

    def support(self, pose: NDArray, xy: NDArray) -> Support:
        """Outside / conflict shares of the scan ``xy`` at ``pose`` (``localise.freespace``)."""
        return self.model.space.support(pose, xy, self.mount)

    def admits(self, s: Support) -> bool:
        """Whether a scan with the free-space support ``s`` neither contradicts the map's free
        space (``max_conflict``, ``max_loose_conflict``) nor lies mostly outside the map
        (``max_outside``): what a hypothesis needs."""
        opt = self.options
        return (
            s.conflict <= opt.max_conflict
            and s.loose <= opt.max_loose_conflict
            and s.outside <= opt.max_outside
        )
