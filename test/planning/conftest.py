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
