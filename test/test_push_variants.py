"""The switchable push-policy and search variants of PC-RRT (all off by default):
`push_yaw_rate` (push with the hand's real footprint, finger first), `avoid_others`,
`detour` and `fail_penalty`. Each test fails without its mechanism."""

import math

import numpy as np
import pytest
import yaml

from rearrangement_planner.model.resources import scenes_dir
from rearrangement_planner.model.state import State
from rearrangement_planner.physics.step import Invalid, Physics
from rearrangement_planner.physics.validation import load_scene, parse_scene
from rearrangement_planner.planning.approach import approach_path
from rearrangement_planner.planning.manifold import tool_planar_pose
from rearrangement_planner.planning.pcrrt import PCRRT, PlannerOptions, _Tree
from rearrangement_planner.planning.propagation import (
    Propagation,
    _around_others,
    push_policy_prop,
    pusher_footprint,
    replay,
)

ALL_ON = {"push_yaw_rate": 1.0, "avoid_others": True, "detour": 1.0, "fail_penalty": 0.05}


@pytest.fixture(scope="module")
def clutter(panda):
    return load_scene(scenes_dir() / "clutter.yaml", robot=panda)


@pytest.fixture(scope="module")
def on_plane(clutter):
    """The clutter scene's start state once the arm is on the pushing plane."""
    physics = Physics(clutter)
    return approach_path(physics, clutter.initial_state(), np.random.default_rng(0))[0][-1]


def test_pusher_footprint_is_the_panda_hand(clutter, on_plane):
    """Finger nub at the tool point, the 24 cm hand bar behind it, the wrist further back; the
    same in the tool frame wherever the hand is on the plane."""
    footprint = pusher_footprint(Physics(clutter), on_plane.q)
    assert footprint.shape == (3, 5)
    by_radius = {round(r, 3): row for *row, r in footprint}
    nub, bar, wrist = by_radius[0.018], by_radius[0.035], by_radius[0.05]
    assert max(nub[0], nub[2]) + 0.018 == pytest.approx(0.0, abs=0.003)   # tip = tool point
    assert abs(bar[1] - bar[3]) == pytest.approx(0.17, abs=1e-3)          # across the heading
    assert bar[0] == pytest.approx(bar[2], abs=1e-6) and -0.08 < bar[0] < -0.05
    assert max(wrist[0], wrist[2]) < -0.1


def test_finger_first_push_takes_the_box_to_its_goal(panda):
    """easy_push from the plane start: holding the yaw, the hand bar catches the box off its
    centre line, turns it and shoves it away from the goal; turning the hand to push finger
    first puts the pusher's leading point behind the box and drives it to the goal."""
    scene = load_scene(scenes_dir() / "easy_push.yaml", robot=panda)
    physics = Physics(scene)
    x = approach_path(physics, scene.initial_state(), np.random.default_rng(0))[0][-1]
    g, goal = scene.goal_index, np.asarray(scene.goal.position)
    start = float(np.hypot(*(x.objects[g, :2] - goal)))
    ends = {}
    for yaw_rate in (0.0, 1.0):
        result = push_policy_prop(physics, x, g, goal, 90, 0.1, 0.1, np.zeros(7),
                                  yaw_rate=yaw_rate)
        assert result.stopped is None                                  # valid all the way
        ends[yaw_rate] = result.states[-1]
    assert float(np.hypot(*(ends[1.0].objects[g, :2] - goal))) < 0.02
    turned = math.remainder(tool_planar_pose(physics.robot, ends[1.0].q)[2]
                            - tool_planar_pose(physics.robot, x.q)[2], 2 * math.pi)
    assert turned < -0.3                           # towards the push heading, -pi/2
    assert float(np.hypot(*(ends[0.0].objects[g, :2] - goal))) > start


def test_around_others_turns_the_approach_along_an_object():
    objects = np.array([[0.0, 0.0, 0.0], [1.0, 1.0, 0.0]])
    others, radii = np.array([0, 1]), np.array([0.05, 0.05])
    tool = np.array([0.08, 0.0])                      # 3 cm from object 0's footprint
    v = np.array([-0.1, 0.02])                        # heading into it
    out = _around_others(v, tool, objects, others, radii)
    assert np.hypot(*out) == pytest.approx(np.hypot(*v))
    assert out[0] >= -1e-12 and out[1] > 0.0          # along its boundary, on v's side
    away = np.array([0.1, 0.0])
    np.testing.assert_array_equal(_around_others(away, tool, objects, others, radii), away)
    far = np.array([0.5, 0.0])
    np.testing.assert_array_equal(_around_others(v, far, objects, others, radii), v)


