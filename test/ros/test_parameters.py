"""Each setting written once (issue 17): the node's parameters come from the option
dataclasses, and config/planner.yaml holds exactly their defaults, in their order."""

import dataclasses

import pytest
import yaml

from rearrangement_planner.model.resources import config_dir
from rearrangement_planner.planning import PLANNERS, DARRTOptions, PCRRTOptions, PlannerOptions
from rearrangement_planner.planning.pipeline import PipelineOptions
from rearrangement_planner.planning.registry import PRODUCT_DEFAULTS, all_settings
from rearrangement_planner.planning.settings import SettingSpec
from rearrangement_planner.ros.parameters import PARAMETERS


def test_config_file_lists_every_parameter_at_its_default_in_order():
    data = yaml.safe_load((config_dir() / "planner.yaml").read_text())
    in_file = data["rearrangement_planner"]["ros__parameters"]
    declared = {p.name: list(p.default) if isinstance(p.default, tuple) else p.default
                for p in PARAMETERS}
    assert list(in_file) == list(declared)
    assert in_file == declared


def test_every_planner_setting_is_a_parameter_with_its_range_and_description():
    by_name = {p.name: p for p in PARAMETERS}
    for options in (PlannerOptions, PCRRTOptions, DARRTOptions, PipelineOptions):
        for setting in options.describe():
            parameter = by_name[setting.name]
            assert parameter.default == PRODUCT_DEFAULTS.get(setting.name, setting.default)
            assert (parameter.low, parameter.high) == (setting.low, setting.high)
            assert setting.description and parameter.description.startswith(
                setting.description)


def test_a_setting_shared_by_planners_has_one_default():
    for spec in PLANNERS.values():
        for setting in spec.options_type.describe():
            shared = next(s for s in all_settings() if s.name == setting.name)
            assert shared.default == PRODUCT_DEFAULTS.get(setting.name, setting.default)


def test_descriptions_come_from_the_field_docstrings():
    spec = {s.name: s for s in PCRRTOptions.describe()}
    assert spec["k_actions"].description.startswith("Actions sampled and propagated")
    assert spec["sampler"].choices == ("tool", "uniform")
    assert [f.name for f in dataclasses.fields(PCRRTOptions)] == list(spec)


@pytest.mark.parametrize(("values", "message"), [
    ({"push_bias": 1.5}, "push_bias must be in [0, 1], got 1.5"),
    ({"k_actions": 0}, "k_actions must be in [1, 100], got 0"),
    ({"sampler": "grid"}, "sampler must be one of tool, uniform, not 'grid'"),
    ({"greedy_goal": "yes"}, "greedy_goal must be a bool, got 'yes'"),
    ({"dt": float("nan")}, "dt must be in [0.001, 1], got nan"),
    ({"min_duration": 3.0}, "min_duration (3 s) must be at most max_duration (2 s)"),
])
def test_out_of_range_options_name_the_setting(values, message):
    with pytest.raises(ValueError) as info:
        PCRRTOptions(**values)
    assert str(info.value) == message


def test_setting_text_is_parsed_to_its_type():
    assert SettingSpec("x", True, "").parse("false") is False
    assert SettingSpec("x", 3, "").parse("7") == 7
    with pytest.raises(ValueError, match="x takes a float"):
        SettingSpec("x", 0.5, "").parse("fast")


def test_base_options_are_adopted_by_every_planner():
    base = PlannerOptions(time_limit=5.0, max_iterations=7, trees=3)
    for spec in PLANNERS.values():
        options = spec.options(base)
        assert isinstance(options, spec.options_type)
        assert (options.time_limit, options.max_iterations, options.trees) == (5.0, 7, 3)
    with pytest.raises(ValueError, match="darrt has no setting push_bias"):
        PLANNERS["darrt"].options(push_bias=0.5)
