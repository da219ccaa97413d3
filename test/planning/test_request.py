"""The plan request (`planning.requests.request`): one value, the product's defaults written once,
and a
setting a planner does not read refused."""

from __future__ import annotations

import time

import pytest

from rearrangement_planner.physics.options import PhysicsOptions
from rearrangement_planner.physics.validation import load_scene
from rearrangement_planner.planning import (
    PLANNERS,
    DARRTOptions,
    PCRRTOptions,
    PlanRequest,
    plan_scene,
)
from rearrangement_planner.planning.machinery.interface import Outcome
from rearrangement_planner.planning.requests.parallel import RaceOptions
from rearrangement_planner.planning.requests.request import request_settings
from rearrangement_planner.planning.requests.robustness import FIRST_PLAN, RobustOptions
from rearrangement_planner.planning.requests.shortcut import NO_SHORTCUT


@pytest.fixture(scope="module")
def scene():
    return load_scene("easy_push")


def test_the_planner_is_resolved_once_and_its_options_adopted(scene):
    request = PlanRequest(scene, "darrt", PCRRTOptions(time_limit=7.0))
    assert request.planner is PLANNERS["darrt"]
    assert isinstance(request.options, DARRTOptions) and request.options.time_limit == 7.0
    assert PlanRequest(scene).planner is PLANNERS["pc-rrt"]
    with pytest.raises(ValueError, match="unknown planner 'rrt-star'; choose one of pc-rrt"):
        PlanRequest(scene, "rrt-star")


def test_the_default_request_is_the_settings_defaults(scene):
    request = PlanRequest(scene)
    defaults = {s.name: s.default for s in request_settings()}
    for name, value in request.settings().items():
        assert value == defaults[name], name
    assert request.trees == 2 and request.robust == RobustOptions()


def test_first_plan_is_the_planner_alone(scene):
    request = PlanRequest.first_plan(scene, "static-rrt", seed=4)
    assert (request.trees, request.shortcut, request.robust, request.seed) == \
        (1, NO_SHORTCUT, FIRST_PLAN, 4)
    assert PlanRequest.first_plan(scene, race=RaceOptions(trees=3)).trees == 3


def test_a_planner_refuses_the_settings_it_does_not_read(scene):
    """DARRT never steps the quasistatic physics, and has no PC-RRT settings: given other
    values than the defaults they are refused, naming them; the defaults pass."""
    with pytest.raises(ValueError, match="darrt does not read max_turn"):
        PlanRequest(scene, "darrt", physics=PhysicsOptions(max_turn=2.0))
    with pytest.raises(ValueError, match="max_turn: darrt does not read it"):
        PlanRequest.from_settings(scene, "darrt", {"max_turn": 2.0})
    with pytest.raises(ValueError, match="push_bias: darrt does not read it"):
        PlanRequest.from_settings(scene, "darrt", {"push_bias": 0.1})
    with pytest.raises(ValueError, match="transit_time_limit: pc-rrt does not read it"):
        PlanRequest.from_settings(scene, "pc-rrt", {"transit_time_limit": 3.0})
    assert PlanRequest.from_settings(scene, "darrt", {"max_turn": 5.0, "tipping": True})
    assert "max_turn" not in PlanRequest(scene, "darrt").settings()


def test_from_settings_sets_every_stage_and_checks_ranges(scene):
    request = PlanRequest.from_settings(
        scene, "pc-rrt", {"time_limit": 9.0, "max_turn": 0.0, "trees": 1, "shortcut_time": 0.0,
                          "velocity_scale": 0.3, "min_robustness": 0.0, "scene": "ignored"},
        seed=5)
    assert request.options.time_limit == 9.0 and request.physics.max_turn == 0.0
    assert request.trees == 1 and request.shortcut.shortcut_time == 0.0
    assert request.timing.velocity_scale == 0.3 and request.robust.min_robustness == 0.0
    assert request.seed == 5
    with pytest.raises(ValueError, match=r"trees must be in \[1, 64\], got 0"):
        PlanRequest.from_settings(scene, "pc-rrt", {"trees": 0})
    with pytest.raises(ValueError, match="seed must be a non-negative integer"):
        PlanRequest(scene, seed=-1)


def test_the_time_limit_bounds_the_request_shortcutting_included(easy_push_request):
    """With 600 s of shortcutting asked for and no attempt bound, a request of a 3 s time limit
    answers within it (the finishing push may take a moment more)."""
    request = easy_push_request(judge_worlds=0, shortcut_time=600.0, shortcut_attempts=0,
                                time_limit=3.0)
    started = time.monotonic()
    output = plan_scene(request)
    assert output.solved and time.monotonic() - started < 3.0 + 2.0


def test_a_cancel_while_shortcutting_is_never_answered_as_a_plan(easy_push_request,
                                                                cancel_after):
    request = easy_push_request(judge_worlds=0, shortcut_time=600.0, shortcut_attempts=0,
                                time_limit=30.0)
    output, running, took = cancel_after(lambda cancel: plan_scene(request, cancel=cancel), 2.0)
    assert running and took < 1.0
    assert output.result.outcome is Outcome.CANCELLED and output.trajectory is None
