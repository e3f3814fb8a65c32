"""Monte Carlo consistency of the keypoint covariance (:mod:`laser_corners.kernel.covariance`).

Each trial simulates one concave corner (two 3 m walls, opening angle uniform in
[60, 150] degrees, random bisector direction facing the sensor) at a range uniform in
[``range_min``, ``range_max``], a random sensor heading and a range noise sigma drawn from
``noises``; the keypoint nearest the true corner (within ``match_radius``) is scored by its
normalised estimation error squared NEES = eᵀ C⁻¹ e (e = keypoint - true corner, C =
``Keypoints.cov``). For a consistent 2-D covariance NEES follows χ²(2): 95 % of the keypoints
lie inside their 95 % ellipse (NEES <= 5.991) and the median NEES is 1.386.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from laser_corners.detector import CornerDetector
from laser_corners.params import DetectorParams
from laser_corners.presets import robust_params
from laser_corners.scan import LaserScan
from laser_corners.sim.raycast import cast_ranges
from laser_corners.sim.sensors import UST_10LX, SensorProfile
from laser_corners.sim.worlds import finish_scan

__all__ = ["CHI2_2_95", "ConsistencyResult", "covariance_consistency"]

CHI2_2_95 = 5.991464547107979
"""95 % quantile of χ²(2)."""


@dataclass(frozen=True)
class ConsistencyResult:
    """Outcome of :func:`covariance_consistency`.

    Attributes
    ----------
    nees : ndarray
        NEES of every matched keypoint.
    noise, rng_m : ndarray
        Noise sigma and corner range of each matched trial.
    n_trials : int
        Trials run (matched or not).
    """

    nees: NDArray[np.float64]
    noise: NDArray[np.float64]
    rng_m: NDArray[np.float64]
    n_trials: int

    @property
    def inside_95(self) -> float:
        """Fraction of keypoints whose true corner is inside the 95 % ellipse."""
        return float(np.mean(self.nees <= CHI2_2_95)) if self.nees.size else math.nan

    @property
    def median_nees(self) -> float:
        """Median NEES (1.386 for a consistent covariance)."""
        return float(np.median(self.nees)) if self.nees.size else math.nan


def _corner_scan(
    rng: np.random.Generator, rho: float, sensor: SensorProfile, noise: float
) -> tuple[LaserScan, NDArray[np.float64]]:
    bearing = rng.uniform(-1.0, 1.0)  # corner direction in the sensor frame, radians
    corner = rho * np.array([math.cos(bearing), math.sin(bearing)])
    opening = math.radians(rng.uniform(60.0, 150.0))
    # bisector points back towards the sensor, tilted by up to 30 degrees
    bis = bearing + math.pi + rng.uniform(-0.5, 0.5)
    walls = []
    for side in (-1.0, 1.0):
        a = bis + side * opening / 2.0
        end = corner + 3.0 * np.array([math.cos(a), math.sin(a)])
        walls.append([corner[0], corner[1], end[0], end[1]])
    ranges = cast_ranges(np.array(walls), (0.0, 0.0, 0.0), sensor.angles)
    return finish_scan(ranges, sensor, noise, rng, None, None), corner


def covariance_consistency(
    n_trials: int = 300,
    noises: Sequence[float] = (0.0, 0.01, 0.02, 0.03),
    range_min: float = 0.5,
    range_max: float = 8.0,
    sensor: SensorProfile = UST_10LX,
    params: Callable[[LaserScan, float], DetectorParams] | None = None,
    match_radius: float = 0.3,
    seed: int = 0,
    continuous: bool = False,
) -> ConsistencyResult:
    """Run the Monte Carlo study (see the module docstring).

    Parameters
    ----------
    n_trials : int
        Simulated corners.
    noises : sequence of float
        Range noise sigmas, metres, drawn uniformly per trial.
    range_min, range_max : float
        Corner range interval, metres.
    sensor : SensorProfile
        Simulated scanner.
    params : callable (scan, noise) -> DetectorParams, optional
        Detector parameters per trial; default: the ``robust`` preset for the trial's noise.
    match_radius : float
        Largest keypoint-to-corner distance for a keypoint to count as the corner's.
    seed : int
        Seed of the generator.
    continuous : bool
        Draw the noise uniformly in [``noises[0]``, ``noises[1]``] instead of from the list.
    """
    rng = np.random.default_rng(seed)
    detectors: dict[DetectorParams, CornerDetector] = {}
    nees, noise_out, range_out = [], [], []
    for _ in range(n_trials):
        noise = (
            float(rng.uniform(noises[0], noises[1]))
            if continuous
            else float(rng.choice(np.asarray(noises, dtype=np.float64)))
        )
        rho = float(rng.uniform(range_min, range_max))
        scan, corner = _corner_scan(rng, rho, sensor, noise)
        p = params(scan, noise) if params is not None else robust_params(noise)
        det = detectors.setdefault(p, CornerDetector(p))
        kps = det.detect(scan)
        if len(kps) == 0:
            continue
        d = np.hypot(*(kps.xy - corner).T)
        i = int(np.argmin(d))
        if d[i] > match_radius:
            continue
        e = kps.xy[i] - corner
        nees.append(float(e @ np.linalg.solve(kps.cov[i], e)))
        noise_out.append(noise)
        range_out.append(rho)
    return ConsistencyResult(np.array(nees), np.array(noise_out), np.array(range_out), n_trials)
