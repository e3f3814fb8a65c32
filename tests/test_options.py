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
        (lambda: MatchOptions(bogus=1), "unknown match option 'bogus'; known: min_inliers,"),
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


def _slam_options() -> type[Options]:
    from laser_corners.slam.options import SlamOptions

    return SlamOptions


def _localise_options() -> type[Options]:
    from laser_corners.localise import LocaliseOptions

    return LocaliseOptions


def _mapping_config() -> type[Options]:
    from laser_corners.ros.slam_core import MappingConfig

    return MappingConfig


@pytest.mark.parametrize(
    ("options", "what"),
    [
        (lambda: DetectorParams, "parameter"),
        (lambda: MatchOptions, "match option"),
        (_slam_options, "option"),
        (_localise_options, "option"),
        (_mapping_config, "parameter"),
    ],
)
def test_an_unknown_key_reads_the_same_everywhere(options, what: str) -> None:
    # the constructor, a mapping (YAML, ROS parameters) and key=value overrides all say
    # "unknown <what> 'x'; known: <every field>" (the constructor used to say "x: Extra
    # inputs are not permitted", and MappingConfig "unknown ROS 2 parameter x")
    cls = options()
    known = "known: " + ", ".join(cls.model_fields)
    shape = f"unknown {what} 'bgus'; {known}"
    with pytest.raises(InvalidParamsError) as info:
        cls(bgus=1)
    assert str(info.value) == shape
    with pytest.raises(InvalidParamsError) as info:
        cls.from_mapping({"bgus": 1}, "f.yaml")
    assert str(info.value) == f"f.yaml: {shape}"
    with pytest.raises(InvalidParamsError) as info:
        cls().with_overrides(["bgus=1"])
    assert str(info.value) == shape
    with pytest.raises(InvalidParamsError) as info:  # several at once: one line names them all
        cls.from_mapping({"bgus": 1, "zz": 2}, "f.yaml")
    assert str(info.value) == f"f.yaml: unknown {what} 'bgus', 'zz'; {known}"


def test_ros_node_parameters_say_unknown_keys_the_same_way() -> None:
    from laser_corners.ros.node_core import NodeConfig, parameter_names
    from laser_corners.ros.slam_core import MappingConfig

    known = "known: " + ", ".join(parameter_names())
    with pytest.raises(InvalidParamsError) as info:
        NodeConfig.from_mapping({"min_pionts": 4}, source="ROS 2 parameter", prefix="")
    assert str(info.value) == f"ROS 2 parameters: unknown parameter 'min_pionts'; {known}"
    with pytest.raises(InvalidParamsError) as info:
        NodeConfig.from_mapping({"min_pionts": 4})  # ROS 1: private names
    assert str(info.value) == f"ROS parameters: unknown parameter '~min_pionts'; {known}"
    with pytest.raises(InvalidParamsError) as info:
        MappingConfig.from_mapping({"mode": "slam", "mape": "x"})
    known = "known: " + ", ".join(MappingConfig.model_fields)
    assert str(info.value) == f"ROS 2 parameters: unknown parameter 'mape'; {known}"
    # the other checks of the mapping modes name the parameter in the same line form
    with pytest.raises(InvalidParamsError, match=r"^ROS 2 parameters: mount: expected \[x, y"):
        MappingConfig.from_mapping({"mount": [1.0, 2.0]})
    with pytest.raises(InvalidParamsError, match=r"^ROS 2 parameters: map: mode localise needs"):
        MappingConfig.from_mapping({"mode": "localise"})
    assert MappingConfig().map_period == 5.0 and MappingConfig.from_mapping({}).mode == "slam"


def test_a_flat_name_of_a_group_field_or_a_value_for_a_group_names_the_dotted_names() -> None:
    # every options object with groups (issue 31): ``loop_radius`` was SlamOptions' flat name
    # of ``loop.radius``; ``loop=false`` gives a value to the whole group
    cls = _slam_options()
    with pytest.raises(InvalidParamsError) as info:
        cls().with_overrides(["loop_radius=5"])
    assert str(info.value).startswith("unknown option 'loop_radius' (now 'loop.radius'); known:")
    with pytest.raises(InvalidParamsError) as info:
        cls.from_mapping({"icp_iterations": 5, "bgus": 1}, "f.yaml")
    assert "'icp_iterations' (now 'icp.iterations'), 'bgus';" in str(info.value)
    with pytest.raises(InvalidParamsError, match=r"^loop: .*loop.enabled, loop.radius") as info:
        cls().with_overrides(["loop=false"])
    assert str(info.value).endswith("or the table loop:, got False")
    with pytest.raises(InvalidParamsError) as info:
        MatchOptions().with_overrides(["k_nearest_x=1"])
    assert "(now" not in str(info.value)  # no group there: the plain message
