"""The compiled core against its references: the tool's kinematics and Jacobian
against Pinocchio, the step's contacts against python-fcl, the compiled propagation against
the same steps taken one by one from Python, and the robot shapes the step takes."""

from __future__ import annotations

import math
import threading

import numpy as np
import pytest

from rearrangement_planner.model.errors import RobotModelError
from rearrangement_planner.model.robot import RobotConfig, RobotModel
from rearrangement_planner.model.state import State
from rearrangement_planner.physics.options import simulation_options
from rearrangement_planner.physics.step import Invalid, Physics
from rearrangement_planner.physics.validation import load_scene
from rearrangement_planner.planning.machinery.interface import StopReason
from rearrangement_planner.planning.machinery.manifold import (
    default_push_configuration,
    project_step,
)
from rearrangement_planner.planning.machinery.propagation import (
    Action,
    Propagation,
    Stops,
    constrained_prop,
)
from rearrangement_planner.planning.machinery.termination import Termination

SIM = simulation_options()
"""Plain mechanics: objects slide however pushed (no tipping check, no turn limit)."""


def test_tool_pose_and_jacobian_match_pinocchio(panda):
    """`kernels.tool_kinematics` (the Project step's tool pose and 6 x 7 Jacobian at the tool
    origin, base-frame axes) against Pinocchio on 2,000 random configurations."""
    from rearrangement_planner.physics.kernels import compiled_chain, tool_kinematics

    chain = compiled_chain(panda)
    pose, jac = np.empty((4, 4)), np.empty((6, panda.nq))
    rng = np.random.default_rng(11)
    for _ in range(2000):
        q = rng.uniform(panda.lower, panda.upper)
        tool_kinematics(q, *chain.arrays[:4], chain.tool_joint, chain.tool_local, pose, jac)
        np.testing.assert_allclose(pose, panda.tool_pose(q), atol=1e-12)
        np.testing.assert_allclose(jac, panda.frame_jacobian(q, panda.tool_frame_id),
                                   atol=1e-12)


def test_step_contacts_agree_with_fcl(panda):
    """Over random arm configurations beside a box and a cylinder, the compiled step's
    verdict on a resting state (`check_state`: penetration beyond the tolerance) agrees with
    python-fcl's deepest penetration (`CollisionWorld`) except within fcl's own error (GJK
    overestimates capsule-prism distances by up to 2 mm, see test_kernels)."""
    scene = load_scene("easy_push")
    physics = Physics(scene, SIM)
    tolerance = physics.options.penetration_tolerance
    rng = np.random.default_rng(3)
    start = scene.initial_state()
    q0 = np.asarray(start.q)
    agree = compared = 0
    for _ in range(3000):
        q = np.clip(q0 + rng.normal(0.0, 0.25, panda.nq), panda.lower, panda.upper)
        state = State(q, start.objects)
        verdict = physics.check_state(state)
        if verdict is not None and verdict[0] not in (Invalid.RESIDUAL_PENETRATION,):
            continue
        depth = physics.world.arm_object_penetration(panda.shape_poses(q), start.objects)
        if abs(depth - tolerance) < 2e-3:
            continue                      # within fcl's error of the threshold
        compared += 1
        agree += (verdict is None) == (depth <= tolerance)
    assert compared > 1000
    assert agree == compared


def _one_by_one(physics, state, action, dt, stop):
    """Algorithm 2 from Python: `project_step`, then `Physics.step`, then the stop check."""
    states, links, stopped = [], set(), None
    for _ in range(int(round(action.duration / dt))):
        q_new = project_step(physics.robot, state.q, action.velocity, dt,
                             physics.scene.table.height, nullspace_velocity=action.nullspace)
        result = physics.step(state, q_new)
        if not result.valid:
            stopped = result.reason
            break
        state = result.state
        states.append(state)
        links |= result.pushing_links
        stopped = stop(state) if stop is not None else None
        if stopped is not None:
            break
    return states, stopped, frozenset(links)


