"""Shared fixtures. Robots and scenes are built once per session (Pinocchio models are cheap to
query but not free to build)."""

import pytest

from rearrangement_planner.robot import RobotModel


@pytest.fixture(scope="session")
def panda() -> RobotModel:
    return RobotModel.load("panda")


@pytest.fixture(scope="session")
def default_scene(panda: RobotModel):
    """config/scenes/default.yaml (DESIGN §3 demo scene), sharing the session's Panda model."""
    from rearrangement_planner.scene import load_scene

    return load_scene("default", robot=panda)
