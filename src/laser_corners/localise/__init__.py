"""Localisation in a map that ``laser-corners slam`` wrote (the ``slam`` extra).

:class:`Localiser` is the incremental API (``add(scan, odometry, stamp) -> estimate``),
:func:`run_localise` runs it over a recording. Modules: :mod:`~.options`, :mod:`~.mapmodel`
(the map's point maps and the global search), :mod:`~.hypotheses` (the fix rule),
:mod:`~.window` (the search window of a lost track), :mod:`~.localiser`, :mod:`~.run`.
"""

from laser_corners.localise.localiser import Localiser, LocaliserEstimate
from laser_corners.localise.options import EngineOptions, LocaliseOptions, SmoothOptions
from laser_corners.localise.run import LocaliseRun, run_localise

__all__ = [
    "EngineOptions",
    "LocaliseOptions",
    "LocaliseRun",
    "Localiser",
    "LocaliserEstimate",
    "SmoothOptions",
    "run_localise",
]
