"""The closed loop (docs/design.md "Closed loop"): the retreat out of contact along the executed
path, and execute -> observe -> retreat -> re-plan in MuJoCo, where a world unlike the plan's
makes the first execution miss and the re-plan from what is observed reaches the goal."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from rearrangement_planner.execution.closed_loop import (
    MISSED,
    NOT_SOLVED,
    REACHED,
    execute_closed_loop,
)
from rearrangement_planner.model.state import State
from rearrangement_planner.physics.collision import CollisionWorld
from rearrangement_planner.physics.validation import load_scene
from rearrangement_planner.planning import PCRRTOptions, PlanRequest, plan_scene
from rearrangement_planner.planning.requests import retreat
from rearrangement_planner.planning.requests.retreat import RETREAT_CLEARANCE, retreat_path
from rearrangement_planner.world3d.mujoco_model import ExecutionOptions

BOX = {"name": "box", "shape": "box", "size": [0.06, 0.08, 0.12], "pose": [0.46, 0.0, 0.0],
       "mass": 0.4, "support_friction": 0.4, "pusher_friction": 0.3}


@pytest.fixture(scope="module")
def pushed_box(pushed):
    """The straight push: the fingers end against the box they pushed."""
    return pushed([BOX])


def _gap(scene, q, objects) -> float:
    """The arm's least distance to an object (m), seen through the contacts within 5 cm."""
    world = CollisionWorld(scene)
    contacts = world.arm_object_contacts(scene.robot.shape_poses(q), objects, margin=0.05)
    return min((-c.depth for c in contacts), default=0.05)


def test_the_retreat_backs_out_along_the_path_until_clear(pushed_box):
    scene, trajectory, end = pushed_box
    assert _gap(scene, end.q, end.objects) < 1e-3             # the push ends touching the box
    moves = retreat_path(scene, end, trajectory.positions)
    assert moves is not None and len(moves) >= 2
    np.testing.assert_array_equal(moves[0], end.q)
    assert _gap(scene, moves[-1], end.objects) >= RETREAT_CLEARANCE - 1e-9
    assert all(_gap(scene, q, end.objects) < RETREAT_CLEARANCE for q in moves[:-1])
    # backwards along the path: the tool only moves away from the box (-x)
    tool_x = [scene.robot.tool_pose(q)[0, 3] for q in moves]
    assert np.all(np.diff(tool_x) <= 1e-6) and tool_x[0] - tool_x[-1] < 0.05


def test_an_arm_already_clear_needs_no_retreat(pushed_box):
    scene, trajectory, end = pushed_box
    moved_away = end.objects + [0.2, 0.0, 0.0]
    moves = retreat_path(scene, State(end.q, moved_away), trajectory.positions)
    assert moves is not None and moves.shape == (1, scene.robot.nq)


def test_a_blocked_way_back_pushes_off_the_objects_instead(pushed, pushed_box):
    """A second box put 8 mm behind the wrist after the push: backing out along the path
    would go into it, so the arm moves its contact points away and up until clear."""
    _, trajectory, end = pushed_box
    blocked, _, _ = pushed([BOX, {**BOX, "name": "behind", "pose": [0.3, 0.4, 0.0]}])
    objects = np.vstack([end.objects, [[0.435, 0.0, 0.0]]])
    observed = State(end.q, objects)
    world = CollisionWorld(blocked)
    assert retreat._back_out(world, blocked.robot, observed, trajectory.positions,
                             RETREAT_CLEARANCE) is None
    moves = retreat_path(blocked, observed, trajectory.positions)
    assert moves is not None and len(moves) >= 2
    assert _gap(blocked, moves[-1], objects) >= RETREAT_CLEARANCE - 1e-9
    start = world.arm_object_penetration(blocked.robot.shape_poses(end.q), objects)
    assert all(world.arm_object_penetration(blocked.robot.shape_poses(q), objects)
               <= start + retreat.DEEPER_TOLERANCE for q in moves)


def test_pushing_off_keeps_a_margin_inside_the_joint_limits(pushed, pushed_box, monkeypatch):
    """The blocked way back again: pushing off stays LIMIT_MARGIN inside every joint limit,
    so that the re-plan after it does not start on a limit; with a margin no configuration of
    that move keeps (a radian: the elbow starts 0.87 rad inside its limit) there is none."""
    _, trajectory, end = pushed_box
    blocked, _, _ = pushed([BOX, {**BOX, "name": "behind", "pose": [0.3, 0.4, 0.0]}])
    objects = np.vstack([end.objects, [[0.435, 0.0, 0.0]]])
    world, robot = CollisionWorld(blocked), blocked.robot
    moves = retreat._push_off(world, robot, State(end.q, objects), RETREAT_CLEARANCE)
    assert moves is not None
    assert all(robot.within_limits(q, tol=-retreat.LIMIT_MARGIN) for q in moves[1:])
    monkeypatch.setattr(retreat, "LIMIT_MARGIN", 1.0)
    assert retreat._push_off(world, robot, State(end.q, objects), RETREAT_CLEARANCE) is None


