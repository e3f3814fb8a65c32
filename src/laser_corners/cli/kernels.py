"""The first run's kernel compilation: said once, and ``warmup`` to do it ahead.

numba compiles the detector's kernels on their first call and caches them on disk
(``cache=True``): the first run after an install or an upgrade spends about 30 s (26-35 s
measured) compiling before it detects anything. Commands that detect use
:class:`KernelCommand`, which says so on stderr when the cache is cold, so a first run does
not look hung (or report a slow scans/s without a word). ``laser-corners warmup``
(:mod:`~laser_corners.cli.sim`) compiles them ahead (``make`` runs it after installing).
"""

from __future__ import annotations

import os
import sys
from typing import Any

import typer
import typer.core

__all__ = ["COMPILING", "KernelCommand", "kernels_are_cold"]

COMPILING = "compiling the detector's kernels (first run only, about 30 s)..."
"""What a detecting command says on stderr when the kernel cache is cold."""

DETECTOR_MODULES = ("laser_corners.kernel.", "laser_corners.noise", "laser_corners.pose")
"""The modules whose kernels the detector runs (and ``warmup`` compiles): a stale index of
another room's kernel (after an upgrade, until that kernel runs again) must not make every
detecting command say it compiles."""


def kernels_are_cold() -> bool:
    """Whether numba will compile the detector's kernels in this process.

    Reads numba's on-disk cache index of every cached (``cache=True``) kernel of the modules
    the detector runs (:data:`DETECTOR_MODULES`): cold when none has a usable index (a fresh
    install, an empty ``NUMBA_CACHE_DIR``) or when any index is stale (its source file
    changed, or another numba version wrote it). Kernels that never ran on their own (inlined
    helpers) have no index and do not count. Unknown cache layouts count as warm (no message
    rather than a wrong one).
    """
    from numba.core.dispatcher import Dispatcher

    import laser_corners.detector  # noqa: F401  (loads every kernel module)

    usable = stale = 0
    for name, module in list(sys.modules.items()):
        if not name.startswith(DETECTOR_MODULES) or module is None:
            continue  # other rooms' kernels (matching, slam...): warmup does not compile them
        for obj in list(vars(module).values()):
            if not isinstance(obj, Dispatcher) or obj.py_func.__module__ != name:
                continue
            cache_file = getattr(getattr(obj, "_cache", None), "_cache_file", None)
            index_path = getattr(cache_file, "_index_path", None)
            if index_path is None or not os.path.exists(index_path):
                continue  # caching off, or a kernel that never ran on its own
            try:
                fresh = bool(cache_file._load_index())  # type: ignore[union-attr]
            except Exception:
                return False
            usable, stale = usable + fresh, stale + (not fresh)
    return usable == 0 or stale > 0


class KernelCommand(typer.core.TyperCommand):
    """A command that detects: says once on stderr that it compiles when the cache is cold.

    The check runs after the options are parsed (``--help`` stays instant).
    """

    def invoke(self, ctx: typer.Context) -> Any:  # type: ignore[override]
        if kernels_are_cold():
            typer.echo(f"laser-corners: {COMPILING}", err=True)
        return super().invoke(ctx)