def test_the_compiled_propagation_takes_the_same_steps_as_python():
    """`constrained_prop` (Project, physics and goal test compiled, in batches of 64 steps)
    gives exactly the states, stop reason and pushing links of the same steps taken one by one,
    whether it runs out (1, 63, 64, 65, 150 steps: batch edges), hits an invalid state or
    reaches the goal."""
    scene = load_scene("easy_push")
    physics = Physics(scene, SIM)
    start = scene.initial_state()
    q = default_push_configuration(physics.robot, scene.table.height)
    start = State(q, start.objects)
    # The box starts 0.2 m from this goal point, beyond it from the hand: pushes reach it.
    stop = Stops(scene.goal_index, (0.52, 0.3), 0.195)
    outcomes = set()
    for steps in (1, 63, 64, 65, 150):
        rng = np.random.default_rng(steps)
        for k in range(12):
            action = Action(np.array([rng.uniform(-0.1, 0.1), rng.uniform(-0.1, 0.1),
                                      rng.uniform(-0.3, 0.3)]), steps * 0.05,
                            rng.uniform(-0.1, 0.1, physics.robot.nq))
            stops = stop if k % 2 else None
            result = constrained_prop(physics, start, action, 0.05, stops)
            states, stopped, links = _one_by_one(physics, start, action, 0.05, stops)
            assert len(result.states) == len(states) == result.count
            if states:      # the end without building the states, and the arrays read-only
                np.testing.assert_array_equal(result.end.q, states[-1].q)
                np.testing.assert_array_equal(result.end.objects, states[-1].objects)
                assert not result.arm.flags.writeable and not result.objects.flags.writeable
                again = Propagation.of_states(states, result.duration, None, frozenset())
                np.testing.assert_array_equal(again.objects, result.objects)
                np.testing.assert_array_equal(result.prefix(1, 0.05).arm, result.arm[:1])
            for got, want in zip(result.states, states, strict=True):
                np.testing.assert_array_equal(got.q, want.q)
                np.testing.assert_array_equal(got.objects, want.objects)
            assert result.stopped == stopped and result.pushing_links == links
            assert result.duration == pytest.approx(len(states) * 0.05)
            outcomes.add(type(stopped).__name__ if stopped is not None else None)
            outcomes.add(stopped)
    assert {None, "Invalid", StopReason.GOAL} <= outcomes, outcomes


def test_a_propagation_from_outside_the_joint_limits_projects_from_inside_them():
    """A propagation's later steps take the tool's kinematics from the physics step's (q is
    Project's own output, inside the limits); its first step from a q past a limit must read
    the tool where Project holds q, at the limit, as Project from Python does."""
    scene = load_scene("easy_push")
    physics = Physics(scene, SIM)
    robot = physics.robot
    q = default_push_configuration(robot, scene.table.height)
    for j, past_limit in ((0, robot.upper[0] + 0.005), (0, robot.lower[0] - 0.005),
                          (2, robot.upper[2] + 0.005), (3, robot.lower[3] - 0.005)):
        past = q.copy()                   # a joint past its limit, the arm clear of the table
        past[j] = past_limit
        start = State(past, scene.initial_state().objects)
        action = Action(np.array([0.05, -0.03, 0.1]), 0.5, np.zeros(robot.nq))
        result = constrained_prop(physics, start, action, 0.05)
        states, stopped, _ = _one_by_one(physics, start, action, 0.05, None)
        assert result.count == len(states) > 1 and result.stopped == stopped
        for got, want in zip(result.states, states, strict=True):
            np.testing.assert_array_equal(got.q, want.q)
            np.testing.assert_array_equal(got.objects, want.objects)


