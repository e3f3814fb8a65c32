"""A SLAM result built from a simulated drive, with the fields of ``laser_corners.slam.SlamResult``.

The output writers, figures and commands read a result by its fields only, so they are tested
here without running SLAM: the poses are the simulator's truth, the odometry drifts, the
keyframe scans are simulated from the true poses through a known mount.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import yaml
from pydantic import BaseModel, ConfigDict

from laser_corners.scan import LaserScan, compose
from laser_corners.sim import UST_10LX, rectangular_room, trajectory

MOUNT = (0.1, 0.0, 0.0)
START = 1000.0
RATE_HZ = 10.0


class FakeOptions(BaseModel):
    """Stands for ``SlamOptions`` (a frozen pydantic model)."""

    model_config = ConfigDict(frozen=True, extra="forbid")
    keyframe_distance: float = 0.3
    min_range: float = 0.1
    max_range: float = 30.0
    point_spacing: float = 0.05

    def to_yaml(self) -> str:
        return yaml.safe_dump({"slam": self.model_dump()}, sort_keys=False)


@dataclass
class FakeLandmarks:
    xy: np.ndarray
    cov: np.ndarray
    n_obs: np.ndarray
    first_stamp: np.ndarray
    last_stamp: np.ndarray


@dataclass
class FakeClosure:
    query: int
    match: int
    relative: np.ndarray
    accepted: bool
    reason: str


@dataclass
class FakeResult:
    stamps: np.ndarray
    poses: np.ndarray
    odometry: np.ndarray
    keyframes: np.ndarray
    keyframe_poses: np.ndarray
    scans: list[LaserScan]
    mount: np.ndarray
    landmarks: FakeLandmarks
    closures: list[FakeClosure]
    ms_per_scan: np.ndarray
    options: FakeOptions = field(default_factory=FakeOptions)
    counts: dict[str, int] = field(default_factory=dict)
    interrupted: bool = False
    partial_reason: str | None = None
    warnings: list[str] = field(default_factory=list)

    def write_g2o(self, path: str | Path) -> None:
        with Path(path).open("w") as handle:
            for i, (x, y, t) in enumerate(self.keyframe_poses):
                handle.write(f"VERTEX_SE2 {i} {x:.6f} {y:.6f} {t:.6f}\n")
            for i in range(1, len(self.keyframe_poses)):
                handle.write(f"EDGE_SE2 {i - 1} {i} 0 0 0 1 0 0 1 0 1\n")


def fake_result(n_scans: int = 120, every: int = 6, interrupted: bool = False) -> FakeResult:
    """A drive of ``n_scans`` scans through a 6 x 4 m room, a keyframe every ``every`` scans."""
    rng = np.random.default_rng(7)
    world = rectangular_room()
    poses = trajectory(world, n_scans, rng, rate_hz=RATE_HZ, speed=0.6)
    stamps = START + np.arange(n_scans) / RATE_HZ
    drift = np.cumsum(np.full(n_scans, math.radians(0.2)))
    odometry = poses.copy()
    odometry[:, 2] += drift
    odometry[:, 0] += 0.01 * np.arange(n_scans)
    keyframes = np.arange(0, n_scans, every)
    scans = [
        world.scan(compose(tuple(poses[k]), MOUNT), UST_10LX, stamp=float(stamps[k]))
        for k in keyframes
    ]
    corners = np.asarray(world.corners, dtype=np.float64)
    landmarks = FakeLandmarks(
        corners,
        np.tile(np.eye(2) * 1e-4, (len(corners), 1, 1)),
        np.full(len(corners), 3),
        np.full(len(corners), stamps[0]),
        np.full(len(corners), stamps[-1]),
    )
    k = len(keyframes)
    closures = [
        FakeClosure(k - 1, 0, np.zeros(3), True, "accepted"),
        FakeClosure(k - 2, 1, np.zeros(3), True, "accepted"),
        FakeClosure(k - 3, 2, np.zeros(3), False, "low overlap 0.43"),
        FakeClosure(k - 4, 3, np.zeros(3), False, "low overlap 0.2"),
    ]
    return FakeResult(
        stamps,
        poses,
        odometry,
        keyframes,
        poses[keyframes],
        scans,
        np.asarray(MOUNT),
        landmarks,
        closures,
        rng.uniform(1.0, 3.0, n_scans),
        counts={"keypoints": 1234},
        interrupted=interrupted,
    )
