"""Place recognition with FLIRT's protocol: ``laser-corners evaluate loops INPUT``.

The protocol of flirtlib's ``RansacLoopClosureTest`` on a log with corrected poses:

* every scan is a *query*, registered with :mod:`laser_corners.matching` (the library's
  matcher, :func:`~laser_corners.matching.register_pairs`, with the scan check on) against
  every other scan outside a local window in time (the *candidates*);
* among the accepted registrations, the candidate with the most inliers (ties: the higher
  scan agreement) gives the query's pose in the map, the candidate's true pose composed with
  the registration;
* the query is a *detection* at threshold ``T`` when that candidate has at least ``T``
  inliers, and a *correct* one when the estimated pose lies within ``max_position_error``
  (0.5 m) and ``max_angle_error`` (0.2 rad) of the query's true pose;
* precision(T) = correct / detections, recall(T) = correct detections of queries that have a
  revisit / queries that have a revisit.

The window and the revisits are defined in :mod:`laser_corners.eval.revisits`
(``docs/place-recognition.md``).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from functools import partial
from typing import Annotated, ClassVar, Literal

import numpy as np
from numpy.typing import NDArray
from pydantic import Field

from laser_corners.errors import InputError
from laser_corners.eval.methods import DEFAULT_METHODS, detect_all, method_factories
from laser_corners.eval.revisits import candidates, revisits, travel_distance
from laser_corners.keypoints import Keypoints
from laser_corners.matching import (
    PLACE_RECOGNITION,
    KeypointBank,
    MatchOptions,
    describe,
    register_pairs,
)
from laser_corners.options import Options
from laser_corners.scan import LaserScan, compose, invert, pose_error

__all__ = [
    "DEFAULT_METHODS",
    "LOOPS_MATCH",
    "LoopsConfig",
    "LoopsResult",
    "MethodLoops",
    "evaluate_loops",
    "loop_bank",
    "loop_detectors",
    "precision_recall",
]


LOOPS_MATCH = PLACE_RECOGNITION
"""Matcher options of ``evaluate loops``: the library's
:data:`~laser_corners.matching.PLACE_RECOGNITION` (scan check on: a registration is accepted
only when the scans agree; one inlier is enough for the kernel, the sweep over T thresholds
the inliers of the accepted registrations afterwards)."""


class LoopsConfig(Options):
    """Settings of :func:`evaluate_loops` (see the module docstring).

    Attributes
    ----------
    methods : tuple of str
        Method names (:func:`loop_detectors`).
    min_inliers : int
        Default detection threshold T, the row of ``loops.json`` (inliers of the best
        accepted registration): 1, the smallest T at which every method reaches precision
        0.98 on the simulator's loop (tests) and on fr079-corrected (docs).
    thresholds : tuple of int
        Thresholds T of the precision-recall sweep.
    max_position_error, max_angle_error : float
        A detection is correct within these of the true pose, metres and radians.
    window_travel : float
        Candidates closer than this in travelled path are excluded, metres.
    revisit_overlap : float
        Share of the query's points a candidate must see for a revisit.
    overlap_tolerance : float
        Range agreement of a seen point, metres.
    max_scans : int or None
        Use at most this many scans (the first ones).
    descriptor : str
        Descriptor kind of :func:`laser_corners.matching.describe`, for every method.
    match : MatchOptions
        Options of :mod:`laser_corners.matching`, for every method (its ``min_inliers`` is
        replaced by the smallest swept threshold).
    """

    title: ClassVar[str] = "LoopsConfig"

    methods: tuple[str, ...] = Field(DEFAULT_METHODS, min_length=1)
    min_inliers: int = Field(1, ge=1)
    thresholds: tuple[Annotated[int, Field(ge=1)], ...] = Field(tuple(range(1, 16)), min_length=1)
    max_position_error: float = Field(0.5, gt=0.0)
    max_angle_error: float = Field(0.2, gt=0.0)
    window_travel: float = Field(5.0, ge=0.0)
    revisit_overlap: float = Field(0.5, gt=0.0, le=1.0)
    overlap_tolerance: float = Field(0.3, gt=0.0)
    max_scans: int | None = Field(None, ge=1)
    descriptor: Literal["bsc", "csc"] = "csc"
    match: MatchOptions = LOOPS_MATCH


@dataclass
class MethodLoops:
    """Per-query outcome of one method (arrays have one entry per query scan).

    Attributes
    ----------
    name, keypoints_per_scan : str, float
        Method name; mean keypoints per scan.
    best_candidate : ndarray of int
        Accepted candidate with the most inliers (-1: no accepted registration).
    best_inliers : ndarray of int
        Its inliers.
    position_error, angle_error : ndarray
        Error of the estimated query pose, metres and radians (inf without one).
    correct : ndarray of bool
        The estimated pose is within the correctness bounds.
    n_pairs : int
        Registered (query, candidate) pairs.
    seconds : dict of str to float
        Wall-clock time of ``detect``, ``describe`` and ``match``.
    """

    name: str
    keypoints_per_scan: float
    best_candidate: NDArray[np.int64]
    best_inliers: NDArray[np.int64]
    position_error: NDArray[np.float64]
    angle_error: NDArray[np.float64]
    correct: NDArray[np.bool_]
    n_pairs: int
    seconds: dict[str, float] = field(default_factory=dict)

    @property
    def ms_per_pair(self) -> float:
        """Matching wall-clock time per pair (all cores), milliseconds."""
        return 1000.0 * self.seconds.get("match", 0.0) / max(self.n_pairs, 1)


@dataclass
class LoopsResult:
    """Everything :func:`evaluate_loops` computed (written by
    :func:`laser_corners.viz.loops_report.write_loops_report`)."""

    source: str
    config: LoopsConfig
    n_scans: int
    has_revisit: NDArray[np.bool_]
    revisit_candidate: NDArray[np.int64]
    methods: dict[str, MethodLoops] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)
    seconds: dict[str, float] = field(default_factory=dict)

    def curve(self, name: str) -> dict[str, NDArray[np.float64]]:
        """Precision-recall sweep of one method over ``config.thresholds``."""
        m = self.methods[name]
        return precision_recall(m.best_inliers, m.correct, self.has_revisit, self.config.thresholds)

    def summary(self) -> dict[str, dict[str, dict[str, float | int | None]]]:
        """The content of ``loops.json``: each method at the default threshold."""
        t = self.config.min_inliers
        out: dict[str, dict[str, float | int | None]] = {}
        for name, m in self.methods.items():
            pr = precision_recall(m.best_inliers, m.correct, self.has_revisit, (t,))
            precision = float(pr["precision"][0])
            out[name] = {
                "precision": None if math.isnan(precision) else precision,
                "recall": float(pr["recall"][0]),
                "min_inliers": t,
                "queries": int(m.best_inliers.shape[0]),
                "ms_per_pair": m.ms_per_pair,
            }
        return {"methods": out}


def precision_recall(
    best_inliers: NDArray[np.int64],
    correct: NDArray[np.bool_],
    has_revisit: NDArray[np.bool_],
    thresholds: Sequence[int],
) -> dict[str, NDArray[np.float64]]:
    """Precision and recall of the best candidates at each threshold T.

    A query is a detection when ``best_inliers >= T``; precision = correct detections /
    detections (NaN without detections); recall = correct detections of queries with a
    revisit / queries with a revisit (0 without any).

    Examples
    --------
    >>> pr = precision_recall(np.array([6, 6, 3, 0]), np.array([True, False, True, False]),
    ...                       np.array([True, True, True, False]), [3, 5])
    >>> pr["precision"].round(3).tolist(), pr["recall"].round(3).tolist()
    ([0.667, 0.5], [0.667, 0.333])
    """
    inl = np.asarray(best_inliers).reshape(-1)
    ok = np.asarray(correct, dtype=bool).reshape(-1)
    rev = np.asarray(has_revisit, dtype=bool).reshape(-1)
    if not inl.shape == ok.shape == rev.shape:
        raise ValueError("best_inliers, correct and has_revisit need one entry per query")
    t = np.asarray(thresholds, dtype=np.int64).reshape(-1)
    detected = inl[None, :] >= t[:, None]
    n_det = detected.sum(axis=1)
    n_ok = (detected & ok[None, :]).sum(axis=1)
    n_ok_rev = (detected & ok[None, :] & rev[None, :]).sum(axis=1)
    n_rev = int(rev.sum())
    with np.errstate(invalid="ignore", divide="ignore"):
        precision = np.where(n_det > 0, n_ok / np.maximum(n_det, 1), np.nan)
    recall = n_ok_rev / n_rev if n_rev else np.zeros(len(t))
    return {
        "min_inliers": t.astype(np.float64),
        "detections": n_det.astype(np.float64),
        "correct": n_ok.astype(np.float64),
        "precision": precision.astype(np.float64),
        "recall": np.asarray(recall, dtype=np.float64),
    }


def loop_detectors(
    names: Sequence[str], sample: LaserScan
) -> dict[str, Callable[[list[LaserScan]], list[Keypoints]]]:
    """Keypoint detectors by method name, from the one registry :mod:`laser_corners.eval.methods`.

    Raises
    ------
    InvalidParamsError
        An unknown name (the message lists the known ones).
    """
    return {
        name: partial(detect_all, factory(sample))
        for name, factory in method_factories(names).items()
    }


QUERY_BLOCK = 32
"""Queries registered per numba call (amortises the start-up of the threads)."""

Progress = Callable[[str, int, int], None]
"""``progress(stage, done, total)``: called as the evaluation advances."""


def loop_bank(
    scans: list[LaserScan], keypoints: list[Keypoints], config: LoopsConfig
) -> KeypointBank:
    """Describe every scan once and put keypoints, descriptors and scans in one bank."""
    desc = [describe(s, k, config.descriptor) for s, k in zip(scans, keypoints, strict=True)]
    return KeypointBank.from_lists(keypoints, desc, scans, config.match.scan_points)


def _evaluate_method(
    name: str,
    detect: Callable[[list[LaserScan]], list[Keypoints]],
    scans: list[LaserScan],
    config: LoopsConfig,
    progress: Progress,
) -> MethodLoops:
    """Detect and describe every scan once, then register each query against its candidates."""
    seconds: dict[str, float] = {}
    t0 = time.perf_counter()
    progress(f"{name}: detecting", 0, len(scans))
    keypoints = detect(scans)
    seconds["detect"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    progress(f"{name}: describing", 0, len(scans))
    bank = loop_bank(scans, keypoints, config)
    seconds["describe"] = time.perf_counter() - t0
    options = config.match.with_overrides({"min_inliers": min(config.thresholds)})
    poses = np.array([s.pose for s in scans], dtype=np.float64)
    travel = travel_distance(poses)
    n = len(scans)
    best_c = np.full(n, -1, dtype=np.int64)
    best_n = np.zeros(n, dtype=np.int64)
    err_xy = np.full(n, np.inf)
    err_th = np.full(n, np.inf)
    n_pairs = 0
    stage = f"{name}: matching"
    t0 = time.perf_counter()
    for lo in range(0, n, QUERY_BLOCK):
        block = range(lo, min(n, lo + QUERY_BLOCK))
        cands = [candidates(travel, q, config.window_travel) for q in block]
        counts = [c.shape[0] for c in cands]
        n_pairs += sum(counts)
        q_arr = np.repeat(np.arange(block.start, block.stop, dtype=np.int64), counts)
        res = register_pairs(bank, q_arr, np.concatenate(cands), options)
        bounds = np.concatenate([[0], np.cumsum(counts)])
        for q, cand, b0, b1 in zip(block, cands, bounds[:-1], bounds[1:], strict=True):
            ok = res.accepted[b0:b1]
            if not ok.any():
                continue
            # the most inliers among the accepted registrations; ties: the higher agreement
            score = np.where(ok, res.n_inliers[b0:b1], -1)
            k = int(np.lexsort((-res.agreement[b0:b1], -score))[0])
            c = int(cand[k])
            est = compose(scans[c].pose, invert(tuple(res.poses[b0 + k])))  # type: ignore[arg-type]
            best_c[q], best_n[q] = c, res.n_inliers[b0 + k]
            err_xy[q], err_th[q] = pose_error(est, scans[q].pose)  # type: ignore[arg-type]
        progress(stage, block.stop, n)
    seconds["match"] = time.perf_counter() - t0
    correct = (err_xy <= config.max_position_error) & (err_th <= config.max_angle_error)
    return MethodLoops(
        name=name,
        keypoints_per_scan=float(np.mean([len(k) for k in keypoints])) if n else 0.0,
        best_candidate=best_c,
        best_inliers=best_n,
        position_error=err_xy,
        angle_error=err_th,
        correct=correct,
        n_pairs=n_pairs,
        seconds=seconds,
    )


def evaluate_loops(
    scans: Sequence[LaserScan],
    config: LoopsConfig | None = None,
    source: str = "",
    progress: Progress | None = None,
    on_method: Callable[[LoopsResult], None] | None = None,
) -> LoopsResult:
    """Run FLIRT's place-recognition protocol for each method of ``config.methods``.

    Parameters
    ----------
    scans : sequence of LaserScan
        A log with corrected sensor poses; scans without a pose are dropped (noted).
    config : LoopsConfig, optional
        Settings.
    source : str
        Name recorded in the report.
    progress : callable, optional
        ``progress(stage, done, total)``.
    on_method : callable, optional
        Called with the (partial) result after each method, e.g. to write the report so far.

    Returns
    -------
    LoopsResult

    Raises
    ------
    InputError
        Fewer than two scans with a pose.
    InvalidParamsError
        An unknown method.
    """
    cfg = config if config is not None else LoopsConfig()
    say = progress if progress is not None else (lambda stage, done, total: None)
    posed = [s for s in scans if s.pose is not None]
    if cfg.max_scans is not None:
        posed = posed[: cfg.max_scans]
    if len(posed) < 2:
        raise InputError(f"{source or 'input'}: fewer than two scans with a pose")
    notes = []
    if len(posed) < len(scans) and cfg.max_scans is None:
        notes.append(f"{len(scans) - len(posed)} scans without a pose dropped")
    detectors = loop_detectors(cfg.methods, posed[0])
    t0 = time.perf_counter()
    say("revisits", 0, 1)
    rev = revisits(posed, cfg.window_travel, cfg.revisit_overlap, cfg.overlap_tolerance)
    say("revisits", 1, 1)
    result = LoopsResult(
        source,
        cfg,
        len(posed),
        rev >= 0,
        rev,
        notes=notes,
        seconds={"revisits": time.perf_counter() - t0},
    )
    # compile or load the kernels once, so the first method's time is matching only
    register_pairs(
        loop_bank(posed[:2], [Keypoints.empty(), Keypoints.empty()], cfg), [0], [1], cfg.match
    )
    for name, detect in detectors.items():
        result.methods[name] = _evaluate_method(name, detect, posed, cfg, say)
        if on_method is not None:
            on_method(result)
    return result
