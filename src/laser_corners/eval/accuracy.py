"""Ground-truth accuracy benchmark on simulated scans (``laser-corners evaluate sim``).

Random worlds (:func:`~laser_corners.sim.random_world`) are scanned from random poses with a
sweep of range-noise levels; each method's keypoints are matched to the true corners:

* a *visible* corner (:meth:`~laser_corners.sim.World.visible_corner_mask` with ``probe`` and
  ``min_beams``) is *found* when a keypoint lies within ``match_radius`` of it, keypoints and
  visible corners paired one-to-one by minimum total distance (Hungarian assignment);
* a keypoint is *false* when no corner of the world (visible or not) lies within
  ``match_radius``;
* localisation error: distance of each found corner to its paired keypoint;
* keypoints per corner: keypoints whose nearest world corner is a found visible corner within
  ``match_radius``, divided by the number of found corners (1.0: no duplicates).
"""

from __future__ import annotations

import csv
import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.optimize import linear_sum_assignment

from laser_corners.eval.methods import MethodFactory, method_factories
from laser_corners.sim.generate import random_poses, random_world
from laser_corners.sim.sensors import UST_10LX, SensorProfile
from laser_corners.sim.worlds import World

__all__ = [
    "DEFAULT_SIGMAS",
    "AccuracyStats",
    "ScanMatch",
    "SimCase",
    "default_methods",
    "make_cases",
    "markdown_table",
    "match_scan",
    "run_sweep",
    "write_tables",
]

DEFAULT_SIGMAS: tuple[float, ...] = (0.0, 0.005, 0.01, 0.02, 0.03)
"""Range-noise levels of the default sweep, metres."""


@dataclass(frozen=True)
class ScanMatch:
    """Keypoints of one scan matched against the true corners."""

    n_visible: int
    n_found: int
    n_keypoints: int
    n_false: int
    n_on_found: int
    errors: NDArray[np.float64]


def match_scan(
    keypoints: ArrayLike,
    visible: ArrayLike,
    all_corners: ArrayLike,
    match_radius: float = 0.1,
) -> ScanMatch:
    """Match one scan's keypoints to its true corners (all in the same frame).

    Parameters
    ----------
    keypoints : array_like, shape (M, 2)
        Detected keypoints.
    visible : array_like, shape (V, 2)
        True corners seen from the pose (to be found).
    all_corners : array_like, shape (C, 2)
        Every corner of the world (a keypoint near any of them is not false).
    match_radius : float
        Match distance, metres.
    """
    kp = np.asarray(keypoints, dtype=np.float64).reshape(-1, 2)
    vis = np.asarray(visible, dtype=np.float64).reshape(-1, 2)
    allc = np.asarray(all_corners, dtype=np.float64).reshape(-1, 2)
    errors = np.zeros(0)
    found_idx = np.zeros(0, dtype=np.int64)
    if len(kp) and len(vis):
        d = np.hypot(vis[:, None, 0] - kp[None, :, 0], vis[:, None, 1] - kp[None, :, 1])
        cost = np.where(d <= match_radius, d, 1e6)
        rows, cols = linear_sum_assignment(cost)
        ok = d[rows, cols] <= match_radius
        errors = d[rows[ok], cols[ok]]
        found_idx = rows[ok]
    n_false = len(kp)
    n_on_found = 0
    if len(kp) and len(allc):
        d_all = np.hypot(kp[:, None, 0] - allc[None, :, 0], kp[:, None, 1] - allc[None, :, 1])
        nearest = d_all.argmin(axis=1)
        near = d_all[np.arange(len(kp)), nearest] <= match_radius
        n_false = int(np.count_nonzero(~near))
        if len(found_idx):
            found_xy = vis[found_idx]
            on = (
                np.hypot(
                    allc[nearest, 0][:, None] - found_xy[None, :, 0],
                    allc[nearest, 1][:, None] - found_xy[None, :, 1],
                ).min(axis=1)
                < 1e-9
            )
            n_on_found = int(np.count_nonzero(near & on))
    return ScanMatch(len(vis), len(errors), len(kp), n_false, n_on_found, errors)


@dataclass
class AccuracyStats:
    """Accumulated matches of one method at one noise level."""

    method: str
    sigma: float
    n_scans: int = 0
    n_visible: int = 0
    n_found: int = 0
    n_keypoints: int = 0
    n_false: int = 0
    n_on_found: int = 0
    seconds: float = 0.0
    errors: list[NDArray[np.float64]] = field(default_factory=list)

    def add(self, match: ScanMatch) -> None:
        """Accumulate one scan."""
        self.n_scans += 1
        self.n_visible += match.n_visible
        self.n_found += match.n_found
        self.n_keypoints += match.n_keypoints
        self.n_false += match.n_false
        self.n_on_found += match.n_on_found
        self.errors.append(match.errors)

    @property
    def recall(self) -> float:
        """Found visible corners / visible corners."""
        return self.n_found / self.n_visible if self.n_visible else math.nan

    @property
    def precision(self) -> float:
        """Keypoints near a true corner / keypoints."""
        return 1.0 - self.false_rate if self.n_keypoints else math.nan

    @property
    def false_rate(self) -> float:
        """False keypoints / keypoints."""
        return self.n_false / self.n_keypoints if self.n_keypoints else math.nan

    @property
    def false_per_scan(self) -> float:
        """False keypoints per scan."""
        return self.n_false / self.n_scans if self.n_scans else math.nan

    @property
    def keypoints_per_corner(self) -> float:
        """Keypoints on found corners / found corners (1.0: no duplicates)."""
        return self.n_on_found / self.n_found if self.n_found else math.nan

    def error_quantile(self, q: float) -> float:
        """Quantile ``q`` of the localisation error of found corners, metres."""
        e = np.concatenate(self.errors) if self.errors else np.zeros(0)
        return float(np.quantile(e, q)) if e.size else math.nan

    def row(self) -> dict[str, Any]:
        """The table row: counts, rates, errors in millimetres, ms per scan."""
        return {
            "method": self.method,
            "sigma_m": self.sigma,
            "scans": self.n_scans,
            "visible_corners": self.n_visible,
            "recall": self.recall,
            "precision": self.precision,
            "false_rate": self.false_rate,
            "false_per_scan": self.false_per_scan,
            "median_error_mm": 1e3 * self.error_quantile(0.5),
            "p95_error_mm": 1e3 * self.error_quantile(0.95),
            "keypoints_per_corner": self.keypoints_per_corner,
            "ms_per_scan": 1e3 * self.seconds / self.n_scans if self.n_scans else math.nan,
        }


