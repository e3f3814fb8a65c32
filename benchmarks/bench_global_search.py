"""CPU milliseconds per whole-map search (``registration/global_search.py``) on the shared maps.

Usage::

    PYTHONPATH=src python benchmarks/bench_global_search.py [LOG ...] [--cache DIR]
        [--scans 10] [--counts 1 4 16] [--output FILE]

LOG is a file of ``../shared/data/real`` (default: ``fr079.bag aces.bag intel.bag
edmonton.clf.gz``), mapped once by ``laser-corners slam`` (cached under ``--cache``, the
folders ``bench_relocalise.py`` makes). Per log:

* **localiser**: ``MapModel.global_search`` with the default options (0.2 m lattice within
  ``global_reach`` of a keyframe, 2° headings, <= 120 points) on ``--scans`` scans spread
  over the log, keeping ``count`` candidates for each of ``--counts`` (16 is the default
  ``global_candidates``); also the map's lattice positions, grid cells and pooled-level bytes.
* **slam**: ``OldMap.search`` (the SLAM's exhaustive relocalisation, 3 candidates) of the map
  of the first 80 % keyframes, queried by 6 later keyframes (3 keyframes' points each).

CPU time of this process (``time.process_time``: less sensitive to other load than wall
time), mean / max per call, the first call (numba's compile or cache load) left out. Writes
the table to ``--output`` (default: stdout only, nothing in the repository).
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from laser_corners.localise import LocaliseOptions
from laser_corners.localise.mapmodel import MapModel
from laser_corners.registration.mapfolder import SavedMap, load_map
from laser_corners.registration.points import ScanPoints, scan_points
from laser_corners.slam.loops import query_points
from laser_corners.slam.relocalise import OldMap

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_localise import REAL, cached_map, read_log
from report import write_table

LOGS = ["fr079.bag", "aces.bag", "intel.bag", "edmonton.clf.gz"]


def _cpu_ms(call, inputs: list) -> str:
    """Mean / max CPU ms of ``call`` over ``inputs`` (after one call to compile or load)."""
    call(inputs[0])
    ms = []
    for x in inputs:
        start = time.process_time()
        call(x)
        ms.append((time.process_time() - start) * 1e3)
    return f"{np.mean(ms):.0f} / {np.max(ms):.0f}"


def localiser_row(saved: SavedMap, path: Path, n_scans: int, counts: list[int]) -> list[str]:
    """Lattice size, grid, pooled bytes and ms per ``global_search`` for each count."""
    opt = LocaliseOptions()
    model = MapModel(saved, opt)
    scans = read_log(path)[0]
    pick = np.linspace(50, len(scans) - 50, n_scans).astype(int)
    pts = [scan_points(scans[i], saved.mount, opt.min_range, opt.max_range, 0.2).xy for i in pick]
    rows, cols = model.grid.score.shape
    out = [f"{len(model.positions):,}", f"{cols} x {rows}", f"{model.pyramid.nbytes / 1e6:.1f}"]
    for count in counts:
        out.append(_cpu_ms(lambda p, c=count: model.global_search(p, opt.global_yaw_step, c), pts))
    return out


def slam_row(saved: SavedMap) -> str:
    """ms per ``OldMap.search`` of the first 80 % keyframes, queried by later keyframes."""
    spans = zip(saved.offsets[:-1], saved.offsets[1:], strict=True)
    points = [
        ScanPoints(saved.points[a:b], saved.normals[a:b], saved.has_normal[a:b]) for a, b in spans
    ]
    end = int(0.8 * len(points))
    old = OldMap.build(points, saved.poses, end)
    later = np.linspace(end + 3, len(points) - 1, 6).astype(int)
    return _cpu_ms(old.search, [query_points(k, points, saved.poses, 3) for k in later])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("logs", nargs="*", default=LOGS)
    parser.add_argument(
        "--cache", type=Path, default=Path(tempfile.gettempdir()) / "laser-corners-reloc"
    )
    parser.add_argument("--scans", type=int, default=10)
    parser.add_argument("--counts", type=int, nargs="+", default=[1, 4, 16])
    parser.add_argument("--output", type=Path)
    args = parser.parse_args()
    head = ["log", "keyframes", "lattice positions", "grid cells", "pooled MB"]
    head += [f"localiser ms, {c} best" for c in args.counts] + ["slam ms, 3 best"]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for name in args.logs:
        path = REAL / name
        saved = load_map(cached_map(path, args.cache / f"{name.split('.')[0]}-full", None))
        cells = [
            f"`{name}`",
            str(len(saved.poses)),
            *localiser_row(saved, path, args.scans, args.counts),
        ]
        lines.append("| " + " | ".join([*cells, slam_row(saved)]) + " |")
        print(lines[-1], flush=True)
    if args.output:
        write_table(args.output, "Whole-map search: CPU ms per call (mean / max)", lines)


if __name__ == "__main__":
    main()