def test_a_step_skips_the_pairs_and_substeps_that_cannot_touch_and_ends_the_same():
    """The physics step asks only the (shape, object) pairs within the step's reach by their exact
    distance (`_clear_far`) and starts at the substep before the nearest of them could touch.
    Over random pushes among the default scene's objects, every step ends exactly as it does
    when every pair and every substep is asked (a free-space margin of 10 m clears nothing):
    the same outcome, object poses and flags; and the boxes alone called many more pairs
    near. A loop's steps share one workspace (`step_workspace`): only the poses at a step's
    end carry over, to a step that starts there (most of these), and each step ends as a step
    with fresh buffers does; and a valid step leaves the joints' poses at its end behind
    (`WORK_JOINTS`), from which the tool's pose and Jacobian are exactly those at q1 (the next
    Project step reads them), whether the step ran one substep or several."""
    from rearrangement_planner.physics.kernels import (
        compiled_chain,
        tool_from_joints,
        tool_kinematics,
    )
    from rearrangement_planner.physics.step import (
        _KNOWN,
        _KNOWN_Q,
        OPT_FREE_SPACE,
        WORK_JOINTS,
        _clear_far,
        _poses,
        _reach,
        single_step,
        step_kernel,
        step_workspace,
    )
    from rearrangement_planner.planning.machinery.propagation import PushTarget, propagate

    scene = load_scene("default")
    physics = Physics(scene)
    every = physics.arrays._replace(options=physics.arrays.options.copy())
    every.options[OPT_FREE_SPACE] = 10.0
    w = physics.arrays
    q = default_push_configuration(physics.robot, scene.table.height)
    start = State(q, scene.initial_state().objects)
    rng = np.random.default_rng(5)
    moved = boxed = exact = steps = carried = substepped = 0
    work = step_workspace(w, q, np.array(start.objects))
    chain = compiled_chain(physics.robot)
    tool = [np.empty((4, 4)), np.empty((6, physics.robot.nq))]
    shared_tool = [np.empty((4, 4)), np.empty((6, physics.robot.nq))]
    for k in range(80):
        nullspace = rng.uniform(-0.3, 0.3, physics.robot.nq)
        if k % 2:       # a random action (Algorithm 2)
            action = Action(np.array([rng.uniform(-0.1, 0.1), rng.uniform(-0.1, 0.1),
                                      rng.uniform(-0.5, 0.5)]), 3.0, nullspace)
            result = constrained_prop(physics, start, action, 0.1)
        else:           # the push policy's closed-loop push: onto an object, then through it
            obj = k // 2 % len(scene.objects)
            target = start.objects[obj, :2] + rng.uniform(-0.2, 0.2, 2)
            result = propagate(physics, start, 60, 0.1, nullspace, None,
                               push=PushTarget(obj, (target[0], target[1]), 0.1, k % 4 == 0))
        q0, objects = np.array(start.q), np.array(start.objects)
        for i in range(result.count):
            q1 = np.array(result.arm[i])
            out = [np.empty_like(objects) for _ in range(2)]
            info = [np.zeros(4 + physics.flag_count, dtype=np.int64) for _ in range(2)]
            codes = [single_step(q0, q1, objects, arrays, out[k], info[k], np.zeros(1))
                     for k, arrays in enumerate((w, every))]
            assert codes[0] == codes[1]
            np.testing.assert_array_equal(out[0], out[1])
            np.testing.assert_array_equal(info[0][4:], info[1][4:])
            carried += work[_KNOWN][0] >= 0 and np.array_equal(work[_KNOWN_Q], q0)
            shared, shared_info = np.empty_like(objects), np.zeros_like(info[0])
            assert step_kernel(q0, q1, objects, w, shared, shared_info, np.zeros(1),
                               work) == codes[0]
            np.testing.assert_array_equal(shared, out[0])
            np.testing.assert_array_equal(shared_info, info[0])
            if codes[0] == 0:
                tool_kinematics(q1, *chain.arrays[:4], chain.tool_joint, chain.tool_local, *tool)
                tool_from_joints(work[WORK_JOINTS], chain.parents, chain.axes, chain.q_index,
                                 chain.tool_joint, chain.tool_local, *shared_tool)
                np.testing.assert_array_equal(shared_tool[0], tool[0])
                np.testing.assert_array_equal(shared_tool[1], tool[1])
                substepped += int(shared_info[3]) > 1
            moved += bool(info[0][4 + len(w.shapes):].any())
            poses = np.empty((len(w.shapes), 4, 4))
            _poses(q0, w.chain, poses, np.empty((len(w.chain[0]), 4, 4)), np.empty((2, 4, 4)))
            near = np.empty((len(w.shapes), len(objects)), dtype=np.bool_)
            near_static = np.empty((len(w.shapes), len(w.static_centre)), dtype=np.bool_)
            _reach(poses, w.shapes, objects, w.obj_size, w.obj_props, w.static_centre,
                   w.static_dims, 0.02, near, near_static)
            boxed += int(near.sum())
            _clear_far(poses, w.shapes, objects, w.obj_kind, w.obj_dims, w.obj_props, 0.02,
                       near)
            exact += int(near.sum())
            q0, objects, steps = q1, np.array(result.objects[i]), steps + 1
    assert steps > 1000 and moved > 30, (steps, moved)
    assert exact < boxed / 2, (exact, boxed)
    assert carried > steps / 2, (carried, steps)
    assert substepped > 100, substepped


