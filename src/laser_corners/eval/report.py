"""Deprecated: the real-data report moved (data to ``real_summary``, figures to ``viz.report``).

Kept only so ``cli.py`` keeps working until it imports :func:`repeatability_rows` from
:mod:`laser_corners.eval.real_summary` and :func:`write_real_report` from
:mod:`laser_corners.viz.report`; delete this module then. :func:`write_real_report` imports
the figure writer at call time (``viz`` is above ``eval``).
"""

from __future__ import annotations

from pathlib import Path

from laser_corners.eval.real import RealEvaluation
from laser_corners.eval.real_summary import repeatability_rows, summary

__all__ = ["repeatability_rows", "summary", "write_real_report"]


def write_real_report(result: RealEvaluation, output: Path) -> dict[str, Path]:
    """Deprecated alias of :func:`laser_corners.viz.report.write_real_report`."""
    from laser_corners.viz.report import write_real_report as write

    return write(result, output)
