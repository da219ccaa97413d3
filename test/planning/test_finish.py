"""The finishing push (planning/requests/finish.py): a plan that stops on the goal margin's edge
is pushed on towards the goal point, in the planner's own physics."""

import numpy as np

from rearrangement_planner.planning import PCRRTOptions, PlanRequest, plan_scene
from rearrangement_planner.planning.machinery.propagation import replay
from rearrangement_planner.planning.machinery.termination import Termination
from rearrangement_planner.planning.requests.finish import (
    FINISH_GAIN,
    NO_FINISH,
    TAIL_STEPS,
    FinishOptions,
    finish,
)

OPTIONS = PCRRTOptions(time_limit=60.0)


def _distance(scene, state) -> float:
    return float(np.hypot(*(state.objects[scene.goal_index, :2] - scene.goal.position)))


def _finished(physics, states, radius=0.01):
    return finish(physics, states, OPTIONS, radius, Termination.within(10.0))


def test_a_plan_on_the_margin_edge_is_pushed_on_towards_the_goal_point(easy, physics, plan):
    """The search stops on the margin's edge; the finished plan keeps the plan's head, ends at
    least FINISH_GAIN nearer the goal point, and its arm path alone replays it exactly."""
    before = _distance(easy, plan.states[-1])
    assert OPTIONS.goal_radius(easy) - 0.01 < before <= OPTIONS.goal_radius(easy)
    finished = _finished(physics, plan.states)
    after = _distance(easy, finished[-1])
    assert after <= before - FINISH_GAIN
    kept = len(plan.states) - 1 - max(TAIL_STEPS)
    assert all(a.equals(b) for a, b in zip(finished[:kept], plan.states[:kept], strict=True))
    replayed, problem = replay(physics, finished[0], np.array([s.q for s in finished]))
    assert problem == ""
    for expected, got in zip(finished, replayed, strict=True):
        np.testing.assert_allclose(got.objects, expected.objects, atol=1e-9)


def test_the_finish_is_reproducible(physics, plan):
    one, two = _finished(physics, plan.states), _finished(physics, plan.states)
    assert len(one) == len(two)
    assert all(a.equals(b) for a, b in zip(one, two, strict=True))


def test_no_finish_at_radius_zero_or_within_the_radius(easy, physics, plan):
    assert _finished(physics, plan.states, radius=0.0) is plan.states
    inside = _distance(easy, plan.states[-1]) + 0.001
    assert _finished(physics, plan.states, radius=inside) is plan.states


def test_a_request_finishes_its_plan_and_a_first_plan_does_not(easy):
    """The default request finishes; `first_plan` is the planner alone. The same search with
    the finish on ends nearer the goal point, from the same path's head."""
    assert PlanRequest(easy).finish == FinishOptions() and FinishOptions().finish_radius > 0
    assert PlanRequest.first_plan(easy).finish == NO_FINISH
    alone = plan_scene(PlanRequest.first_plan(easy, seed=1)).result
    finished = plan_scene(PlanRequest.first_plan(easy, seed=1, finish=FinishOptions())).result
    assert alone.solved and finished.solved
    assert _distance(easy, finished.states[-1]) <= _distance(easy, alone.states[-1]) - FINISH_GAIN
    assert finished.states[1].equals(alone.states[1])
