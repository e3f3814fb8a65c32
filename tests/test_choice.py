"""Which detector parameters (:mod:`laser_corners.choice`): a preset or fixed parameters plus
overrides, checked when the choice is made, resolved against a recording's first scan."""

from __future__ import annotations

import pickle

import pytest
import yaml

from laser_corners import DetectorParams
from laser_corners.choice import ParamsChoice
from laser_corners.errors import InvalidParamsError
from laser_corners.presets import get_preset
from laser_corners.sim import corner_scan


def test_a_preset_with_overrides_resolves_and_describes_itself() -> None:
    choice = ParamsChoice("paper", overrides=("min_points=6", "scales=0.1,0.2,0.3"))
    params = choice.resolve(None)
    assert params.min_points == 6 and params.scales == (0.1, 0.2, 0.3)
    assert params.max_fit_rmse == DetectorParams().max_fit_rmse  # the rest is the paper's
    assert choice.label == "paper + overrides" and not choice.needs_scan
    described = yaml.safe_load(choice.describe())
    assert described == {"preset": "paper", "overrides": ["min_points=6", "scales=0.1,0.2,0.3"]}
    assert pickle.loads(pickle.dumps(choice)) == choice


def test_a_mapping_of_overrides_becomes_key_value_strings() -> None:
    choice = ParamsChoice(overrides={"min_points": 7, "scales": (0.1, 0.2, 0.3)})
    assert choice.overrides[0] == "min_points=7"
    assert choice.resolve(None).scales == (0.1, 0.2, 0.3)


def test_a_scan_dependent_preset_waits_for_the_scan() -> None:
    choice = ParamsChoice("auto", overrides=("min_points=4",))
    assert choice.needs_scan
    assert choice.start_params() == DetectorParams(min_points=4)  # the paper's + overrides
    scan = corner_scan()
    expected = get_preset("auto", scan).with_overrides(["min_points=4"])
    assert choice.resolve(scan) == expected
    with pytest.raises(InvalidParamsError, match="needs a scan"):
        choice.resolve(None)


def test_fixed_parameters_from_a_file(tmp_path) -> None:
    path = tmp_path / "mine.yaml"
    path.write_text(yaml.safe_dump({"min_points": 8}))
    choice = ParamsChoice.from_options(params_file=path, overrides=["max_angle_deg=120"])
    assert choice.label == "mine.yaml + overrides" and choice.source == "mine.yaml"
    params = choice.resolve(corner_scan())
    assert (params.min_points, params.max_angle_deg) == (8, 120)
    assert yaml.safe_load(choice.describe())["params"]["min_points"] == 8
    with pytest.raises(InvalidParamsError, match="not both"):
        ParamsChoice.from_options(preset="paper", params_file=path)


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"preset": "nope"}, "unknown preset 'nope'"),
        ({"overrides": ("bogus=1",)}, "bogus"),
        ({"overrides": ("min_points=1",)}, "min_points"),
        ({"preset": "auto", "overrides": ("min_points=1",)}, "min_points"),
    ],
)
def test_bad_choices_fail_when_made_naming_the_key(kwargs: dict, message: str) -> None:
    with pytest.raises(InvalidParamsError, match=message) as info:
        ParamsChoice(**kwargs)
    assert "\n" not in str(info.value)


def test_of_turns_every_form_into_a_choice() -> None:
    choice = ParamsChoice("auto")
    assert ParamsChoice.of(choice) is choice
    assert ParamsChoice.of(None) == ParamsChoice()
    assert ParamsChoice.of("robust").preset == "robust"
    fixed = DetectorParams(min_points=9)
    assert ParamsChoice.of(fixed).resolve(None) is fixed
    assert ParamsChoice.of(fixed).label == "parameters"
    with pytest.raises(InvalidParamsError, match="got int"):
        ParamsChoice.of(3)  # type: ignore[arg-type]
