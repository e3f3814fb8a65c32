"""LaserScan and DetectorParams: validation, gaps, conversion, loading."""

from __future__ import annotations

import math
import re

import numpy as np
import pytest

from laser_corners import DetectorParams, InvalidParamsError, LaserScan
from laser_corners.kernel.linefit import X_ON_Y, Y_ON_X, fit_line
from laser_corners.params import PAPER_SCALES
from laser_corners.presets import get_preset


def make(**kw):
    fields = dict(
        ranges=[1.0, 2.0, 3.0], angle_min=0.0, angle_increment=0.1, range_min=0.06, range_max=10.0
    )
    fields.update(kw)
    return LaserScan(**fields)


@pytest.mark.parametrize(
    ("field", "value", "message"),
    [
        ("angle_min", math.nan, "angle_min must be finite"),
        ("angle_increment", math.inf, "angle_increment must be finite"),
        ("angle_increment", 0.0, "angle_increment must be non-zero"),
        ("range_min", 10.0, "range_min .* must be < range_max"),
        ("ranges", np.ones((2, 3)), "ranges must be 1-D"),
        ("ranges", ["a", "b"], "ranges must be numeric"),
        ("range_min", -1.0, "range_min must be a finite number >= 0"),
        ("ranges", np.ones(1081), r"angle_increment \(0.1 rad\) with 1081 beams spans"),
    ],
)
def test_scan_validation_names_the_field(field, value, message) -> None:
    with pytest.raises(ValueError, match=message):
        make(**{field: value})


def test_full_turn_and_clockwise_scans_are_accepted() -> None:
    n = 1440
    full = make(ranges=np.ones(n), angle_min=-math.pi, angle_increment=2 * math.pi / (n - 1))
    assert full.n_beams == n
    clockwise = make(ranges=np.ones(5), angle_increment=-0.1)
    assert clockwise.angles[-1] == pytest.approx(-0.4)
    with pytest.raises(ValueError, match="angle_increment"):
        make(ranges=np.ones(1081), angle_increment=-1.0)


def test_gaps_are_counted_never_errors() -> None:
    scan = make(ranges=[np.nan, np.inf, 0.06, 0.05, 10.0, 11.0, 1.0, -np.inf])
    assert scan.n_gaps == 7
    assert scan.valid.tolist() == [False] * 6 + [True, False]
    xy, valid = scan.to_cartesian()
    assert np.isnan(xy[~valid]).all()
    assert np.allclose(xy[6], [math.cos(0.6), math.sin(0.6)])


def test_cartesian_in_angular_order() -> None:
    scan = make(ranges=[1.0, 1.0, 1.0], angle_min=-0.5, angle_increment=0.5)
    xy, _ = scan.to_cartesian()
    assert np.allclose(
        xy, [[math.cos(-0.5), math.sin(-0.5)], [1, 0], [math.cos(0.5), math.sin(0.5)]]
    )
    assert not scan.ranges.flags.writeable


def test_paper_defaults() -> None:
    p = DetectorParams()
    assert p.scales == PAPER_SCALES == (0.05, 0.075, 0.1, 0.125, 0.15, 0.175, 0.2, 0.225, 0.25)
    assert (p.min_points, p.min_angle_deg, p.max_angle_deg) == (5, 45.0, 135.0)
    assert (p.max_fit_rmse, p.max_point_distance, p.max_centroid_distance) == (0.025, 0.05, 0.025)
    assert p.min_consecutive_scales == 3
    assert get_preset("paper") == p


@pytest.mark.parametrize(
    ("fields", "message"),
    [
        ({"scales": []}, "scales must not be empty"),
        ({"scales": [0.1, 0.05, 0.2]}, "strictly increasing"),
        ({"scales": [-0.1, 0.2]}, "each scale must be in (0, 100] metres"),
        ({"min_points": 1}, "min_points: must be in [2, 10000]"),
        ({"max_fit_rmse": -0.1}, "max_fit_rmse: must be in [0, 100] (metres), got -0.1"),
        ({"max_angle_deg": 200}, "max_angle_deg: must be in [0, 180]"),
        ({"min_consecutive_scales": 20}, "exceeds the number of scales"),
        ({"bogus": 1}, "bogus"),
    ],
)
def test_params_validation_is_one_clear_line(fields, message) -> None:
    with pytest.raises(InvalidParamsError, match=re.escape(message)) as info:
        DetectorParams(**fields)
    assert "\n" not in str(info.value)


