"""Why place recognition misses and errs: what bounds recall and precision of ``evaluate loops``.

Usage::

    PYTHONPATH=src python benchmarks/loops_diagnosis.py LOG [--methods paper,falko-like]
        [--option max_scan_conflict=0.02 ...] [--summary-only]

Runs :func:`laser_corners.eval.loops.evaluate_loops` (the defaults of ``evaluate loops``), then
asks three questions per method, with the library's own matcher and scan check:

1. **Verifiable queries.** A query with a revisit is *verifiable* when at least one of its
   candidates passes the scan check (``PLACE_RECOGNITION``'s verification, alignment included)
   at the *true* relative pose: no keypoint method can do better than these with this check.
   Printed: recall among the verifiable queries.
2. **Misses that a looser matcher recovers.** For each verifiable query the method missed,
   the query is registered against its verifiable candidates with every keypoint pair as a
   candidate match (descriptor and opening gates off, :data:`LOOSE`): when that still finds
   no correct pose, no keypoint pair of the two scans gives a pose the scan check accepts,
   i.e. the miss is the keypoints' coverage, not the descriptor or the matcher's limits.
3. **Wrong detections.** For each wrong detection at the default threshold: whether any
   accepted registration of that query (against all its candidates) was correct, i.e. whether
   a better choice among the candidates could have fixed it, or the true place was never found.

``--option NAME=VALUE`` (repeatable) changes a field of the matcher's options
(:class:`~laser_corners.matching.MatchOptions`, e.g. a stricter scan check) for the evaluation
and the questions; ``--summary-only`` prints precision and recall at the default threshold and
skips the questions. All numbers depend on the scans, the poses and the detector only (no
randomness).
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

import numba as nb
import numpy as np
from numpy.typing import NDArray

from laser_corners.eval.loops import (
    LoopsConfig,
    LoopsResult,
    evaluate_loops,
    loop_bank,
    loop_detectors,
)
from laser_corners.eval.methods import DEFAULT_METHODS
from laser_corners.eval.real import load_scans
from laser_corners.eval.revisits import travel_distance
from laser_corners.matching import KeypointBank, register_pairs
from laser_corners.matching.kernel_args import KernelOptions, Offsets, ScanArrays, Side
from laser_corners.matching.verify import verify_pose
from laser_corners.scan import LaserScan, pose_error, relative_pose

LOOSE = {
    "max_distance": 100.0,
    "k_nearest": 64,
    "max_opening_difference": 180.0,
    "max_hypotheses": 300,
    "iterations": 3000,
}
"""Matcher options of question 2: every keypoint pair is a candidate match, and up to 300
pose hypotheses (3000 RANSAC draws) go to the scan check."""


@nb.njit(cache=True, parallel=True)
def _verifiable(
    rows: Side,
    offsets: Offsets,
    poses: NDArray[np.float64],
    travel: NDArray[np.float64],
    window: float,
    options: KernelOptions,
    out: NDArray[np.bool_],
) -> None:
    """``out[q, c]``: candidate c passes the scan check at the true pose of c in q."""
    ranges, geom, pts = rows.ranges, rows.geometry, rows.points
    r_off, p_off = offsets.ranges, offsets.points
    n = poses.shape[0]
    for q in nb.prange(n):
        cq, sq = math.cos(poses[q, 2]), math.sin(poses[q, 2])
        scan_q = ScanArrays(ranges[r_off[q] : r_off[q + 1]], geom[q], pts[p_off[q] : p_off[q + 1]])
        for c in range(n):
            if abs(travel[c] - travel[q]) < window:
                continue
            dx, dy = poses[c, 0] - poses[q, 0], poses[c, 1] - poses[q, 1]
            if dx * dx + dy * dy > 400.0:  # 20 m: no overlap on these logs
                continue
            scan_c = ScanArrays(
                ranges[r_off[c] : r_off[c + 1]], geom[c], pts[p_off[c] : p_off[c + 1]]
            )
            pose = (cq * dx + sq * dy, -sq * dx + cq * dy, poses[c, 2] - poses[q, 2])
            agreement, _ = verify_pose(scan_q, scan_c, pose, options)
            out[q, c] = agreement >= 0.0


def _correct_any(
    bank: KeypointBank,
    scans: list[LaserScan],
    query: int,
    cands: NDArray[np.int64],
    config: LoopsConfig,
    options: object,
) -> bool:
    """Some accepted registration of ``query`` against ``cands`` is within the bounds."""
    if cands.size == 0:
        return False
    res = register_pairs(bank, np.full(cands.shape[0], query), cands, options)  # type: ignore[arg-type]
    for t in np.flatnonzero(res.accepted):
        true = relative_pose(scans[query].pose, scans[int(cands[t])].pose)  # type: ignore[arg-type]
        err_xy, err_th = pose_error(tuple(res.poses[t]), true)  # type: ignore[arg-type]
        if err_xy <= config.max_position_error and err_th <= config.max_angle_error:
            return True
    return False


def diagnose(scans: list[LaserScan], result: LoopsResult) -> None:
    """Print the three answers for every method of ``result``."""
    cfg = result.config
    poses = np.array([s.pose for s in scans], dtype=np.float64)
    travel = travel_distance(poses)
    rev = result.has_revisit
    detectors = loop_detectors(list(result.methods), scans[0])
    check = cfg.match.kernel_options("csc")
    loose = cfg.match.with_overrides(LOOSE)
    for name, m in result.methods.items():
        bank = loop_bank(scans, detectors[name](scans), cfg)
        ok_pairs = np.zeros((len(scans), len(scans)), dtype=np.bool_)
        _verifiable(*bank.arrays(), poses, travel, cfg.window_travel, check, ok_pairs)
        verifiable = rev & ok_pairs.any(axis=1)
        found = m.correct & (m.best_inliers >= cfg.min_inliers)
        missed = np.flatnonzero(verifiable & ~found)
        recovered = sum(
            _correct_any(bank, scans, int(q), np.flatnonzero(ok_pairs[q]), cfg, loose)
            for q in missed
        )
        wrong = np.flatnonzero((m.best_inliers >= cfg.min_inliers) & ~m.correct)
        all_cands = [np.flatnonzero(np.abs(travel - travel[q]) >= cfg.window_travel) for q in wrong]
        fixable = sum(
            _correct_any(bank, scans, int(q), c, cfg, cfg.match)
            for q, c in zip(wrong, all_cands, strict=True)
        )
        n_rev, n_ver = max(int(rev.sum()), 1), max(int(verifiable.sum()), 1)
        print(
            f"{name}: {m.keypoints_per_scan:.2f} keypoints/scan; queries with a revisit "
            f"{int(rev.sum())}, verifiable {int(verifiable.sum())} "
            f"({verifiable.sum() / n_rev:.1%})"
            f"; recall {(found & rev).sum() / n_rev:.3f}, among the verifiable "
            f"{(found & verifiable).sum() / n_ver:.3f}"
        )
        print(
            f"  verifiable but missed: {missed.size}; a correct pose with every keypoint "
            f"pair as a match: {recovered} (the rest: no keypoint pair gives a pose the "
            "scan check accepts)"
        )
        print(
            f"  wrong detections: {wrong.size}; with a correct accepted registration among "
            f"the candidates: {fixable}"
        )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("log", type=Path)
    parser.add_argument("--methods", default=",".join(DEFAULT_METHODS))
    parser.add_argument(
        "--option",
        action="append",
        default=[],
        metavar="NAME=VALUE",
        help="a MatchOptions field, e.g. max_distance=0.5",
    )
    parser.add_argument("--summary-only", action="store_true")
    args = parser.parse_args()
    scans, _ = load_scans(args.log, None, None)
    scans = [s for s in scans if s.pose is not None]
    config = LoopsConfig().with_overrides(
        [f"methods={args.methods}", *(f"match.{o}" for o in args.option)]
    )
    changes = args.option
    result = evaluate_loops(scans, config, args.log.name)
    for name, row in result.summary()["methods"].items():
        print(
            f"{name}: precision {row['precision']:.3f} recall {row['recall']:.3f} at T = "
            f"{row['min_inliers']} ({changes or 'the defaults'})"
        )
    if not args.summary_only:
        diagnose(scans, result)


if __name__ == "__main__":
    main()