def test_a_push_to_the_goal_stops_there_in_the_compiled_propagation():
    """The goal test runs inside the compiled loop: a push of the easy_push box towards its
    goal ends on the first step whose box centre is within the radius."""
    scene = load_scene("easy_push")
    physics = Physics(scene, SIM)
    start = scene.initial_state()
    g, goal = scene.goal_index, np.asarray(scene.goal.position)
    distance = float(np.hypot(*(start.objects[g, :2] - goal)))
    stop = Stops(g, tuple(goal), distance + 1e-9)
    action = Action(np.zeros(3), 0.5, np.zeros(physics.robot.nq))
    result = constrained_prop(physics, start, action, 0.05, stop)
    assert len(result.states) == 1 and result.stopped.value == "goal"


def test_timeout_and_cancel_end_the_compiled_propagation():
    scene = load_scene("easy_push")
    physics = Physics(scene, SIM)
    start = scene.initial_state()
    action = Action(np.array([0.0, 0.0, 0.1]), 10.0, np.zeros(physics.robot.nq))
    late = Stops(scene.goal_index, (9.0, 9.0), 0.0, Termination(-math.inf))
    assert constrained_prop(physics, start, action, 0.05, late).stopped.value == "timeout"
    flag = threading.Event()
    flag.set()
    cancelled = Stops(scene.goal_index, (9.0, 9.0), 0.0, Termination(cancel=flag))
    result = constrained_prop(physics, start, action, 0.05, cancelled)
    assert result.stopped.value == "cancel" and len(result.states) <= 64


def test_a_sphere_shape_is_a_capsule_of_length_zero_and_a_box_shape_is_refused(panda):
    """The step takes capsules and spheres; a robot config with a box contact shape gets an
    error naming the shape, not a wrong answer."""
    from rearrangement_planner.model.robot import ContactShape

    scene = load_scene("easy_push")
    box = ContactShape("panda_hand", "box", (0.04, 0.04, 0.04), np.eye(4))
    config = RobotConfig(**{**panda.config.__dict__,
                            "contact_shapes": (*panda.config.contact_shapes, box)})
    with pytest.raises(RobotModelError, match=r"contact shape 23 on panda_hand is a box"):
        Physics(scene, robot=RobotModel(config))
    # A sphere at the finger tips pushes as a capsule of length 0 there does.
    offset = np.eye(4)
    offset[:3, 3] = [0.0, 0.0, 0.1034]          # at the tool point (0.5, 0), on the pushing plane
    sphere = ContactShape("panda_hand", "sphere", (0.012,), offset)
    capsule = ContactShape("panda_hand", "capsule", (0.012, 0.0), offset)
    results = []
    for shape in (sphere, capsule):
        robot = RobotModel(RobotConfig(**{**panda.config.__dict__, "contact_shapes": (shape,)}))
        physics = Physics(scene, SIM, robot=robot)
        state = State(default_push_configuration(robot, scene.table.height),
                      scene.initial_state().objects)
        action = Action(np.array([0.0, 0.1, 0.0]), 2.0, np.zeros(robot.nq))   # into the box
        results.append(constrained_prop(physics, state, action, 0.05))
    assert len(results[0].states) == len(results[1].states) > 0
    assert results[0].pushing_links == {"panda_hand"}
    np.testing.assert_array_equal(results[0].states[-1].objects, results[1].states[-1].objects)


