"""PC-RRT (Algorithm 1): solves the easy scene, is reproducible under a seed, its path replays
through the physics, and it stops honestly (timeout = failure, cancel within 0.2 s)."""

from itertools import pairwise

import numpy as np
import pytest

from rearrangement_planner.model.resources import scenes_dir
from rearrangement_planner.physics.step import Invalid, Physics
from rearrangement_planner.physics.validation import load_scene
from rearrangement_planner.planning import DARRT, PCRRT, Outcome, PCRRTOptions, StopReason
from rearrangement_planner.planning.machinery.propagation import replay
from rearrangement_planner.planning.machinery.termination import NEVER
from rearrangement_planner.planning.requests.warmup import warm_up


@pytest.fixture(scope="module")
def easy(panda):
    return load_scene(scenes_dir() / "easy_push.yaml", robot=panda)


@pytest.fixture(scope="module")
def easy_plan(easy):
    return PCRRT(easy, PCRRTOptions(time_limit=60.0)).plan(seed=0)


def test_easy_scene_is_solved_and_ends_in_the_goal(easy, easy_plan):
    assert easy_plan.solved, easy_plan.message
    final = easy_plan.states[-1].objects[easy.goal_index, :2]
    assert easy.goal.reached(final)
    assert easy_plan.iterations > 0 and easy_plan.tree_size > 1


def test_same_seed_same_plan(easy, easy_plan):
    again = PCRRT(easy, PCRRTOptions(time_limit=60.0)).plan(seed=0)
    assert again.solved and len(again.states) == len(easy_plan.states)
    assert np.array_equal(again.arm_path, easy_plan.arm_path)
    assert all(np.array_equal(a.objects, b.objects)
               for a, b in zip(again.states, easy_plan.states, strict=True))


def test_every_edge_replays_to_the_same_states(easy, easy_plan):
    """The stored arm path alone reproduces every state through the physics (every tree edge
    on the path is valid when replayed)."""
    states, problem = replay(Physics(easy), easy_plan.states[0], easy_plan.arm_path)
    assert problem == ""
    assert len(states) == len(easy_plan.states)
    for planned, replayed in zip(easy_plan.states, states, strict=True):
        np.testing.assert_allclose(replayed.objects, planned.objects, atol=1e-12)


def test_path_starts_at_the_scene_start_and_reaches_the_plane(easy, easy_plan):
    np.testing.assert_array_equal(easy_plan.states[0].q, easy.start_configuration)
    np.testing.assert_array_equal(easy_plan.states[0].objects, easy.object_poses)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_no_plan_time_past_the_budget(seed):
    """The termination condition is asked between batches of propagation steps, and the
    compiled core is loaded before the clock starts (by the caller), so neither a failure nor
    a success ends much later than the time limit (a benchmark counts plans found within the
    budget; the benchmark's p99 overrun is the measurement, this margin is for a loaded CI
    machine)."""
    warm_up()               # as every entry point does (plan_scene, the node, a tree worker)
    scene = load_scene("clutter")
    result = PCRRT(scene, PCRRTOptions(time_limit=1.0)).plan(seed=seed)
    assert result.plan_time <= 1.25, (result.outcome, result.plan_time)


def test_a_tree_that_outgrows_its_arrays_in_compiled_code_plans_the_same(easy, easy_plan,
                                                                          monkeypatch):
    """The compiled iterations add nodes to the tree's arrays themselves and hand back to
    Python when they are full; from arrays of two nodes (grown some ten times) the plan is
    the one of the default arrays."""
    from functools import partial

    from rearrangement_planner.planning.planners import pcrrt

    monkeypatch.setattr(pcrrt, "Tree", partial(pcrrt.Tree, capacity=2))
    again = PCRRT(easy, PCRRTOptions(time_limit=60.0)).plan(seed=0)
    assert again.tree_size == easy_plan.tree_size > 8
    assert np.array_equal(again.arm_path, easy_plan.arm_path)


def test_the_deadline_cuts_a_long_action_short(panda):
    """The compiled iteration reads the clock between batches of steps, not only between
    iterations: three actions of 60,000 steps that hold the arm still (valid all along, about
    two seconds of physics) end within the 0.2 s budget's margin."""
    warm_up()
    scene = load_scene("seven_objects", robot=panda)
    options = PCRRTOptions(time_limit=0.2, dt=0.001, min_duration=60.0, max_duration=60.0,
                           max_speed=0.001, max_yaw_rate=0.0, nullspace_speed=0.0,
                           push_bias=0.0, goal_bias=0.0)
    result = PCRRT(scene, options).plan(seed=1)
    assert result.outcome is Outcome.TIMEOUT
    assert result.plan_time < 0.7, result.plan_time