@dataclass(frozen=True)
class SimCase:
    """One simulated pose: its world, pose and the corners to find (sensor frame)."""

    world: World
    pose: tuple[float, float, float]
    visible: NDArray[np.float64]
    all_corners: NDArray[np.float64]


def make_cases(
    n_worlds: int,
    poses_per_world: int,
    sensor: SensorProfile = UST_10LX,
    seed: int = 0,
    probe: float = 0.25,
    min_beams: float = 4.0,
) -> list[SimCase]:
    """Random worlds and poses with their visible corners (the same for every noise level)."""
    rng = np.random.default_rng(seed)
    cases = []
    for _ in range(n_worlds):
        world = random_world(rng)
        for pose_arr in random_poses(world, poses_per_world, rng):
            pose = (float(pose_arr[0]), float(pose_arr[1]), float(pose_arr[2]))
            mask = world.visible_corner_mask(pose, sensor, probe=probe, min_beams=min_beams)
            corners = world.to_sensor_frame(world.corners, pose)
            cases.append(SimCase(world, pose, corners[mask], corners))
    return cases


def default_methods(
    names: Sequence[str] = ("paper", "robust", "split-and-merge"),
) -> dict[str, Any]:
    """Method factories by name, from the registry :mod:`laser_corners.eval.methods`.

    Raises
    ------
    InvalidParamsError
        An unknown name (the message lists the known ones).
    """
    return method_factories(names)


def run_sweep(
    cases: Sequence[SimCase],
    methods: dict[str, MethodFactory],
    sigmas: Sequence[float] = DEFAULT_SIGMAS,
    sensor: SensorProfile = UST_10LX,
    seed: int = 0,
    match_radius: float = 0.1,
    progress: Callable[[str], None] | None = None,
) -> tuple[list[AccuracyStats], dict[str, dict[float, Any]]]:
    """Scan every case at every noise level, run every method, match to the truth.

    Returns
    -------
    stats : list of AccuracyStats
        One per (noise level, method), in sweep order.
    detectors : dict
        ``detectors[method][sigma]``: the detector object used (its ``params`` record what
        ran).
    """
    stats: list[AccuracyStats] = []
    used: dict[str, dict[float, Any]] = {name: {} for name in methods}
    for level, sigma in enumerate(sigmas):
        rng = np.random.default_rng([seed, level])
        scans = [
            c.world.scan(c.pose, sensor, noise_sigma=sigma, rng=rng, stamp=float(i))
            for i, c in enumerate(cases)
        ]
        for name, factory in methods.items():
            detector = factory(scans[0])
            used[name][sigma] = detector
            detector.detect_many(scans[:1])  # JIT compile / cache load, not timed
            t0 = time.perf_counter()
            results = detector.detect_many(scans)
            acc = AccuracyStats(name, sigma, seconds=time.perf_counter() - t0)
            for case, kps in zip(cases, results, strict=True):
                acc.add(match_scan(kps.xy, case.visible, case.all_corners, match_radius))
            stats.append(acc)
            if progress is not None:
                progress(
                    f"sigma {sigma:g} m, {name}: recall {acc.recall:.3f}, "
                    f"false {acc.false_rate:.3f}, "
                    f"median error {1e3 * acc.error_quantile(0.5):.1f} mm"
                )
    return stats, used


def write_tables(stats: Sequence[AccuracyStats], output: Path) -> dict[str, Path]:
    """Write ``accuracy.csv`` and ``accuracy.md`` into ``output``.

    The figure is drawn by :func:`laser_corners.viz.report.write_accuracy_report`.
    """
    output.mkdir(parents=True, exist_ok=True)
    rows = [s.row() for s in stats]
    paths = {"csv": output / "accuracy.csv", "markdown": output / "accuracy.md"}
    with paths["csv"].open("w", newline="") as fh:
        writer = csv.DictWriter(fh, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    paths["markdown"].write_text(markdown_table(stats))
    return paths


def markdown_table(stats: Sequence[AccuracyStats]) -> str:
    """The results as a Markdown table (one row per noise level and method)."""
    head = (
        "| sigma m | method | scans | visible corners | recall | false keypoints | "
        "false / scan | median err mm | p95 err mm | keypoints / corner | ms / scan |\n"
        "|---:|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n"
    )
    lines = []
    for s in stats:
        r = s.row()
        lines.append(
            f"| {r['sigma_m']:g} | {r['method']} | {r['scans']} | {r['visible_corners']} | "
            f"{r['recall']:.3f} | {100 * r['false_rate']:.1f} % | {r['false_per_scan']:.2f} | "
            f"{r['median_error_mm']:.1f} | {r['p95_error_mm']:.1f} | "
            f"{r['keypoints_per_corner']:.3f} | {r['ms_per_scan']:.2f} |"
        )
    return head + "\n".join(lines) + "\n"
