"""Path shortcutting (King et al. 2015, §IV): never longer, still valid, still at the goal."""

import numpy as np
import pytest

from rearrangement_planner.physics.validation import load_scene
from rearrangement_planner.planning import PathMetrics, PCRRTOptions, PlanRequest, plan_scene
from rearrangement_planner.planning.machinery.manifold import manifold_error
from rearrangement_planner.planning.machinery.propagation import replay
from rearrangement_planner.planning.machinery.termination import Termination
from rearrangement_planner.planning.requests.shortcut import (
    ShortcutOptions,
    connect,
    path_length,
    shortcut,
)


@pytest.fixture(scope="module")
def short(physics, plan):
    return shortcut(physics, plan.states, Termination.within(60.0, max_iterations=60), seed=0)


def test_shortcut_shortens_and_never_lengthens(plan, short):
    assert short.length_before == pytest.approx(path_length(plan.states))
    assert short.length_after == pytest.approx(path_length(short.states))
    assert short.accepted > 0
    assert short.length_after < short.length_before


def test_shortcut_path_is_valid_and_keeps_the_goal(easy, physics, plan, short):
    """The arm path alone, replayed through the physics from the start, reproduces every
    state of the shortcut path and ends in the goal region."""
    states, problem = replay(physics, short.states[0], np.array([s.q for s in short.states]))
    assert problem == ""
    for expected, got in zip(short.states, states, strict=True):
        np.testing.assert_allclose(got.objects, expected.objects, atol=1e-12)
    assert easy.goal.reached(states[-1].objects[easy.goal_index, :2])
    assert short.states[0].equals(plan.states[0])


def test_shortcut_is_reproducible_with_an_attempt_bound(physics, plan, short):
    again = shortcut(physics, plan.states, Termination.within(60.0, max_iterations=60), seed=0)
    assert np.array_equal(np.array([s.q for s in again.states]),
                          np.array([s.q for s in short.states]))


def test_each_accepted_step_is_monotone(physics, plan):
    """Run attempt by attempt: the length never increases."""
    states, last = plan.states, path_length(plan.states)
    for k in range(8):
        step = shortcut(physics, states, Termination.within(60.0, max_iterations=5), seed=k)
        assert step.length_after <= last + 1e-12
        states, last = step.states, step.length_after


def test_a_path_not_at_the_goal_is_returned_unchanged(physics, plan):
    cut = plan.states[: len(plan.states) // 2]
    result = shortcut(physics, cut, Termination.within(5.0, max_iterations=20), seed=0)
    assert result.accepted == 0 and len(result.states) == len(cut)


def test_connect_lands_exactly_and_stays_on_the_plane(easy, physics, plan):
    robot = easy.robot
    on_plane = [s.q for s in plan.states
                if np.abs(manifold_error(robot, s.q, 0.0)).max() < 1e-3]
    pairs = [(on_plane[k], on_plane[k + 8]) for k in range(0, len(on_plane) - 8, 4)]
    bridges = [(q_b, connect(physics, q_a, q_b)) for q_a, q_b in pairs]
    landed = [(q_b, bridge) for q_b, bridge in bridges if bridge is not None]
    assert len(landed) >= len(pairs) // 2
    for q_b, bridge in landed:
        np.testing.assert_array_equal(bridge[-1], q_b)
        for q in bridge:
            assert np.abs(manifold_error(robot, q, 0.0)).max() < 5e-3


def test_pipeline_reports_lengths_before_and_after(easy):
    out = plan_scene(PlanRequest.first_plan(easy, "pc-rrt", PCRRTOptions(time_limit=60.0),
                                            seed=1, shortcut=ShortcutOptions(60.0, 30)))
    record = out.to_dict()
    assert record["before_shortcut"]["path_length_rad"] >= record["path_length_rad"]
    assert out.metrics == PathMetrics.of(easy, out.result.states)
    assert len(out.trajectory_states) == len(out.trajectory)
    np.testing.assert_array_equal(out.trajectory.positions[-1], out.result.states[-1].q)


def test_shortcutting_keeps_the_goal_margin():
    """A plan made with goal_margin ends within radius - margin, and so does its shortcut (the
    shortcut judges the goal by the planner's radius, not the region's)."""
    scene = load_scene("easy_push")
    output = plan_scene(PlanRequest.first_plan(
        scene, "pc-rrt", PCRRTOptions(time_limit=60.0, goal_margin=0.03), seed=0,
        shortcut=ShortcutOptions(60.0, 40)))
    end = output.result.states[-1].objects[scene.goal_index, :2]
    assert output.solved and output.metrics.path_length_rad \
        <= output.metrics_before_shortcut.path_length_rad
    assert scene.goal.distance(end) <= scene.goal.radius - 0.03
