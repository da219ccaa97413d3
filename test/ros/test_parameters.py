"""Each setting written once: the node's parameters come from the option dataclasses, the node
and the CLI plan the same default request, and config/planner.yaml holds exactly the defaults,
in their order."""

import dataclasses

import pytest
import yaml

from rearrangement_planner.model.errors import InputError
from rearrangement_planner.model.resources import config_dir
from rearrangement_planner.model.settings import SettingSpec
from rearrangement_planner.physics.options import PhysicsOptions
from rearrangement_planner.physics.validation import load_scene
from rearrangement_planner.planning import PLANNERS, DARRTOptions, PCRRTOptions, PlannerOptions
from rearrangement_planner.planning.requests.request import STAGES, PlanRequest, request_settings
from rearrangement_planner.ros.parameters import DEFAULTS, PARAMETERS
from rearrangement_planner.ros.plan_request import node_request
from rearrangement_planner.tools.cli import build_parser, plan_request


def test_config_file_lists_every_parameter_at_its_default_in_order():
    data = yaml.safe_load((config_dir() / "planner.yaml").read_text())
    in_file = data["rearrangement_planner"]["ros__parameters"]
    declared = {p.name: list(p.default) if isinstance(p.default, tuple) else p.default
                for p in PARAMETERS}
    assert list(in_file) == list(declared)
    assert in_file == declared


def test_every_planner_setting_is_a_parameter_with_its_range_and_description():
    by_name = {p.name: p for p in PARAMETERS}
    for options in (PlannerOptions, PCRRTOptions, DARRTOptions, PhysicsOptions, *STAGES):
        for setting in options.describe():
            parameter = by_name[setting.name]
            assert parameter.default == setting.default
            assert (parameter.low, parameter.high) == (setting.low, setting.high)
            assert setting.description and parameter.description.startswith(
                setting.description)


def test_a_setting_shared_by_planners_has_one_default():
    for spec in PLANNERS.values():
        for setting in spec.settings():
            shared = next(s for s in request_settings() if s.name == setting.name)
            assert shared.default == setting.default
    names = [s.name for s in request_settings()]
    assert len(names) == len(set(names))


@pytest.mark.parametrize("planner", list(PLANNERS))
def test_the_node_and_the_cli_plan_the_same_default_request(planner):
    """One source of product defaults: the node's parameters at their defaults and the CLI
    without options build the same plan request (the scene aside, which each loads)."""
    scene = load_scene("easy_push")
    node = node_request({**DEFAULTS, "planner": planner}, scene)
    cli = plan_request(build_parser().parse_args(["easy_push", "--planner", planner]), scene)
    assert node == dataclasses.replace(cli, scene=node.scene)
    assert node == PlanRequest(scene, planner)
    assert (node.options.time_limit, node.trees, node.shortcut.shortcut_time,
            node.robust.min_robustness) == (60.0, 2, 10.0, 1.0)


def test_a_setting_the_planner_ignores_is_refused_by_the_node():
    """DARRT never steps the physics: a turn limit other than the default is refused, naming
    the parameter; at its default it is not."""
    scene = load_scene("easy_push")
    with pytest.raises(InputError, match="parameter max_turn: max_turn: darrt does not read"):
        node_request({**DEFAULTS, "planner": "darrt", "max_turn": 2.0}, scene)
    with pytest.raises(InputError, match="parameter k_actions"):
        node_request({**DEFAULTS, "planner": "darrt", "k_actions": 5}, scene)
    assert node_request({**DEFAULTS, "planner": "darrt"}, scene).planner.name == "darrt"
    with pytest.raises(InputError, match="parameter planner"):
        node_request({**DEFAULTS, "planner": "rrt-star"}, scene)


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
    base = PlannerOptions(time_limit=5.0, max_iterations=7)
    for spec in PLANNERS.values():
        options = spec.options(base)
        assert isinstance(options, spec.options_type)
        assert (options.time_limit, options.max_iterations) == (5.0, 7)
    with pytest.raises(ValueError, match="darrt has no setting push_bias"):
        PLANNERS["darrt"].options(push_bias=0.5)
    with pytest.raises(ValueError, match="darrt does not read push_bias"):
        PLANNERS["darrt"].options(PCRRTOptions(push_bias=0.5))