def test_the_compiled_replay_equals_physics_steps_and_stops_at_the_goal():
    """`replay` (one compiled call over a whole arm path, as robustness rollouts and
    shortcutting use it) gives the states of `Physics.step` taken one by one, the first
    invalid step's reason and detail, and with `until` ends at the first state in the goal
    region."""
    from rearrangement_planner.planning.machinery.propagation import replay
    from rearrangement_planner.planning.machinery.push_policy import push_policy_prop

    scene = load_scene("easy_push")
    physics = Physics(scene, SIM)
    start = State(default_push_configuration(scene.robot, scene.table.height),
                  scene.initial_state().objects)
    g, goal = scene.goal_index, np.asarray(scene.goal.position)
    pushed = push_policy_prop(physics, start, g, goal, 120, 0.05, 0.1, np.zeros(7))
    assert pushed.pushing_links == {"panda_hand"}
    arm = np.array([start.q, *(s.q for s in pushed.states)])
    full, problem = replay(physics, start, arm)
    assert problem == "" and len(full) == len(arm)
    for got, want in zip(full[1:], pushed.states, strict=True):
        np.testing.assert_array_equal(got.objects, want.objects)
    # A path that dives into the table: the same reason and detail as Physics.step's.
    bad = arm[:12].copy()
    bad[-1] = bad[-2] + np.array([0.0, 0.3, 0.0, 0.0, 0.0, 0.0, 0.0])
    states, problem = replay(physics, start, bad)
    step = physics.step(states[-1], bad[len(states)])
    assert step.reason is Invalid.ARM_TABLE and len(states) == len(bad) - 1
    assert problem == f"{step.reason.value}: {step.detail}"
    # Cut at the goal: the first state within 5 cm of where the push ends.
    end = pushed.states[-1].objects[g, :2]
    until = Stops(g, (float(end[0]), float(end[1])), 0.05)
    cut, problem = replay(physics, start, arm, until=until)
    inside = [np.hypot(*(s.objects[g, :2] - end)) <= 0.05 for s in full]
    assert problem == "" and len(cut) == inside.index(True) + 1 < len(arm)


def test_the_object_pair_broad_phase_never_passes_over_an_overlap():
    """`step._apart` lets the object checks skip a pair only when the footprints' circles are
    apart: then `kernels.prism_penetration` says they do not overlap, so the step's verdicts
    are those without it. Random boxes and cylinders near one another, both ways; it skips
    far pairs, never touching ones, and never for a negative tolerance."""
    from rearrangement_planner.physics import kernels
    from rearrangement_planner.physics.step import OBJ_FOOTPRINT, _apart

    rng = np.random.default_rng(5)
    skipped = 0
    for _ in range(3000):
        kinds = rng.integers(0, 2, 2)
        sizes = np.empty((2, 3))
        props = np.zeros((2, OBJ_FOOTPRINT + 1))
        for k in range(2):
            if kinds[k] == 0:
                sizes[k] = [*rng.uniform(0.03, 0.12, 2), 0.1]
                kind = kernels.BOX
            else:
                sizes[k] = [2 * rng.uniform(0.02, 0.05)] * 2 + [0.1]
                kind = kernels.CYLINDER
            kinds[k] = kind
            props[k, OBJ_FOOTPRINT] = (0.5 * sizes[k, 0] if kind == kernels.CYLINDER
                                       else 0.5 * math.hypot(sizes[k, 0], sizes[k, 1]))
        objects = np.array([[0.0, 0.0, rng.uniform(-3, 3)],
                            [*rng.uniform(-0.2, 0.2, 2), rng.uniform(-3, 3)]])
        depth = kernels.prism_penetration(kinds[0], sizes[0], *objects[0], kinds[1], sizes[1],
                                          *objects[1])
        if _apart(objects, props, 0, 1, 0.0):
            skipped += 1
            assert depth <= 0.0, (kinds, sizes, objects, depth)
        assert not _apart(objects, props, 0, 1, -1e-3)
    assert 500 < skipped < 2900, skipped


def test_a_step_s_buffers_stay_bounded_with_many_objects():
    """A step's contact problems work in buffers of `step_workspace`, sized for the most
    contacts one problem may have (`pushing.LCP_CONTACTS`) and not for every (shape, object)
    pair of the scene: with 7 objects and the Panda's 23 shapes that would be 203 contacts and
    16 MB of LCP scratch per loop of steps, with 60 objects 4,800 contacts and gigabytes."""
    from rearrangement_planner.physics.pushing import LCP_CONTACTS, lcp_scratch
    from rearrangement_planner.physics.step import _FLOATS, _P, step_workspace

    scene = load_scene("default")
    physics = Physics(scene)
    q = scene.initial_state().q
    for objects in (1, 7, 60):
        work = step_workspace(physics.arrays, q, np.zeros((objects, 3)))
        contacts = min(len(physics.arrays.shapes) * objects + objects * (objects - 1),
                       LCP_CONTACTS)
        assert work[_P].shape == (contacts, 2)
        assert work[_FLOATS].shape == lcp_scratch(contacts, objects)[0].shape
        assert work[_FLOATS].nbytes < 3e6, (objects, work[_FLOATS].nbytes)
