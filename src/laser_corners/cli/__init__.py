"""The ``laser-corners`` command line (typer + rich), one module per command group.

* :mod:`~laser_corners.cli.app`: the typer app, :func:`main` (the entry point) and the
  one-line error exit;
* :mod:`~laser_corners.cli.common`: shared options and option checks;
* :mod:`~laser_corners.cli.detect` (``detect``, ``info``, ``plot``, ``params``),
  :mod:`~laser_corners.cli.evaluate` (``evaluate sim|real``),
  :mod:`~laser_corners.cli.loops` (``evaluate loops``), :mod:`~laser_corners.cli.slam`
  (``slam``, ``evaluate slam``), :mod:`~laser_corners.cli.localise`,
  :mod:`~laser_corners.cli.batch`,
  :mod:`~laser_corners.cli.view`,
  :mod:`~laser_corners.cli.sim` (``simulate``, ``demo``, ``warmup``),
  :mod:`~laser_corners.cli.ros` (``ros1``, ``ros2``),
  :mod:`~laser_corners.cli.kernels` (the first run's compile notice).

A command parses its options, makes one library call (mostly :mod:`laser_corners.pipeline`)
and presents the result. Heavy modules (numba kernels, readers, matplotlib) are imported
inside the commands, so ``--help`` stays instant. Known errors
(:class:`~laser_corners.errors.LaserCornersError`, file errors) print one line and exit 2,
in one place: :class:`~laser_corners.cli.app.ErrorLineGroup`.
"""

from laser_corners.cli import (
    batch,
    detect,
    evaluate,
    kernels,
    localise,
    loops,
    ros,
    sim,
    slam,
    view,
)
from laser_corners.cli.app import app, evaluate_app, fail, main

__all__ = [
    "app",
    "batch",
    "detect",
    "evaluate",
    "evaluate_app",
    "fail",
    "kernels",
    "localise",
    "loops",
    "main",
    "ros",
    "sim",
    "slam",
    "view",
]
