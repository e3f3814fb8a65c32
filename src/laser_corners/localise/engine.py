"""Localisation as the engine's other mode: :class:`EngineTrack`.

The SLAM engine (:class:`~laser_corners.slam.Slam`) runs on the localiser's scans with the map
as its frozen prior (``frozen=True``): it tracks each scan against the map's keyframes near
its pose and its own recent keyframes, makes keyframes, closes loops into the map and
optimises; its pose is the online estimate. The localiser places it: at every fix of the
global search (:meth:`EngineTrack.place`) and where the tracker, anchored in the map,
disagrees with it by more than the gate (``engine.gate_xy`` / ``engine.gate_yaw``) and the
map sides with the tracker (:meth:`EngineTrack.settle`: on ``engine.gate_scans`` scans in a
row the map explains the scan better at the tracker's pose; counted ``engine_replaced``).
Where the map explains it at least as well at the engine's pose, the engine stands and the
tracker follows it: a tracker sliding along a corridor, or one ICP outlier, no longer drags
the engine (and the map's confirmation of it) away. Until the first fix, and from an odometry
or time jump (:meth:`EngineTrack.cut`) to the next fix, it is unplaced and not fed: the scans
of the search cost it nothing, and no keyframe floats in a frame of its own.
Once a scan the map explains has confirmed it, where the map does not explain a scan (the
robot drives out of it) the engine holds the pose (:meth:`EngineTrack.holds`, estimates
``"local"``) if the scan aligned to the engine's keyframes; the localiser also asks that the
scan not contradict the map's free space there, which a kidnap inside the map does.

Cost per scan: the engine's front end (an ICP against a local map of a bounded number of
keyframes) and, per keyframe, an iSAM2 update and a loop-closure check (nothing while
unplaced); it does not grow with the map except through iSAM2's update (the prior map's
keyframes are held by priors).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from laser_corners.localise.estimate import LocaliserEstimate
from laser_corners.localise.options import LocaliseOptions
from laser_corners.pose import between_many, compose_many, invert_many
from laser_corners.registration.mapfolder import SavedMap
from laser_corners.scan import LaserScan
from laser_corners.slam.options import SlamOptions
from laser_corners.slam.slam import Slam

__all__ = ["EngineTrack", "engine_options"]

SHARED = ("min_range", "max_range", "odometry", "time_jump")
"""Options the engine takes from the localiser's (facts of the scanner and the odometry);
the rest are the SLAM's defaults, which track and close loops as the map was made."""


def engine_options(options: LocaliseOptions) -> SlamOptions:
    """The engine's options for a localiser with ``options`` (see :data:`SHARED`)."""
    return SlamOptions(
        relocalisation=False,
        mount=options.mount,
        **{name: getattr(options, name) for name in SHARED},
    )


def _sigmas(covariance: NDArray[np.float64]) -> tuple[float, float, float]:
    """Standard deviations (x, y, yaw) of a pose covariance (its diagonal, bounded below)."""
    d = np.sqrt(np.maximum(np.diag(covariance), 1e-8))
    return (max(float(d[0]), 0.01), max(float(d[1]), 0.01), max(float(d[2]), 0.002))


