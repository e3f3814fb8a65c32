"""The back end goes on through optimiser errors (laser_corners.slam.backend)."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("gtsam")

import gtsam

from laser_corners.registration.graph import X
from laser_corners.sim import SICK_LMS_1DEG
from laser_corners.slam import Slam, SlamOptions
from laser_corners.slam.backend import Backend, new_isam
from sim_drives import noisy_odometry, straight, two_rooms

INDETERMINATE = (
    "\nIndeterminate linear system detected while working near variable\n"
    "8646911284551352325 (Symbol: x{k}).\n\nThrown when a linear system is ill-posed."
)


class FlakyIsam:
    """A real iSAM2 whose ``update`` raises gtsam's error when ``bad(graph, values)``."""

    def __init__(self, real: object, bad) -> None:
        self.real, self.bad = real, bad

    def update(self, graph=None, values=None):
        if graph is None:
            return self.real.update()
        if self.bad(graph, values):
            raise RuntimeError(INDETERMINATE.format(k=5))
        return self.real.update(graph, values)

    def __getattr__(self, name: str):
        return getattr(self.real, name)


def _holds(graph, a: int, b: int) -> bool:
    """Whether ``graph`` holds the relative-pose factor between keyframes ``a`` and ``b``."""
    keys = {(X(a), X(b))}
    return any(
        isinstance(graph.at(i), gtsam.BetweenFactorPose2) and tuple(graph.at(i).keys()) in keys
        for i in range(graph.size())
    )


def _drive(
    n: int = 160,
    jump_at: int | None = None,
    options: SlamOptions | None = None,
    backend: Backend | None = None,
):
    """SLAM over a straight drive through the two rooms (odometry drifting; with
    ``jump_at``, 1 km added to it from that scan on; ``backend``: the pose graph handed to
    :class:`Slam`): the result, the true poses."""
    truth = np.array(straight((1.5, 1.5), (10.5, 1.5)) + straight((10.5, 1.6), (10.5, 6.5)))[:n]
    rng = np.random.default_rng(1)
    odometry = noisy_odometry(truth, rng)
    if jump_at is not None:
        odometry[jump_at:, 0] += 1000.0
    slam = Slam(options or SlamOptions(), backend=backend)
    world = two_rooms()
    for i, (pose, odo) in enumerate(zip(truth, odometry, strict=True)):
        scan = world.scan(tuple(pose), SICK_LMS_1DEG, noise_sigma=0.01, rng=rng, stamp=i / 10)
        slam.add(scan, odo, i / 10)
    return slam.result(), truth


def test_an_update_that_raises_once_is_rebuilt_and_counted() -> None:
    raised = []

    def once(graph, values) -> bool:
        if not raised and values is not None and values.exists(X(5)):
            raised.append(True)
            return True
        return False

    result, truth = _drive(backend=Backend(make_isam=lambda: FlakyIsam(new_isam(), once)))
    assert raised and result.counts["optimiser_recoveries"] == 1
    assert result.counts["optimiser_anchors"] == 1
    assert result.counts["optimiser_factors_dropped"] == 0
    assert result.warnings == [
        "optimiser: Indeterminate linear system detected while working near variable "
        "8646911284551352325 (Symbol: x5); re-anchored x5 and went on"
    ]
    assert result.poses.shape == (len(truth), 3)
    assert np.max(np.hypot(*(result.poses[:, :2] - truth[:, :2]).T)) < 0.1


def test_a_factor_that_always_raises_is_dropped_and_the_run_goes_on() -> None:
    bad = lambda graph, values: _holds(graph, 4, 5)  # noqa: E731
    backend = Backend(make_isam=lambda: FlakyIsam(new_isam(), bad))
    result, truth = _drive(options=SlamOptions(final_optimisation=False), backend=backend)
    assert result.counts["optimiser_recoveries"] == 1
    assert result.counts["optimiser_factors_dropped"] == 1  # the link 4 -> 5, nothing else
    assert "dropped the 1 factors of that update" in result.warnings[0]
    assert not _holds(result.graph, 4, 5) and _holds(result.graph, 5, 6)
    assert result.keyframe_poses.shape[0] == result.counts["keyframes"] > 5
    assert np.all(np.isfinite(result.poses))
    # the keyframes before the dropped link and after it are each still where they were
    assert np.max(np.hypot(*(result.poses[:40, :2] - truth[:40, :2]).T)) < 0.1


def test_a_failed_batch_optimisation_keeps_the_isam2_estimate() -> None:
    def fail(graph, values, params):
        raise RuntimeError(INDETERMINATE.format(k=3))

    result, truth = _drive(n=100, backend=Backend(solve=fail))
    assert result.counts["final_optimisation_failures"] == 1
    assert result.warnings[0].startswith("batch optimisation: Indeterminate linear system")
    assert result.warnings[0].endswith("the map keeps the iSAM2 estimate")
    assert np.max(np.hypot(*(result.poses[:, :2] - truth[:, :2]).T)) < 0.1


def test_a_1km_odometry_jump_mid_run_is_reanchored() -> None:
    # measured: "Indeterminate linear system ... (Symbol: x12)" from isam.update, the run died
    result, truth = _drive(n=240, jump_at=100)
    assert result.counts["optimiser_recoveries"] >= 1
    assert any("re-anchored" in w for w in result.warnings)
    assert result.poses.shape == (len(truth), 3) and np.all(np.isfinite(result.poses))
    assert np.max(np.hypot(*(result.poses[:95, :2] - truth[:95, :2]).T)) < 0.1
