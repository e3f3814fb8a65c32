"""Global candidates for the localiser from the map's place index (corner keypoints).

:class:`PlaceProposer` keeps the corners of the scans since the search started (the last
``places.query_travel`` metres, chained by odometry) and asks the map's
:class:`~laser_corners.registration.place_index.PlaceIndex` where they could be; each
candidate is moved by a bounded correlative check on the map's likelihood grid
(:func:`~laser_corners.registration.place_index.dense_check`). The localiser then treats the
candidates as it treats the exhaustive search's poses: hypotheses refined by ICP and followed
until one wins (``localise.hypotheses``). An attempt costs milliseconds (the last 10,000 attempts'
times are kept in :attr:`PlaceProposer.ms`), so it runs on every scan of a search.
"""

from __future__ import annotations

import time
from collections import deque

import numpy as np
from numpy.typing import NDArray

from laser_corners.detector import CornerDetector
from laser_corners.localise.estimate import timing_record
from laser_corners.registration.corners import QueryBuffer, corner_detector, scan_corners
from laser_corners.registration.correlative import ScoreGrid
from laser_corners.registration.place_index import (
    Candidate,
    PlaceIndex,
    PlaceOptions,
    QueryWork,
    dense_check,
)
from laser_corners.scan import LaserScan

__all__ = ["PlaceProposer"]


class PlaceProposer:
    """The place index's candidates for the scans of a search (see the module notes).

    Parameters
    ----------
    index : PlaceIndex or None
        The map's index (None: a map made before the index; :attr:`usable` is False).
    poses : ndarray, shape (K, 3)
        The map's keyframe poses.
    grid : ScoreGrid
        The map's likelihood grid (the dense check).
    mount : ndarray, shape (3,)
        Base -> laser transform of the localised robot.
    options : PlaceOptions
    """

    def __init__(
        self,
        index: PlaceIndex | None,
        poses: NDArray[np.float64],
        grid: ScoreGrid,
        mount: NDArray[np.float64],
        options: PlaceOptions,
    ) -> None:
        self.index = index
        if index is not None:
            index.options = options
        self.poses = poses
        self.grid = grid
        self.mount = mount
        self.options = options
        self.buffer = QueryBuffer(options.query_travel)
        self._detector: CornerDetector | None = None
        self.ms: deque[float] = timing_record()
        """Milliseconds of the last 10,000 attempts (query + dense check;
        :data:`~laser_corners.localise.estimate.TIMINGS_KEPT`), oldest first."""
        self.work: deque[QueryWork] = timing_record()
        """The query's work of the last 10,000 attempts (:class:`QueryWork`: corners,
        proposals, poses dense-checked), bounded by the options (``max_query``, ``matches``,
        ``checked``); in step with :attr:`ms`."""

    @property
    def usable(self) -> bool:
        """Whether the index can propose (enabled, and the map has corners)."""
        return (
            self.options.enabled
            and self.index is not None
            and len(self.index) >= self.options.min_votes
        )

    def observe(self, scan: LaserScan, odometry: NDArray[np.float64]) -> None:
        """Keep ``scan``'s corners (with its odometry pose) for the next queries."""
        if not self.usable:
            return
        if self._detector is None:
            self._detector = corner_detector(self.options.detector_preset, scan)
        self.buffer.add(odometry, scan_corners(scan, self._detector, self.mount))

    def clear(self) -> None:
        """Forget the kept scans (a jump: the chain by odometry is broken)."""
        self.buffer.clear()

    def propose(self, points: NDArray[np.float64]) -> list[Candidate]:
        """Candidate base poses of the newest scan, ``points`` its points (base frame), best
        dense score first."""
        if not self.usable:
            return []
        assert self.index is not None
        start = time.perf_counter()
        found = self.index.candidates(self.buffer.query(), self.poses)
        found = dense_check(found, self.grid, points, self.options)
        self.work.append(self.index.work)
        self.ms.append((time.perf_counter() - start) * 1e3)
        return found
