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


def test_the_recordings_are_kept_within_their_limit(tmp_path):
    """Past record_limit_mb the oldest recordings go, never the one just written; other files
    stay."""
    import os

    from rearrangement_planner.ros.plan_request import prune_recordings

    files = []
    for i in range(5):
        file = tmp_path / f"plan{i}.mcap"
        file.write_bytes(b"x" * 1000)
        os.utime(file, (1000 + i, 1000 + i))
        files.append(file)
    (tmp_path / "notes.txt").write_bytes(b"y" * 5000)
    deleted = prune_recordings(tmp_path, 2500, keep=files[0])
    assert deleted == files[1:4]                   # the oldest but the one kept
    assert sorted(p.name for p in tmp_path.iterdir()) == ["notes.txt", "plan0.mcap",
                                                           "plan4.mcap"]
    assert prune_recordings(tmp_path, 0, keep=files[4]) == []          # 0: no limit
