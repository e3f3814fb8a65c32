"""The one registry of evaluation methods (``evaluate sim`` and ``evaluate real``)."""

from __future__ import annotations

import numpy as np
import pytest

from laser_corners import CornerDetector
from laser_corners.errors import InvalidParamsError
from laser_corners.eval.baselines import SplitAndMergeDetector
from laser_corners.eval.falko_like import FalkoLikeDetector
from laser_corners.eval.methods import (
    ALIASES,
    canonical_name,
    detect_all,
    method_factories,
    method_names,
)
from laser_corners.eval.real_config import RealEvalConfig
from laser_corners.sim import SICK_LMS_1DEG, UST_10LX, corner_scan


def test_names_and_aliases() -> None:
    assert method_names() == ["paper", "auto", "robust", "split-and-merge", "falko-like"]
    assert ALIASES == {"baseline": "split-and-merge", "falko": "falko-like"}
    assert canonical_name("falko") == "falko-like"
    assert canonical_name("paper") == "paper"


@pytest.mark.parametrize("name", ["foo", "FALKO-style", "falkolib", ""])
def test_unknown_names_are_rejected_listing_the_known_ones(name: str) -> None:
    with pytest.raises(InvalidParamsError, match="unknown method") as err:
        method_factories(["paper", name])
    for known in method_names():
        assert known in str(err.value)
    with pytest.raises(InvalidParamsError, match="unknown method"):
        RealEvalConfig(methods=("paper", name))


def test_config_keeps_canonical_names() -> None:
    cfg = RealEvalConfig(methods=("paper", "baseline", "falko"))
    assert cfg.methods == ("paper", "split-and-merge", "falko-like")


def test_every_method_finds_the_clean_corner() -> None:
    scan = corner_scan()
    factories = method_factories(method_names())
    kinds = {name: type(factory(scan)) for name, factory in factories.items()}
    assert kinds == {
        "paper": CornerDetector,
        "auto": CornerDetector,
        "robust": CornerDetector,
        "split-and-merge": SplitAndMergeDetector,
        "falko-like": FalkoLikeDetector,
    }
    for name, factory in factories.items():
        kps = factory(scan).detect(scan)
        d = np.hypot(kps.xy[:, 0] - 2.0, kps.xy[:, 1] - 1.0)
        assert len(kps) >= 1 and d.min() < 0.05, name


def test_detect_all_mixed_geometries_chunks_and_progress() -> None:
    rng = np.random.default_rng(1)
    scans = [
        corner_scan(sensor=UST_10LX if k % 3 else SICK_LMS_1DEG, noise_sigma=0.005, rng=rng)
        for k in range(7)
    ]
    detector = CornerDetector()
    steps: list[tuple[int, int]] = []
    got = detect_all(detector, scans, lambda done, total: steps.append((done, total)), chunk=3)
    want = [detector.detect(s) for s in scans]
    assert [len(k) for k in got] == [len(k) for k in want]
    for a, b in zip(got, want, strict=True):
        np.testing.assert_allclose(a.xy, b.xy)
    assert steps == [(3, 7), (6, 7), (7, 7)]
