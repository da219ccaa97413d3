"""The node's closed loop (`ros/replan.py`) without DDS: its inputs, plans and executions
scripted. A re-plan refused its start after the retreat is given a second, farther retreat
and one more plan before the loop gives up."""

from __future__ import annotations

import threading
import time
from types import SimpleNamespace

import numpy as np
import pytest

from rearrangement_planner.physics.validation import load_scene
from rearrangement_planner.planning import PCRRTOptions, PlanRequest, plan_scene
from rearrangement_planner.planning.machinery.interface import Outcome
from rearrangement_planner.ros import replan
from rearrangement_planner.ros.plan_request import Input


@pytest.fixture(scope="module")
def planned(panda):
    scene = load_scene("easy_push", robot=panda)
    output = plan_scene(PlanRequest.first_plan(scene, "pc-rrt", PCRRTOptions(time_limit=30),
                                               seed=1))
    assert output.solved
    return scene, output


def test_a_replan_refused_its_start_gets_a_farther_retreat(planned, monkeypatch):
    scene, output = planned
    goal = np.asarray(scene.goal.position)
    world = {"objects": np.array([[goal[0] - 0.13, goal[1], 0.0]])}
    retreats: list[float] = []
    plans: list[int] = []

    def retreat(job, io, scene, observed, output, clearance=replan.RETREAT_CLEARANCE):
        retreats.append(clearance)
        return "", ""

    def plan(attempt):
        plans.append(attempt)
        if len(plans) == 1:
            return (Outcome.START_INVALID.value, "no collision-free straight approach onto the "
                    "pushing plane found", scene, None, {})
        return Outcome.SUCCEEDED.value, "", scene, output, {}

    def send_and_wait(msg, watched):
        world["objects"] = np.array([[goal[0], goal[1], 0.0]])       # the re-plan reaches
        return Outcome.SUCCEEDED.value, "executed"

    def latest():
        q = output.trajectory.positions[-1]
        soon = time.monotonic() + 60.0            # received after any settle time
        return {"joint_states": Input(q, None, soon),
                "object_poses": Input(world["objects"], None, soon)}

    monkeypatch.setattr(replan, "_retreat", retreat)
    job = SimpleNamespace(cancel=threading.Event(), plan_id="p", attempts=[], phase="",
                          attempt=1, trajectory=None)
    io = replan.LoopIO(latest, lambda: None, send_and_wait, plan, lambda *_: None)
    outcome, message, *_ = replan.close_the_loop(job, io, scene, output, {}, 1,
                                                 time.monotonic())
    assert outcome == Outcome.SUCCEEDED.value, message
    assert plans == [2, 2] and retreats == [replan.RETREAT_CLEARANCE, replan.FARTHER]
    assert message.endswith("goal reached after 1 re-plans")


def test_a_live_view_watches_an_execution_without_stopping_it(planned):
    """Without re-plans the watch only shows the execution (the live view): an object seen far
    off its path, or tilted, stops the arm only when the loop has re-plans to make."""
    scene, output = planned
    far = Input(scene.object_poses + np.array([0.3, 0.0, 0.0]), None, time.monotonic())
    tipped = (time.monotonic() + 1.0, SimpleNamespace(object_id="target", tilt=0.3, bound=0.05))
    shown: list = []
    q = output.trajectory.positions[len(output.trajectory) // 2]

    def watch(attempts, live=True):
        return replan.goal_watch(output, attempts, 0.05, lambda: far, lambda: None,
                                 (lambda *seen: shown.append(seen)) if live else None)

    assert watch(0)(q) is None and len(shown) == 1
    np.testing.assert_array_equal(shown[0][1], far.value)
    assert "strayed" in watch(1)(q)
    assert watch(0, live=False) is None and replan.goal_watch(
        None, 1, 0.05, lambda: far, lambda: None, None) is None
    tilting = replan.goal_watch(output, 1, 0.0, lambda: None, lambda: tipped, None)
    assert "began to tip" in tilting(q)
    shows_only = replan.goal_watch(output, 0, 0.05, lambda: None, lambda: tipped,
                                   lambda *seen: None)
    assert shows_only(q) is None
