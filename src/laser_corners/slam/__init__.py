"""2D SLAM with the library's scans, matching and gtsam (the ``slam`` extra).

:class:`Slam` is the incremental API (``add(scan, odometry, stamp) -> pose, covariance``),
:func:`run_slam` runs it over a recording, :class:`SlamResult` is what both give.
Modules: :mod:`~.options`, :mod:`~.slam` (the orchestrator) over its parts :mod:`~.tracking`
(front end), :mod:`~.keyframer` (keyframes), :mod:`~.closing` (loop closure, relocalisation),
:mod:`~.finish` (final graph and trajectory) and :mod:`~.backend` (gtsam; :mod:`~.factors`,
:mod:`~.recovery`, :mod:`~.batch`), counting into :mod:`~.counts`; :mod:`~.keyframes` (local
map), :mod:`~.loops` (closure verification), :mod:`~.run`, :mod:`~.result`, :mod:`~.output`
(a result as the map folder's contents), :mod:`~.grow` (a run that grows a prior map:
``run_slam(..., prior_map=...)``).
"""

from laser_corners.slam.options import LoopOptions, SlamOptions
from laser_corners.slam.result import Landmarks, LoopClosure, SlamResult
from laser_corners.slam.run import run_slam
from laser_corners.slam.slam import Slam

__all__ = [
    "Landmarks",
    "LoopClosure",
    "LoopOptions",
    "Slam",
    "SlamOptions",
    "SlamResult",
    "run_slam",
]
