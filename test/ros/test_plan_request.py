"""The node's request from its inputs (`ros/plan_request.py`), without DDS: a joint state a
hair past a limit is planned from the limit, one farther out is refused by name."""

from __future__ import annotations

import pytest

from rearrangement_planner.physics.validation import load_scene
from rearrangement_planner.ros.parameters import DEFAULTS
from rearrangement_planner.ros.plan_request import Input, Rejected, planning_scene


@pytest.fixture(scope="module")
def easy(panda):
    return load_scene("easy_push", robot=panda)


def _inputs(scene, q):
    return {"joint_states": Input(q, None, 0.0), "object_poses": Input(scene.object_poses, None,
                                                                       0.0), "goal": None}


def test_a_joint_a_hair_past_its_limit_is_planned_from_the_limit(easy):
    """A controller reports the wrist 0.5 mrad past its limit (encoder noise, tracking error):
    the start is the limit, not START_INVALID (LIMIT_TOLERANCE, 1 mrad)."""
    q = easy.start_configuration.copy()
    q[6] = easy.robot.upper[6] + 0.0005
    scene = planning_scene(easy, _inputs(easy, q), dict(DEFAULTS))
    assert scene.start_configuration[6] == easy.robot.upper[6]


def test_a_joint_farther_past_its_limit_is_refused_by_name(easy):
    q = easy.start_configuration.copy()
    q[6] = easy.robot.upper[6] + 0.005
    with pytest.raises(Rejected, match="panda_joint7 = 2.9023 rad .* outside its joint limits"):
        planning_scene(easy, _inputs(easy, q), dict(DEFAULTS))
