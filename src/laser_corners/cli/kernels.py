"""The first run's kernel compilation: said once, and ``warmup`` to do it ahead.

numba compiles the detector's kernels on their first call and caches them on disk
(``cache=True``): the first run after an install or an upgrade spends about 30 s (26-35 s
measured) compiling before it detects anything. Commands that detect use
:class:`KernelCommand`, which says so on stderr when the cache is cold, so a first run does
not look hung (or report a slow scans/s without a word). ``slam`` and ``localise`` use
:class:`SlamKernelCommand`, which does the same for the kernels of the SLAM, the localiser
and the matching (about 15 s more on a first run). ``laser-corners warmup``
(:mod:`~laser_corners.cli.sim`) compiles both ahead (``make`` runs it after installing).
"""

from __future__ import annotations

import os
import sys
from typing import Any

import typer
import typer.core

__all__ = [
    "COMPILING",
    "COMPILING_SLAM",
    "KernelCommand",
    "SlamKernelCommand",
    "kernels_are_cold",
    "slam_kernels_are_cold",
    "warm_slam_kernels",
]

COMPILING = "compiling the detector's kernels (first run only, about 30 s)..."
"""What a detecting command says on stderr when the kernel cache is cold."""

COMPILING_SLAM = "compiling the SLAM kernels (first run only, about 15 s)..."
"""What ``slam`` and ``localise`` say on stderr when their kernels' cache is cold."""

DETECTOR_MODULES = ("laser_corners.kernel.", "laser_corners.noise", "laser_corners.pose")
"""The modules whose kernels the detector runs (and ``warmup`` compiles): a stale index of
another room's kernel (after an upgrade, until that kernel runs again) must not make every
detecting command say it compiles."""


SLAM_MODULES = (
    "laser_corners.registration.",
    "laser_corners.slam.",
    "laser_corners.localise.",
    "laser_corners.matching.",
)
"""The modules of the SLAM's, the localiser's and the matching's own kernels (``warmup``
compiles them after the detector's)."""


def slam_kernels_are_cold() -> bool:
    """:func:`kernels_are_cold` for the kernels of :data:`SLAM_MODULES`."""
    import laser_corners.localise.mapmodel
    import laser_corners.matching
    import laser_corners.slam  # noqa: F401

    return _cold(SLAM_MODULES)


def kernels_are_cold() -> bool:
    """Whether numba will compile the detector's kernels in this process.

    Reads numba's on-disk cache index of every cached (``cache=True``) kernel of the modules
    the detector runs (:data:`DETECTOR_MODULES`): cold when none has a usable index (a fresh
    install, an empty ``NUMBA_CACHE_DIR``) or when any index is stale (its source file
    changed, or another numba version wrote it). Kernels that never ran on their own (inlined
    helpers) have no index and do not count. Unknown cache layouts count as warm (no message
    rather than a wrong one).
    """
    import laser_corners.detector  # noqa: F401  (loads every kernel module)

    return _cold(DETECTOR_MODULES)


def _cold(modules: tuple[str, ...]) -> bool:
    """Whether any cached kernel of ``modules`` (loaded) has a stale index, or none a usable
    one (see :func:`kernels_are_cold`)."""
    from numba.core.dispatcher import Dispatcher

    usable = stale = 0
    for name, module in list(sys.modules.items()):
        if not name.startswith(modules) or module is None:
            continue  # other rooms' kernels: another check
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


class SlamKernelCommand(typer.core.TyperCommand):
    """``slam`` and ``localise``: say once on stderr that the SLAM's kernels compile when
    their cache is cold (the detector's notice when only the detector's is)."""

    def invoke(self, ctx: typer.Context) -> Any:  # type: ignore[override]
        if slam_kernels_are_cold():
            typer.echo(f"laser-corners: {COMPILING_SLAM}", err=True)
        return super().invoke(ctx)


def warm_slam_kernels() -> None:
    """Compile (or load) the kernels of the SLAM, the localiser and the matching: a short
    simulated drive mapped with every front end part on (corner registration, landmarks,
    loop closure search), its occupancy grid, and the localiser's global search in it (the
    whole-map branch and bound)."""
    import tempfile

    import numpy as np

    from laser_corners.localise import Localiser
    from laser_corners.registration.mapfolder import save_map_data
    from laser_corners.registration.points import scan_points
    from laser_corners.sim import SICK_LMS_1DEG, World
    from laser_corners.slam import LoopOptions, Slam, SlamOptions
    from laser_corners.slam.grid import result_grid

    world = World().add_polygon([[0, 0], [8, 0], [8, 5], [0, 5]])
    world.add_polygon([[3, 2], [3.8, 2], [3.8, 2.7], [3, 2.7]])
    rng = np.random.default_rng(0)
    poses = [(1.0 + 0.1 * i, 1.0 + 0.05 * i, 0.02 * i) for i in range(40)]
    scans = [
        world.scan(p, SICK_LMS_1DEG, noise_sigma=0.01, rng=rng, stamp=0.1 * i)
        for i, p in enumerate(poses)
    ]
    loop = LoopOptions(recent_distance=0.5, every=1)
    options = SlamOptions(front_end="both", landmarks=True, loop=loop)
    slam = Slam(options)
    for i, (pose, scan) in enumerate(zip(poses, scans, strict=True)):
        slam.add(scan, pose, 0.1 * i)
    result = slam.result()
    result_grid(result)
    with tempfile.TemporaryDirectory() as folder:
        save_map_data(result, folder)
        localiser = Localiser(folder)
        for i, (pose, scan) in enumerate(zip(poses, scans, strict=True)):
            localiser.add(scan, pose, 0.1 * i)
        # the whole-map search (the index answers above): its branch and bound, as both
        # the localiser's and the SLAM's exhaustive relocalisation run it
        points = scan_points(scans[0], np.zeros(3), 0.1, 30.0, 0.2).xy
        localiser.map.global_search(points, 0.1, 2)