def test_no_retreat_when_nothing_gets_clear(pushed_box):
    """Clear by a metre: neither the way back nor pushing off gets there."""
    scene, trajectory, end = pushed_box
    assert retreat_path(scene, end, trajectory.positions, clearance=1.0) is None


@pytest.fixture(scope="module")
def easy_push(panda):
    """easy_push planned for its own world (the goal object 7 cm nearer the arm in the world
    the plan is executed in: the fingers catch its far edge and it misses)."""
    scene = load_scene("easy_push", robot=panda)
    request = PlanRequest.first_plan(scene, "pc-rrt", PCRRTOptions(time_limit=30), seed=2)
    target = scene.objects[0]
    world = dataclasses.replace(scene, objects=(
        dataclasses.replace(target, pose=np.asarray(target.pose) + [-0.07, 0.0, 0.0]),))
    return request, world, plan_scene(request)


def test_a_miss_is_mended_by_a_replan_from_what_is_observed(easy_push):
    request, world, plan = easy_push
    loop = execute_closed_loop(request, 2, world, first=plan)
    first, second = loop.attempts
    assert first.ended == MISSED and first.execution.goal_distance_m > world.goal.radius
    assert second.ended == REACHED and loop.reached and loop.replans == 1
    assert second.retreat_s > 0.0           # the fingers ended against the box
    assert loop.time_to_goal_s == pytest.approx(sum(
        a.plan.result.plan_time + a.retreat_s + a.plan.trajectory.duration
        for a in loop.attempts))
    record = loop.to_dict()
    assert record["verdict"] == REACHED and [e["ended"] for e in record["executions"]] == [
        MISSED, REACHED]
    # open loop: the same miss, and nothing more
    (only,) = execute_closed_loop(request, 0, world, first=first.plan).attempts
    assert only.ended == MISSED
    assert only.execution.goal_distance_m == first.execution.goal_distance_m


def test_the_watch_stops_a_straying_execution_and_the_loop_goes_on_from_there(easy_push):
    """divergence_bound 3 cm: the box the fingers catch by its far edge strays from its
    predicted path well before the plan's end; the arm holds there, and the loop observes,
    retreats and re-plans from where things are."""
    request, world, plan = easy_push
    options = ExecutionOptions(arm="servo", divergence_bound=0.03)
    loop = execute_closed_loop(request, 2, world, options, first=plan)
    first = loop.attempts[0]
    report = first.execution
    assert report.stopped.startswith("'target' strayed") and first.detail.startswith("stopped")
    assert 0.0 < report.stopped_at_s < first.plan.trajectory.duration
    assert first.trajectory_s == report.stopped_at_s
    assert loop.reached


def test_a_failed_plan_ends_the_loop_with_nothing_executed(easy_push):
    request, world, _ = easy_push
    hopeless = dataclasses.replace(request, options=dataclasses.replace(
        request.options, max_iterations=1))
    (attempt,) = execute_closed_loop(hopeless, 2, world).attempts
    assert attempt.ended == NOT_SOLVED and attempt.execution is None


def test_a_replan_refused_its_start_gets_a_farther_retreat_in_mujoco(easy_push, monkeypatch):
    """The re-plan after the miss is refused its start (scripted: START_INVALID once): the arm
    backs out farther (closed_loop.FARTHER) and the loop plans once more, and reaches."""
    from rearrangement_planner.execution import closed_loop
    from rearrangement_planner.planning.machinery.interface import Outcome, PlanResult

    request, world, plan = easy_push
    refused: list = []

    def plan_once_refused(sub):
        if not refused:
            refused.append(sub)
            return dataclasses.replace(plan, result=PlanResult(
                Outcome.START_INVALID, "no collision-free straight approach", 0),
                trajectory=None, trajectory_states=())
        return plan_scene(sub)

    clearances: list = []
    real = closed_loop._retreat

    def retreat(*args):
        clearances.append(args[-1])
        return real(*args)

    monkeypatch.setattr(closed_loop, "_retreat", retreat)
    loop = execute_closed_loop(request, 1, world, first=plan, plan=plan_once_refused)
    assert clearances == [RETREAT_CLEARANCE, closed_loop.FARTHER]
    assert loop.reached and loop.replans == 1


def test_the_loop_goes_past_its_replans_only_while_it_closes_in():
    from rearrangement_planner.execution.closed_loop import CLOSING_IN, replans_left

    assert replans_left([0.3], 1, 2)                                 # within replans
    assert not replans_left([0.3, 0.29 + 1e-9], 1, 2)                 # not 1 cm nearer
    assert replans_left([0.3, 0.3 - CLOSING_IN], 1, 2)                # nearer: one more
    assert not replans_left([0.3, 0.2, 0.1, 0.05], 1, 2)              # closing used up
    assert not replans_left([0.3, 0.2], 1, 0)                         # closing 0: never past
    assert not replans_left([0.3, None], 1, 2)                        # not executed: not nearer
