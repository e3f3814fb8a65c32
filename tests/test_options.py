"""The one options form: every options object validates, names the field and the allowed range
in one line, and takes the same ``key=value`` overrides (laser_corners.options)."""

from __future__ import annotations

import pytest

from laser_corners import CornerDetector, DetectorParams, InvalidParamsError
from laser_corners.choice import ParamsChoice
from laser_corners.eval.baselines import SplitAndMergeParams
from laser_corners.eval.falko_like import FalkoLikeParams
from laser_corners.eval.loops import LoopsConfig
from laser_corners.eval.real_config import RealEvalConfig
from laser_corners.matching import PLACE_RECOGNITION, DescriptorParams, MatchOptions
from laser_corners.options import Options


@pytest.mark.parametrize(
    ("build", "message"),
    [
        (
            lambda: MatchOptions(k_nearest=0),
            "MatchOptions.k_nearest: input should be greater than or equal to 1, got 0",
        ),
        (
            lambda: MatchOptions(min_scan_agreement=1.5),
            "min_scan_agreement: input should be less than or equal to 1",
        ),
        (
            lambda: MatchOptions(verification="icp"),
            "verification: input should be 'ransac' or 'clique'",
        ),
        (
            lambda: LoopsConfig(thresholds=(0, 2)),
            "LoopsConfig.thresholds: input should be greater than or equal to 1",
        ),
        (
            lambda: RealEvalConfig(resolution=-1.0),
            "RealEvalConfig.resolution: input should be greater than 0",
        ),
        (lambda: DescriptorParams("bsc", radius=-1.0), "DescriptorParams.radius"),
        (lambda: FalkoLikeParams(sectors=2), "FalkoLikeParams.sectors"),
        (lambda: SplitAndMergeParams(min_points=1), "SplitAndMergeParams.min_points"),
        (lambda: MatchOptions(bogus=1), "MatchOptions.bogus: extra inputs are not permitted"),
    ],
)
def test_errors_name_the_field_and_the_range_in_one_line(build, message: str) -> None:
    with pytest.raises(InvalidParamsError) as info:
        build()
    assert message.lower() in str(info.value).lower()
    assert "\n" not in str(info.value)


def test_one_override_path_for_every_options_object() -> None:
    for cls in (DetectorParams, MatchOptions, LoopsConfig, RealEvalConfig, DescriptorParams):
        assert issubclass(cls, Options)
    opt = PLACE_RECOGNITION.with_overrides(["max_distance=0.5", "verify_scan=false"])
    assert opt.max_distance == 0.5 and not opt.verify_scan and opt.k_nearest == 2
    assert PLACE_RECOGNITION.max_distance == 0.4  # frozen: a copy was made
    cfg = LoopsConfig().with_overrides(["methods=paper,falko", "match.k_nearest=4"])
    assert cfg.methods == ("paper", "falko") and cfg.match.k_nearest == 4
    assert cfg.match.verify_scan  # the other match options stay
    assert RealEvalConfig().with_overrides(["radii=0.05,0.2"]).radii == (0.05, 0.2)
    with pytest.raises(InvalidParamsError, match="unknown match option 'k_nearst'"):
        MatchOptions().with_overrides(["k_nearst=2"])
    with pytest.raises(InvalidParamsError, match=r"MatchOptions\.k_nearest"):
        LoopsConfig().with_overrides(["match.k_nearest=0"])
    with pytest.raises(InvalidParamsError, match="frozen: cannot set 'tolerance'"):
        MatchOptions().tolerance = 0.2  # type: ignore[misc]
    assert MatchOptions.from_mapping({"tolerance": 0.2}) == MatchOptions(tolerance=0.2)


def test_params_choice_is_the_one_preset_plus_overrides() -> None:
    choice = ParamsChoice("paper", overrides={"min_points": 6, "scales": (0.1, 0.2, 0.3)})
    assert choice.overrides == ("min_points=6", "scales=[0.1, 0.2, 0.3]")
    params = choice.resolve(None)
    assert params.min_points == 6 and params.scales == (0.1, 0.2, 0.3)
    assert (
        CornerDetector(choice).params
        == params
        == CornerDetector("paper").params.with_overrides(list(choice.overrides))
    )
    auto = ParamsChoice("auto", overrides=("min_points=6",))
    assert auto.needs_scan and auto.start_params().min_points == 6
    with pytest.raises(InvalidParamsError, match="unknown parameter 'bogus'"):
        ParamsChoice(overrides=("bogus=1",))
    # the evaluation config holds a choice; the old preset/overrides keywords still work
    cfg = RealEvalConfig(preset="auto", overrides=("min_points=6",))
    assert cfg.detector == auto and cfg.preset == "auto" and cfg.overrides == ("min_points=6",)
