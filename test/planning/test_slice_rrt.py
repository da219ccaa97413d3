"""The slice-based RRT (Haustein et al. 2018, Algorithm 1) with the learned and the hand-made
oracle: it solves, is reproducible, its path replays through the physics, its transits leave the
objects where they are, its tree is grouped by object arrangement; the hand-made oracle puts the
hand behind the object, the learned one near the object and pushes within its bounds."""

import math

import numpy as np
import pytest

from rearrangement_planner.model.state import State
from rearrangement_planner.physics.step import Physics
from rearrangement_planner.physics.validation import load_scene
from rearrangement_planner.planning import PLANNERS, Outcome
from rearrangement_planner.planning.machinery.manifold import ik_on_manifold, tool_planar_pose
from rearrangement_planner.planning.machinery.propagation import replay
from rearrangement_planner.planning.machinery.push_policy import support_distance
from rearrangement_planner.planning.machinery.termination import NEVER
from rearrangement_planner.planning.planners.learned_oracle import MIN_DURATION, LearnedOracle
from rearrangement_planner.planning.planners.slice_rrt import HandOracle, SliceRRT, SliceRRTOptions


@pytest.fixture(scope="module")
def default(panda):
    return load_scene("default", robot=panda)


@pytest.fixture(scope="module", params=["learned", "hand"])
def oracle(request):
    return request.param


@pytest.fixture(scope="module")
def default_plan(default, oracle):
    return SliceRRT(default, SliceRRTOptions(time_limit=60.0, oracle=oracle)).plan(seed=0)


def test_the_default_scene_is_solved_and_ends_in_the_goal(default, default_plan):
    assert default_plan.solved, default_plan.message
    assert default.goal.reached(default_plan.states[-1].objects[default.goal_index, :2])
    np.testing.assert_array_equal(default_plan.states[0].q, default.start_configuration)


def test_same_seed_same_plan(default, default_plan, oracle):
    again = SliceRRT(default, SliceRRTOptions(time_limit=60.0, oracle=oracle)).plan(seed=0)
    assert again.iterations == default_plan.iterations
    assert np.array_equal(again.arm_path, default_plan.arm_path)


def test_every_edge_replays_to_the_same_states(default, default_plan):
    states, problem = replay(Physics(default), default_plan.states[0], default_plan.arm_path)
    assert problem == ""
    for planned, replayed in zip(default_plan.states, states, strict=True):
        np.testing.assert_allclose(replayed.objects, planned.objects, atol=1e-12)


def test_the_hand_oracle_puts_the_finger_tips_behind_the_object(default, panda):
    """The manipulation state: the tool `reach + standoff` behind the object's far side from
    the target, facing the push; IK reaches it, and there the hand touches nothing."""
    options = SliceRRTOptions(standoff=0.01)
    oracle = HandOracle(default, panda.tool_reach, panda.nq, options)
    objects = default.object_poses
    t = default.goal_index
    target = objects[t, :2] + np.array([0.0, -0.2])
    pose = oracle.manipulation_state(objects, t, target, np.random.default_rng(0))
    u = np.array([0.0, -1.0])
    back = support_distance(default.objects[t], float(objects[t, 2]), -u) + panda.tool_reach \
        + 0.01
    np.testing.assert_allclose(pose[:2], objects[t, :2] - u * back, atol=1e-12)
    assert pose[2] == pytest.approx(-math.pi / 2)
    assert oracle.manipulation_state(objects, t, objects[t, :2], np.random.default_rng(0)) \
        is None                                      # nothing to push
    push = oracle.push(pose, objects, t, target)
    np.testing.assert_allclose(push.velocity, [0.0, -options.max_speed, 0.0], atol=1e-12)
    assert push.duration == pytest.approx(0.2 / options.max_speed)


def test_a_transit_stops_before_it_would_move_an_object(default, panda):
    """The tool steered straight through the can: the transit ends before the can moves, so
    it stays in its slice."""
    planner = SliceRRT(default, SliceRRTOptions())
    can = default.object_index("can")
    x, y = default.object_poses[can, :2]
    q = ik_on_manifold(panda, x - 0.2, y, 0.0, default.table.height, panda.home,
                       rng=np.random.default_rng(0))
    start = State(q, default.object_poses)
    transit = planner._transit(start, np.array([x + 0.2, y, 0.0]), planner.stop_check(
        NEVER))
    assert transit.states, "the transit should get some way towards the can"
    for state in transit.states:
        np.testing.assert_array_equal(state.objects, start.objects)
    end = tool_planar_pose(panda, transit.states[-1].q)
    assert end[0] < x                                 # it did not pass the can


