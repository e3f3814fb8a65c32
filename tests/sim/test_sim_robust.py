"""The `robust` preset and its kernel options (min_extent_ratio, refine_*) on simulated scans."""

from __future__ import annotations

import numpy as np
import pytest

from laser_corners import CornerDetector, DetectorParams
from laser_corners.errors import InvalidParamsError
from laser_corners.eval.accuracy import default_methods, make_cases, run_sweep
from laser_corners.presets import get_preset, robust_params
from laser_corners.sim import UST_10LX, World, corner_scan


def test_new_options_default_to_the_paper() -> None:
    p = DetectorParams()
    assert (p.min_extent_ratio, p.refine_radius) == (0.0, 0.0)
    assert get_preset("paper") == p
    with pytest.raises(InvalidParamsError, match="min_extent_ratio"):
        DetectorParams(min_extent_ratio=1.5)
    with pytest.raises(InvalidParamsError, match="refine_radius"):
        DetectorParams(refine_radius=-1.0)


def _leg_scene() -> World:
    world = World().add_polygon([[-1.0, -3.0], [3.0, -3.0], [3.0, 3.0], [-1.0, 3.0]])
    world.add_circle((1.0, 0.3), 0.05)  # a leg, 1 m ahead
    return world


def test_min_extent_drops_keypoints_on_legs() -> None:
    world = _leg_scene()
    scan = world.scan((0.0, 0.0, 0.0), UST_10LX)
    leg = np.array([1.0, 0.3])

    def on_leg(params: DetectorParams) -> int:
        kps = CornerDetector(params).detect(scan)
        return int(np.count_nonzero(np.hypot(*(kps.xy - leg).T) < 0.15))

    assert on_leg(DetectorParams()) >= 1  # the paper's test: a leg looks corner-like
    assert on_leg(DetectorParams(min_extent_ratio=0.6, scales=robust_params(0).scales)) == 0


def test_refinement_is_exact_without_noise_and_helps_with_noise() -> None:
    base = DetectorParams()
    refined = base.with_overrides({"refine_radius": 0.5})
    kps = CornerDetector(refined).detect(corner_scan((2.0, 1.0)))
    assert len(kps) == 1 and np.hypot(*(kps.xy[0] - [2.0, 1.0])) < 1e-9
    rng = np.random.default_rng(8)
    scans = [corner_scan((2.0, 1.0), noise_sigma=0.01, rng=rng) for _ in range(60)]
    errors = {}
    for name, params in (("paper", base), ("refined", refined)):
        found = CornerDetector(params).detect_many(scans)
        errors[name] = np.median([np.hypot(*(k.xy - [2.0, 1.0]).T).min() for k in found])
    assert errors["refined"] < 0.7 * errors["paper"]


def test_detect_and_detect_many_agree_with_the_options() -> None:
    rng = np.random.default_rng(2)
    world = _leg_scene()
    scans = [world.scan((0.1 * i, -0.2, 0.1 * i), UST_10LX, 0.01, rng) for i in range(4)]
    detector = CornerDetector(robust_params(0.01))
    for kps, scan in zip(detector.detect_many(scans), scans, strict=True):
        one = detector.detect(scan)
        assert np.allclose(kps.xy, one.xy, atol=1e-12)
        assert np.array_equal(kps.beam_index, one.beam_index)


def test_robust_beats_paper_on_noisy_worlds() -> None:
    cases = make_cases(12, 4, UST_10LX, seed=5)
    stats, _ = run_sweep(cases, default_methods(["paper", "robust"]), sigmas=(0.01, 0.03))
    by = {(s.method, s.sigma): s for s in stats}
    for sigma in (0.01, 0.03):
        assert by["robust", sigma].false_rate < 0.5 * by["paper", sigma].false_rate
    # the targets (measured at full size in docs/simulation-and-accuracy.md), with
    # some slack for this small sample
    assert by["robust", 0.01].recall >= 0.95
    assert by["robust", 0.01].false_rate <= 0.03
    assert by["robust", 0.01].error_quantile(0.5) <= 0.006
    assert by["robust", 0.03].recall >= 0.85
    assert by["robust", 0.03].false_rate <= 0.08