class EngineTrack:
    """The engine under a localiser (see the module notes).

    Parameters
    ----------
    saved : SavedMap
        The map (a map folder: its keyframes' points become the engine's frozen prior).
    options : LocaliseOptions
    mount : ndarray, shape (3,)
    counts : dict
        The localiser's counters.
    """

    def __init__(
        self, saved: SavedMap, options: LocaliseOptions, mount: NDArray, counts: dict
    ) -> None:
        self.options = options
        self.slam = Slam(engine_options(options), mount, prior_map=saved, frozen=True)
        self.counts = counts
        self.pose: NDArray[np.float64] | None = None
        self.covariance: NDArray[np.float64] | None = None
        self.confirmed = False
        """Whether the map confirmed the engine since it was last placed (a scan the tracker
        anchored in the map, within the gate): only then does it hold the pose alone."""
        self.placed = False
        """Whether the engine is placed in the map (from :meth:`place` to :meth:`cut`): only
        then is it fed scans (unplaced, its keyframes would float in a frame of their own)."""
        self.outvoted = 0
        """Tracked scans in a row on which the map sided with a disagreeing tracker."""

    def place(self, pose: NDArray, covariance: NDArray, odometry: NDArray | None) -> None:
        """The last scan was at ``pose`` (a fix, or the tracker where the engine disagrees;
        ``covariance``: its uncertainty; ``odometry``: its odometry pose, None before the first
        scan): the next scan starts a new segment there, moved by the odometry step
        (:meth:`~laser_corners.slam.Slam.place`); not confirmed yet."""
        self.slam.place(pose, _sigmas(covariance), odometry)
        self.placed, self.confirmed, self.outvoted = True, False, 0

    def cut(self) -> None:
        """The odometry or the stamps jumped: the engine is unplaced (and not fed) until the
        next :meth:`place`, which starts a new segment."""
        if self.placed:
            self.slam.cut()
        self.placed, self.pose, self.covariance = False, None, None

    def add(self, scan: LaserScan, odometry: NDArray, stamp: float) -> None:
        """One scan, while placed: the engine's pose and covariance (:attr:`pose`,
        :attr:`covariance`; None while unplaced)."""
        if self.placed:
            self.pose, self.covariance = self.slam.add(scan, odometry, stamp)

    def disagrees(self, pose: NDArray) -> bool:
        """Whether the engine, placed, is farther than the gate from ``pose`` (or unplaced);
        agreeing with a pose anchored in the map confirms it."""
        if not self.placed or self.pose is None:
            return True
        d = between_many(pose, self.pose)
        opt = self.options
        far = math.hypot(d[0], d[1]) > opt.engine.gate_xy or abs(d[2]) > opt.engine.gate_yaw
        if not far:
            self.confirmed, self.outvoted = True, 0
        return bool(far)

    def settle(
        self, tracked: NDArray, agreement: Callable[[NDArray], float]
    ) -> Literal["engine", "tracker", "replace"]:
        """The tracker, anchored in the map, disagrees with the placed engine on this scan
        (:meth:`disagrees`): the map settles which pose the scan takes.

        ``agreement(pose)``: the share of the scan's points near a map point at ``pose``.
        ``"engine"`` where it is at least as high at the engine's pose (the engine stands,
        confirmed by the map); else ``"tracker"``, or ``"replace"`` (re-place the engine at
        ``tracked``) once that happened on ``engine.gate_scans`` scans in a row."""
        assert self.pose is not None
        if agreement(tracked) <= agreement(self.pose):
            self.confirmed, self.outvoted = True, 0
            return "engine"
        self.outvoted += 1
        return "replace" if self.outvoted >= self.options.engine.gate_scans else "tracker"

    def holds(self) -> bool:
        """Whether the engine alone may give this scan's pose: placed, confirmed by the map
        since, and the scan aligned to its keyframes."""
        return (
            self.placed
            and self.pose is not None
            and self.confirmed
            and self.slam.tracking.scan_aligned
        )

    def alone(self, odometry: NDArray, index: int, stamp: float) -> LocaliserEstimate | None:
        """The engine's estimate of scan ``index`` where the map gives none (``"local"``: the
        scan is placed by the engine's own keyframes), None while it is not placed."""
        if not self.placed or self.pose is None:
            return None
        return self._estimate(odometry, index, stamp, "local", 0.0)

    def estimate(self, tracked: LocaliserEstimate, odometry: NDArray) -> LocaliserEstimate:
        """The tracker's estimate of this scan with the engine's pose and covariance (once the
        map confirmed the engine; before, the tracker's own)."""
        if not (self.placed and self.confirmed) or self.pose is None:
            return tracked
        t = tracked
        return self._estimate(odometry, t.scan_index, t.stamp, t.status, t.agreement)

    def _estimate(
        self, odometry: NDArray, index: int, stamp: float, status: str, agreement: float
    ) -> LocaliserEstimate:
        assert self.pose is not None and self.covariance is not None
        return LocaliserEstimate(
            pose=self.pose.copy(),
            covariance=self.covariance,
            status=status,
            map_to_odom=compose_many(self.pose, invert_many(odometry)),
            scan_index=index,
            stamp=stamp,
            agreement=agreement,
        )