def test_timeout_is_a_failure_without_a_path(panda):
    scene = load_scene("seven_objects", robot=panda)
    result = PCRRT(scene, PCRRTOptions(time_limit=0.3)).plan(seed=1)
    assert result.outcome is Outcome.TIMEOUT and not result.solved
    assert result.states == ()
    assert result.plan_time < 2.0


def test_cancel_stops_within_0_2_s(panda, cancel_after):
    # seed 5: no plan within 20,000 iterations (5 s at the fastest), so it is still running
    clutter = load_scene(scenes_dir() / "clutter.yaml", robot=panda)
    planner = PCRRT(clutter, PCRRTOptions(time_limit=60.0, goal_bias=0.0))
    result, running, latency = cancel_after(
        lambda cancel: planner.plan(seed=5, stop=planner.options.termination(cancel)), 1.0)
    assert running
    assert result.outcome is Outcome.CANCELLED
    assert latency < 0.2


def test_progress_is_reported(easy):
    # A period of 0 reports before every iteration: the count does not depend on the machine's
    # speed (seed 0 takes 350 iterations and reports 18 times; a 0.1 s period gave 2 reports
    # on a loaded machine).
    reports = []
    PCRRT(easy, PCRRTOptions(time_limit=30.0, progress_period=0.0)).plan(
        seed=0, progress=reports.append)
    assert len(reports) >= 10
    assert all(b.elapsed > a.elapsed for a, b in pairwise(reports))
    assert reports[-1].tree_size >= 1 and reports[-1].best_goal_distance > 0


def test_start_in_collision_is_start_invalid(easy):
    start = easy.initial_state()
    bad = start.with_q(np.array([0.0, 1.7, 0.0, -0.5, 0.0, 0.5, 0.0]))  # arm in the table
    result = PCRRT(easy, PCRRTOptions(time_limit=5.0)).plan(bad, seed=0)
    assert result.outcome is Outcome.START_INVALID and "table" in result.message


def test_options_reject_nonsense():
    with pytest.raises(ValueError, match="sampler"):
        PCRRTOptions(sampler="magic")
    with pytest.raises(ValueError, match="goal_bias"):
        PCRRTOptions(goal_bias=1.5)


def test_timed_trajectory_replays_to_the_planned_final_poses(easy, easy_plan):
    """The controller-ready trajectory's joint motion, stepped through the physics from the
    start state, reproduces the planned final object poses."""
    from rearrangement_planner.planning.requests.trajectory import TimingOptions, time_parameterize

    trajectory = time_parameterize(easy.robot, easy_plan.arm_path, TimingOptions())
    assert np.all(np.diff(trajectory.times) > 0)
    assert np.all(trajectory.velocities[-1] == 0)
    assert np.all(np.abs(trajectory.velocities) <= easy.robot.velocity_limits + 1e-9)
    states, problem = replay(Physics(easy), easy_plan.states[0], trajectory.positions)
    assert problem == ""
    np.testing.assert_allclose(states[-1].objects, easy_plan.states[-1].objects, atol=1e-6)


def test_push_policy_moves_the_object_towards_its_target(easy):
    """The push-bias action lines the tool up behind the object and pushes it along the line
    to the target; every step is a valid physics step (replays exactly)."""
    from rearrangement_planner.model.state import State
    from rearrangement_planner.planning.machinery.manifold import ik_on_manifold
    from rearrangement_planner.planning.machinery.push_policy import push_policy_prop

    physics = Physics(easy)
    g = easy.goal_index
    centre, goal = easy.object_poses[g, :2], np.asarray(easy.goal.position)
    u = (goal - centre) / np.linalg.norm(goal - centre)
    tool = centre - u * 0.12 + np.array([-u[1], u[0]]) * 0.03   # behind, a little off the line
    q = ik_on_manifold(easy.robot, tool[0], tool[1], float(np.arctan2(u[1], u[0])), 0.0,
                       easy.robot.home, rng=np.random.default_rng(0))
    start = State(q, easy.object_poses)
    assert physics.check_state(start) is None and not physics.world.arm_object_contacts(
        easy.robot.shape_poses(q), start.objects)
    result = push_policy_prop(physics, start, g, goal, 60, 0.1, 0.1, np.zeros(7))
    assert len(result.states) >= 20
    end = result.states[-1].objects[g, :2]
    assert np.linalg.norm(end - goal) < np.linalg.norm(centre - goal) - 0.05
    states, problem = replay(physics, start, [start.q] + [s.q for s in result.states])
    assert problem == ""
    np.testing.assert_array_equal(states[-1].objects, result.states[-1].objects)


