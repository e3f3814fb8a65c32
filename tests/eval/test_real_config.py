"""Settings of the real-data evaluation (:mod:`laser_corners.eval.real_config`): the paper's
defaults, the detector choice (also from the older ``preset=``/``overrides=``), canonical
method names, and bad values named in one line."""

from __future__ import annotations

import pytest

from laser_corners.choice import ParamsChoice
from laser_corners.errors import InvalidParamsError
from laser_corners.eval.real_config import RealEvalConfig


def test_defaults_are_the_papers() -> None:
    config = RealEvalConfig()
    assert (config.resolution, config.association_radius, config.std_threshold) == (
        0.03,
        0.06,
        0.03,
    )
    assert config.detector == ParamsChoice() and config.preset == "paper"
    assert config.overrides == () and config.radii == (0.05, 0.1)


def test_the_older_preset_and_overrides_keywords_make_the_detector_choice() -> None:
    config = RealEvalConfig(preset="auto", overrides=("min_points=6",))
    assert config.detector == ParamsChoice("auto", overrides=("min_points=6",))
    assert config.preset == "auto" and config.overrides == ("min_points=6",)
    assert RealEvalConfig(overrides=("min_points=7",)).preset == "paper"
    with pytest.raises(InvalidParamsError, match="not both"):
        RealEvalConfig(detector=ParamsChoice(), preset="auto")


def test_methods_are_kept_under_their_canonical_names() -> None:
    config = RealEvalConfig(methods=("baseline", "falko", "auto"))
    assert config.methods == ("split-and-merge", "falko-like", "auto")


@pytest.mark.parametrize(
    ("field", "value"),
    [
        ("resolution", 0.0),
        ("association_radius", float("nan")),
        ("min_ratio", 1.5),
        ("radii", ()),
        ("radii", (0.05, -0.1)),
        ("max_range", 0.0),
        ("methods", ()),
        ("max_scans", 0),
    ],
)
def test_bad_values_name_the_field_in_one_line(field: str, value) -> None:
    with pytest.raises(InvalidParamsError, match=field) as info:
        RealEvalConfig(**{field: value})
    assert "\n" not in str(info.value)