def test_the_tree_is_grouped_in_slices_of_one_arrangement(default):
    planner = SliceRRT(default, SliceRRTOptions(time_limit=60.0, max_iterations=150))
    captured = {}
    original = planner._iteration

    def spy(run):
        captured["run"] = run
        return original(run)

    planner._iteration = spy
    result = planner.plan(seed=3)
    run = captured["run"]
    # seed 3 finds no plan in 150 iterations (nor does any of seeds 0-11 since the nominal c)
    assert result.outcome is Outcome.PLANNING_FAILED and result.iterations == 150
    assert len(run.members) > 1                      # pushes made new slices
    assert sum(len(m) for m in run.members) == run.tree.n
    for index, nodes in enumerate(run.members):
        for node in nodes:
            np.testing.assert_array_equal(run.tree.objects[node], run.slice_objects[index])


def test_slice_rrt_is_registered_and_reads_the_pushing_model():
    spec = PLANNERS["slice-rrt"]
    assert spec.steps_physics and spec.shortcut and spec.options_type is SliceRRTOptions
    assert {"max_turn", "tipping", "robot_share", "oracle"} <= {s.name for s in spec.settings()}
    assert SliceRRTOptions().oracle == "learned"


def test_the_learned_oracle_proposes_states_beside_the_object_and_bounded_pushes(default, panda):
    """Manipulation states from the shipped generator lie outside the object's footprint and
    within the reach the models were trained on, in the object's frame wherever the object is;
    the policy's push keeps to max_speed per component in the base frame (pushing longer when it
    had to slow down), and does not turn the tool."""
    planner = SliceRRT(default, SliceRRTOptions(oracle="learned"))
    oracle = planner.oracle
    assert isinstance(oracle, LearnedOracle)
    rng = np.random.default_rng(0)
    t = default.goal_index
    obj = default.objects[t]
    models = oracle.models
    for yaw in (0.0, 1.0, -2.5):
        objects = default.object_poses.copy()
        objects[t, 2] = yaw
        target = objects[t, :2] + np.array([0.05, -0.25])
        for _ in range(20):
            pose = oracle.manipulation_state(objects, t, target, rng)
            gap = math.hypot(*(pose[:2] - objects[t, :2])) - obj.footprint_radius
            assert -0.02 <= gap <= models.reach + 0.03, gap
            push = oracle.push(pose, objects, t, target)
            assert np.all(np.abs(push.velocity[:2]) <= models.max_speed + 1e-12)
            assert push.velocity[2] == 0.0
            assert MIN_DURATION <= push.duration <= math.sqrt(2) * models.max_duration
    assert oracle.manipulation_state(default.object_poses, t, default.object_poses[t, :2],
                                     rng) is None      # nothing to push


def test_a_push_is_judged_where_it_ends(panda):
    """A push that passes through the goal region and leaves it is no plan; one that ends
    inside is, and the push's propagation carries no goal test that would cut it short."""
    from rearrangement_planner.planning.machinery.propagation import Propagation
    from rearrangement_planner.planning.planners.slice_rrt import _SliceRun

    scene = load_scene("easy_push", robot=panda)
    planner = SliceRRT(scene, SliceRRTOptions(oracle="hand"))
    run = _SliceRun(planner, 0, None, None)
    assert run.begin(scene.initial_state()) is None
    assert run.push_stop.goal_index == -1 and run.stop.goal_index == scene.goal_index
    root = run.tree.state(0)

    def at(xy):
        objects = root.objects.copy()
        objects[scene.goal_index, :2] = xy
        return State(root.q, objects)

    goal = np.asarray(scene.goal.position)
    through = Propagation.of_states((at(goal), at(goal + [0.3, 0.0])), 0.2, None, frozenset())
    assert run.extend(0, through, goal_at_end=True) is None
    into = Propagation.of_states((at(goal + [0.3, 0.0]), at(goal)), 0.2, None, frozenset())
    result = run.extend(0, into, goal_at_end=True)
    assert result is not None and result.solved


def test_the_learned_oracle_is_refused_for_an_arm_it_has_no_weights_for():
    """The learned oracle ships per arm; a request for another arm names the setting and the
    way out when it is made, before any planning."""
    from rearrangement_planner.planning import PlanRequest
    from rearrangement_planner.planning.planners.slice_rrt import SliceRRTOptions

    scene = load_scene("default_xarm7")
    with pytest.raises(ValueError, match=r"oracle: no learned oracle for robot 'xarm7'.*"
                                         r"shipped for panda\); use oracle=hand"):
        PlanRequest.first_plan(scene, "slice-rrt")
    PlanRequest.first_plan(scene, "slice-rrt", SliceRRTOptions(oracle="hand"))
