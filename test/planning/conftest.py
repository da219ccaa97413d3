"""Fixtures of the planning tests: easy_push, its physics, and PC-RRT's plan of it (seed 1,
found in well under a second), each built once per test file that asks for it."""

import pytest

from rearrangement_planner.physics.step import Physics
from rearrangement_planner.physics.validation import load_scene
from rearrangement_planner.planning import PCRRT, PCRRTOptions


@pytest.fixture(scope="module")
def easy(panda):
    return load_scene("easy_push", robot=panda)


@pytest.fixture(scope="module")
def physics(easy):
    return Physics(easy)


@pytest.fixture(scope="module")
def plan(easy, physics):
    result = PCRRT(easy, PCRRTOptions(time_limit=60.0), physics).plan(seed=1)
    assert result.solved
    return result


@pytest.fixture
def easy_push_request(panda):
    """`easy_push_request(seed=1, **settings)`: the request of easy_push (one tree, one
    candidate) judged in 4 worlds, `settings` changed."""
    from rearrangement_planner.planning import PlanRequest

    scene = load_scene("easy_push", robot=panda)

    def make(seed: int = 1, **settings) -> PlanRequest:
        values = {"judge_worlds": 4, "trees": 1, "min_robustness": 0.5, "rollouts": 5,
                  "candidates": 1, **settings}
        return PlanRequest.from_settings(scene, "pc-rrt", values, seed=seed)

    return make
