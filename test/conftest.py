"""Shared fixtures. Robots and scenes are built once per session (Pinocchio models are cheap to
query but not free to build)."""

import pytest

from rearrangement_planner.robot import RobotModel


@pytest.fixture(scope="session")
def panda() -> RobotModel:
    return RobotModel.load("panda")
