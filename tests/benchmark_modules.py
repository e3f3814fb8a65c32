"""Modules of ``benchmarks/`` (scripts beside each other, not a package) loaded by path.

The studies that only the benchmarks use live there (``covariance_consistency``,
``registration_errors``), as does the frozen kernel the detector is checked against; the tests
load them with :func:`load`.
"""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path
from types import ModuleType

BENCHMARKS = Path(__file__).resolve().parents[1] / "benchmarks"


def load(name: str) -> ModuleType:
    """``benchmarks/<name>.py`` as module ``name`` (once per process: numba's cache re-imports
    a module by name)."""
    if name not in sys.modules:
        spec = importlib.util.spec_from_file_location(name, BENCHMARKS / f"{name}.py")
        module = importlib.util.module_from_spec(spec)  # type: ignore[arg-type]
        sys.modules[name] = module
        spec.loader.exec_module(module)  # type: ignore[union-attr]
    return sys.modules[name]