def test_fail_penalty_steers_nearest_away_from_dead_ends(clutter, on_plane):
    planner = PCRRT(clutter, PlannerOptions(fail_penalty=0.05))
    tree = _Tree(on_plane, planner._arm_feature(on_plane.q))
    moved = on_plane.objects.copy()
    moved[clutter.goal_index, :2] += [0.0, -0.05]            # node 1: nearer the sample
    tree.add(State(on_plane.q, moved), planner._arm_feature(on_plane.q), 0, ())
    sample_objects = moved.copy()
    sample_objects[clutter.goal_index, :2] += [0.0, -0.1]
    sample_arm = planner._arm_feature(on_plane.q)
    assert planner._nearest(tree, sample_arm, sample_objects) == 1
    tree.fails[1] = 10.0                                     # 0.5 > 5 * 0.05 m of goal weight
    assert planner._nearest(tree, sample_arm, sample_objects) == 0
    plain = PCRRT(clutter, PlannerOptions())
    assert plain._nearest(tree, sample_arm, sample_objects) == 1


def test_via_point_goes_round_the_whole_row(clutter, on_plane):
    """The target pushed up against the two blockers (whose 4 cm gap it cannot pass): the via
    point is beside the row, its footprint clear of every object, not in the gap."""
    planner = PCRRT(clutter, PlannerOptions(detour=1.0))
    g = clutter.goal_index
    objects = on_plane.objects.copy()
    objects[g, :2] = [0.5, 0.115]
    x = State(on_plane.q, objects)
    u, perp = np.array([0.0, -1.0]), np.array([1.0, 0.0])
    radius = clutter.objects[g].footprint_radius
    for seed in range(6):
        via = planner._via_point(x, np.asarray(clutter.goal.position), u, perp,
                                 np.random.default_rng(seed))
        assert via is not None and abs(via[0] - 0.5) > 0.12, via
        for i in range(1, len(clutter.objects)):
            gap = np.hypot(*(objects[i, :2] - via)) - clutter.objects[i].footprint_radius
            assert gap >= radius + 0.01 - 1e-9


def test_detour_action_replays_exactly(clutter, on_plane):
    """A detour is one action through the physics: its arm path alone reproduces it."""
    planner = PCRRT(clutter, PlannerOptions(**ALL_ON))
    g = clutter.goal_index
    goal = np.asarray(clutter.goal.position)
    stop = planner._stop_check(lambda: False, math.inf)
    first = planner._push(on_plane, g, goal, 90, np.zeros(7), stop)
    assert first.stopped is Invalid.OBJECT_OVERLAP                       # met the blockers
    result = planner._detour_push(on_plane, first, goal, np.zeros(7),
                                  np.random.default_rng(0), stop)
    assert len(result.states) > len(first.states)
    arm = np.array([on_plane.q, *(s.q for s in result.states)])
    replayed, problem = replay(planner.physics, on_plane, arm)
    assert problem == ""
    np.testing.assert_allclose(replayed[-1].objects, result.states[-1].objects, atol=1e-12)
    assert isinstance(result, Propagation)


def test_variants_are_reproducible(clutter):
    options = PlannerOptions(max_iterations=25, time_limit=120.0, **ALL_ON)
    a = PCRRT(clutter, options).plan(seed=3)
    b = PCRRT(clutter, options).plan(seed=3)
    assert (a.iterations, a.tree_size, a.propagation_steps) == (
        b.iterations, b.tree_size, b.propagation_steps)
    assert a.best_goal_distance == b.best_goal_distance


def test_variant_options_are_checked():
    for bad in ({"detour": 1.5}, {"push_yaw_rate": -1.0}, {"fail_penalty": -0.1}):
        with pytest.raises(ValueError):
            PlannerOptions(**bad)


def test_finger_first_push_with_nothing_of_the_hand_at_object_height_does_not_crash(panda):
    """Objects lower than the hand: `pusher_footprint` is empty, and the finger-first push
    takes the tool point as the pusher instead of failing (it raised ValueError on argmax of
    an empty sequence, which aborted a planning run with push_yaw_rate > 0)."""
    data = yaml.safe_load((scenes_dir() / "easy_push.yaml").read_text())
    data["objects"][0]["size"][2] = 0.01
    scene = parse_scene(data, robot=panda)
    physics = Physics(scene)
    x = approach_path(physics, scene.initial_state(), np.random.default_rng(0))[0][-1]
    assert pusher_footprint(physics, x.q).size == 0
    goal = np.asarray(scene.goal.position)
    result = push_policy_prop(physics, x, 0, goal, 20, 0.1, 0.1, np.zeros(7), yaw_rate=1.0)
    assert len(result.states) == 20 and result.stopped is None
    tool = tool_planar_pose(physics.robot, result.states[-1].q)
    assert float(np.hypot(*(tool[:2] - tool_planar_pose(physics.robot, x.q)[:2]))) > 0.05