def test_a_facing_push_turns_the_hand_across_the_push_line(easy):
    """face_push: the hand starts 0.3 rad off the push heading. A facing push turns it until
    its flat face lies across the push line and carries the box to the target along a line
    contact; a plain push keeps its yaw, meets the box with a corner and turns it faster than
    the turn limit allows, so it stops there."""
    from rearrangement_planner.model.state import State
    from rearrangement_planner.planning.machinery.manifold import ik_on_manifold, tool_planar_pose
    from rearrangement_planner.planning.machinery.push_policy import push_policy_prop

    physics = Physics(easy)
    g = easy.goal_index
    centre, goal = easy.object_poses[g, :2], np.asarray(easy.goal.position)
    u = (goal - centre) / np.linalg.norm(goal - centre)
    heading = float(np.arctan2(u[1], u[0]))
    tool = centre - u * 0.12
    q = ik_on_manifold(easy.robot, tool[0], tool[1], heading + 0.3, 0.0, easy.robot.home,
                       rng=np.random.default_rng(0))
    start = State(q, easy.object_poses)
    ends = {facing: push_policy_prop(physics, start, g, goal, 60, 0.1, 0.1, np.zeros(7),
                                     facing=facing) for facing in (False, True)}
    off = {facing: abs((tool_planar_pose(easy.robot, r.states[-1].q)[2] - heading + np.pi / 2)
                       % np.pi - np.pi / 2) for facing, r in ends.items()}
    assert off[True] < 0.05 and off[False] > 0.25, off
    assert ends[True].stopped is None                      # arrived: within 1 cm of it
    assert np.linalg.norm(ends[True].states[-1].objects[g, :2] - goal) < 0.015
    assert ends[False].stopped is Invalid.TURNING


@pytest.mark.parametrize("push_bias", [0.0, 1.0])
def test_push_bias_is_switchable(easy, push_bias):
    result = PCRRT(easy, PCRRTOptions(time_limit=60.0, push_bias=push_bias)).plan(seed=2)
    assert result.solved


@pytest.mark.parametrize("greedy", [True, False])
def test_greedy_goal_push_runs_only_when_switched_on(easy, monkeypatch, greedy):
    from rearrangement_planner.planning.machinery.push_policy import PushPolicy

    calls = []
    original = PushPolicy.goal_push

    def counting(self, x, rng, stop):
        calls.append(float(np.linalg.norm(x.objects[easy.goal_index, :2] - self.goal_xy)))
        return original(self, x, rng, stop)

    monkeypatch.setattr(PushPolicy, "goal_push", counting)
    result = PCRRT(easy, PCRRTOptions(time_limit=60.0, max_iterations=150,
                                        greedy_goal=greedy)).plan(seed=2)
    if greedy:
        # Each greedy push starts from a new best: strictly decreasing goal distances.
        assert calls and all(b < a for a, b in pairwise(calls)), calls
        assert result.best_goal_distance <= min(calls) + 1e-12   # hypot vs norm rounding
    else:
        assert calls == []


def test_a_state_on_the_goal_boundary_is_refused_by_the_margin(easy):
    """docs/design.md goal margin: with goal_margin the goal object must end well inside its
    region; a state whose centre is on the region's edge ends no plan."""
    goal = np.asarray(easy.goal.position)
    g = easy.goal_index
    objects = easy.object_poses
    objects[g, :2] = goal + np.array([easy.goal.radius - 1e-4, 0.0])     # just inside the edge
    on_edge = easy.initial_state().with_objects(objects)
    plain = PCRRT(easy, PCRRTOptions(goal_margin=0.0)).stop_check(NEVER)
    margin = PCRRT(easy, PCRRTOptions(goal_margin=0.03)).stop_check(NEVER)
    assert plain(on_edge) is StopReason.GOAL and margin(on_edge) is None


def test_a_plan_with_a_margin_ends_well_inside_the_region(easy):
    result = PCRRT(easy, PCRRTOptions(time_limit=60.0, goal_margin=0.03)).plan(seed=1)
    end = result.states[-1].objects[easy.goal_index, :2]
    assert result.solved and easy.goal.distance(end) <= easy.goal.radius - 0.03


def test_a_margin_as_large_as_the_region_is_goal_invalid(easy):
    result = PCRRT(easy, PCRRTOptions(goal_margin=easy.goal.radius)).plan(seed=0)
    assert result.outcome is Outcome.GOAL_INVALID and "goal_margin" in result.message


