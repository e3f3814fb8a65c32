"""DetectorParams (:mod:`laser_corners.params`): the paper's defaults, validation in one line
naming the field, loading and overrides."""

from __future__ import annotations

import re

import pytest

from laser_corners import DetectorParams, InvalidParamsError
from laser_corners.params import PAPER_SCALES
from laser_corners.presets import get_preset


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


def _roundtrip(tmp_path, params: DetectorParams):
    path = tmp_path / "dump.yaml"
    path.write_text(params.to_yaml())
    return path