def test_params_from_yaml_toml_and_overrides(tmp_path) -> None:
    yml = tmp_path / "p.yaml"
    yml.write_text("detector:\n  min_points: 6\n  scales: [0.1, 0.2, 0.3]\n")
    p = DetectorParams.from_file(yml)
    assert p.min_points == 6 and p.scales == (0.1, 0.2, 0.3)
    toml = tmp_path / "p.toml"
    toml.write_text("max_fit_rmse = 0.01\n")
    assert DetectorParams.from_file(toml).max_fit_rmse == 0.01
    q = p.with_overrides(["max_angle_deg=120", "scales=[0.2, 0.3, 0.4]"])
    assert q.max_angle_deg == 120 and q.scales == (0.2, 0.3, 0.4) and q.min_points == 6
    assert DetectorParams.from_file(_roundtrip(tmp_path, q)) == q
    with pytest.raises(InvalidParamsError, match="unknown parameter 'nope'"):
        p.with_overrides(["nope=1"])
    with pytest.raises(InvalidParamsError, match="key=value"):
        p.with_overrides(["min_points"])
    bad = tmp_path / "bad.yaml"
    bad.write_text("min_points: 1\n")
    with pytest.raises(InvalidParamsError, match=r"bad.yaml: min_points"):
        DetectorParams.from_file(bad)
    with pytest.raises(InvalidParamsError, match="cannot read"):
        DetectorParams.from_file(tmp_path / "missing.yaml")


def _roundtrip(tmp_path, params: DetectorParams):
    path = tmp_path / "dump.yaml"
    path.write_text(params.to_yaml())
    return path


def test_line_fit_models_and_degenerate_cases() -> None:
    horizontal = fit_line([[0, 1], [1, 1.01], [2, 0.99], [3, 1.0]])
    vertical = fit_line([[2, 0], [2.01, 1], [1.99, 2], [2, 3]])
    assert horizontal.model == Y_ON_X and vertical.model == X_ON_Y
    assert horizontal.intersect(vertical) == pytest.approx((2.0, 1.0), abs=0.02)
    exactly_vertical = fit_line([[1, 0], [1, 1], [1, 2]])
    assert exactly_vertical.model == X_ON_Y and exactly_vertical.rmse == 0.0
    parallel = fit_line([[0, 2], [1, 2], [2, 2]])
    assert fit_line([[0, 0], [1, 0], [2, 0]]).intersect(parallel) is None
    single = fit_line([[1, 1], [1, 1]])
    assert single.rmse == math.inf and single.intersect(horizontal) is None


def test_params_ergonomics_one_line_messages() -> None:
    p = DetectorParams()
    with pytest.raises(
        InvalidParamsError, match=r"frozen: cannot set 'min_points'.*with_overrides"
    ):
        p.min_points = 3  # type: ignore[misc]
    assert p.with_overrides(["scales=0.1,0.2,0.3"]).scales == (0.1, 0.2, 0.3)
    assert p.with_overrides(["scales=0.3", "min_consecutive_scales=1"]).scales == (0.3,)
    for bad in ("scales=0.1,a", "scales=[a, b]"):
        with pytest.raises(
            InvalidParamsError, match="expected comma-separated metres like"
        ) as info:
            p.with_overrides([bad])
        assert "\n" not in str(info.value)
    with pytest.raises(InvalidParamsError, match="strictly increasing"):
        p.with_overrides(["scales=0.2,0.1"])
    with pytest.raises(InvalidParamsError, match=re.escape("max_gap_beams: must be in [0, 1000]")):
        DetectorParams(max_gap_beams=-1)


def test_detector_from_preset_and_by_name() -> None:
    from laser_corners import CornerDetector
    from laser_corners.sim import corner_scan

    scan = corner_scan()
    assert CornerDetector("paper").params == DetectorParams()
    assert CornerDetector.from_preset("auto", scan).params == get_preset("auto", scan)
    assert len(CornerDetector.from_preset("robust", scan).detect(scan)) == 1
    for name in ("auto", "robust"):
        with pytest.raises(InvalidParamsError, match=f"preset '{name}' needs a scan.*from_preset"):
            CornerDetector.from_preset(name)
        with pytest.raises(InvalidParamsError, match=f"preset '{name}' needs a scan"):
            CornerDetector(name)
    with pytest.raises(InvalidParamsError, match="unknown preset 'nope'"):
        CornerDetector.from_preset("nope")
    with pytest.raises(InvalidParamsError, match="takes DetectorParams or a preset name"):
        CornerDetector(3)  # type: ignore[arg-type]