def _post_scene(panda, support_friction=0.8):
    """easy_push with its goal object replaced by a 4 cm x 4 cm x 20 cm post on a grippy table:
    at the hand's height (6 cm) it tips under any push; with `support_friction` 0.47 under a
    push square to a face (mu h 2.8 cm > 2 cm) but not along its diagonal (2.83 cm)."""
    from rearrangement_planner.physics.validation import parse_scene

    easy = load_scene("easy_push", robot=panda)
    post = {"name": "post", "shape": "box", "size": [0.04, 0.04, 0.2], "mass": 0.3,
            "support_friction": support_friction, "pusher_friction": 0.3,
            "pose": easy.objects[easy.goal_index].pose.tolist()}
    return parse_scene({"table": {"center": list(easy.table.center),
                                  "size": list(easy.table.size), "height": 0.0},
                        "start_configuration": easy.start_configuration.tolist(),
                        "objects": [post], "goal": {"object": "post",
                                                     "position": list(easy.goal.position),
                                                     "radius": easy.goal.radius}}, robot=panda)


# (the hand keeping its yaw: facing pushes do not find the thin post within 300 iterations of
# seeds 1-3)
POST_OPTIONS = PCRRTOptions(time_limit=60.0, max_iterations=300, face_push=False)


def test_the_tipping_setting_keeps_plans_from_toppling_the_goal_object(panda):
    """`tipping` (a planner setting, honoured by plan_scene): with the check on no plan can
    move the post; with it off (objects never tip) the same request is solved."""
    from rearrangement_planner.physics.options import PhysicsOptions
    from rearrangement_planner.planning import PlanRequest, plan_scene

    scene = _post_scene(panda)
    for tipping, solved in ((False, True), (True, False)):
        request = PlanRequest.first_plan(scene, "pc-rrt", POST_OPTIONS, seed=1,
                                         physics=PhysicsOptions(tipping=tipping))
        output = plan_scene(request)
        assert output.solved is solved, (tipping, output.result.message)


def test_a_goal_object_every_push_would_tip_is_refused_at_once(panda):
    """A goal object that tips under the arm's push whichever way it slides is GOAL_INVALID
    before any search (`search.unpushable`), the message naming it and the numbers; one that
    a push along its diagonal slides upright is searched for."""
    from rearrangement_planner.physics.options import PhysicsOptions
    from rearrangement_planner.planning.machinery.search import unpushable

    result = PCRRT(_post_scene(panda), POST_OPTIONS).plan(seed=1)
    assert result.outcome is Outcome.GOAL_INVALID and result.iterations == 0
    assert "'post' would tip over under any push" in result.message, result.message
    assert "0.8 x push height 0.060 m" in result.message and "(0.028 m)" in result.message
    assert unpushable(Physics(_post_scene(panda, 0.47))) is None
    assert unpushable(Physics(_post_scene(panda), PhysicsOptions(tipping=False))) is None
    # DARRT carries its objects rigidly: a post that any push would tip is still its to plan.
    carried = DARRT(_post_scene(panda), PCRRTOptions(time_limit=5.0, max_iterations=1))
    assert carried.plan(seed=1).outcome is not Outcome.GOAL_INVALID


def test_an_unsolved_search_says_what_it_saw(panda):
    """A search that runs out of budget says how near the goal object came and why the model
    cut its propagations short: here, the post never moves: pushes square to a face would tip
    it, and pushes along its diagonal turn it faster than the turn limit."""
    result = PCRRT(_post_scene(panda, 0.47), POST_OPTIONS).plan(seed=1)
    assert result.outcome is Outcome.PLANNING_FAILED
    assert "the goal object never came nearer its goal point than its start" in result.message
    assert "object_would_tip of the goal object" in result.message, result.message
    assert "object_turns of the goal object" in result.message


def test_the_pushing_model_settings_reach_the_planners_physics(easy):
    """A request's `PhysicsOptions` (tipping, max_turn) are the physics its planner plans in,
    the Static RRT's with its static objects on top; a plain `Physics(scene)` is the planner's
    default pushing model (tipping on, the turn limit at 5 rad/m)."""
    from rearrangement_planner.physics.options import PhysicsOptions
    from rearrangement_planner.physics.step import Physics
    from rearrangement_planner.planning.requests.registry import PLANNERS

    assert Physics(easy).options == PhysicsOptions(tipping=True, max_turn=5.0)
    given = Physics(easy, PhysicsOptions(max_turn=2.0, tipping=False))
    assert PCRRT(easy, physics=given).physics.options.max_turn == 2.0
    default = load_scene("default", robot=easy.robot)
    given = Physics(default, PhysicsOptions(max_turn=2.0, tipping=False))
    static = PLANNERS["static-rrt"].make(default, physics=given).physics.options
    assert static.max_turn == 2.0 and not static.tipping
    assert static.static_objects == {"can", "block"}
