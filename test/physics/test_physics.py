"""The quasistatic physics step on the Panda (docs/design.md): whole-arm pushing, invariants after
every valid step, independence of how a motion is chopped, and every invalid reason."""

import dataclasses
import math

import numpy as np
import pytest
import yaml

from rearrangement_planner.model.robot import RobotConfig, RobotModel
from rearrangement_planner.model.scene import NOMINAL_C_SCALE
from rearrangement_planner.model.state import State
from rearrangement_planner.physics.options import PhysicsOptions, simulation_options
from rearrangement_planner.physics.step import OBJ_C, Invalid, Physics
from rearrangement_planner.physics.validation import load_scene, parse_scene
from rearrangement_planner.planning.machinery.manifold import default_push_configuration

SIM = simulation_options()
"""Plain mechanics: objects slide however pushed (no tipping check, no turn limit)."""

TABLE = {"center": [0.55, 0.0], "size": [0.8, 1.2], "height": 0.0}
# Arm folded low: the forearm (panda_link5) slopes down to 0.07 m and the wrist sits at object
# height, so a rotation of joint 1 sweeps forearm and wrist across the table.
LOW_ARM = [-0.7677, 1.6127, 1.0578, -1.7876, 1.2966, 0.8244, -0.8218]


def polar(radius, angle, yaw=0.0):
    return [radius * math.cos(angle), radius * math.sin(angle), yaw]


def cylinder(name, pose, radius=0.03):
    return {"name": name, "shape": "cylinder", "radius": radius, "height": 0.12, "pose": pose}


def box(name, pose, size=(0.06, 0.06, 0.12)):
    return {"name": name, "shape": "box", "size": list(size), "pose": pose}


def make_scene(objects, q, obstacles=(), robot=None, table=TABLE):
    data = {"start_configuration": list(q), "table": table, "objects": objects,
            "goal": {"object": objects[0]["name"], "position": [0.5, 0.0]}}
    if obstacles:
        data["obstacles"] = list(obstacles)
    if robot is None:
        data["robot"] = "panda"
    return parse_scene(data, robot=robot)


def sweep(physics, state, joint, delta, steps):
    """Rotate one joint by `delta` per call; stop at the first invalid step."""
    results = []
    for _ in range(steps):
        q = state.q.copy()
        q[joint] += delta
        result = physics.step(state, q)
        results.append(result)
        if not result.valid:
            break
        state = result.state
    return state, results


def _push_path(panda, end):
    """The tool on the pushing plane moving along +x from 0.40 m to `end` (IK every 5 mm)."""
    from rearrangement_planner.planning.machinery.manifold import ik_on_manifold

    q = default_push_configuration(panda, 0.0)
    path = []
    for x in np.arange(0.40, end, 0.005):
        q = ik_on_manifold(panda, float(x), 0.0, 0.0, 0.0, q)
        path.append(q)
    return path


def _walk(physics, state, path):
    """Step through `path` until a step is invalid: the last step's result and the last valid
    state."""
    result = None
    for q_next in path:
        result = physics.step(state, q_next)
        if not result.valid:
            break
        state = result.state
    assert result is not None
    return result, state


@pytest.fixture(scope="module")
def push_q(panda):
    return np.array(default_push_configuration(panda, 0.0))


@pytest.fixture(scope="module")
def whole_arm_scene(panda):
    return make_scene([cylinder("a", polar(0.43, 0.45)), cylinder("b", polar(0.56, 0.78))],
                      LOW_ARM, robot=panda)


def test_whole_arm_sweep_moves_two_objects_at_once_with_forearm_and_wrist(whole_arm_scene):
    physics = Physics(whole_arm_scene, SIM)
    state, results = sweep(physics, whole_arm_scene.initial_state(), 0, 0.005, 150)
    assert all(r.valid for r in results), results[-1].detail
    simultaneous = [r for r in results if len(r.moved_objects) == 2]
    assert simultaneous, "no step moved both objects"
    assert "panda_link5" in set().union(*(r.pushing_links for r in simultaneous))
    links = set().union(*(r.pushing_links for r in results))
    assert "panda_link5" in links and links - {"panda_hand"}, links
    moved = np.linalg.norm(state.objects[:, :2] - whole_arm_scene.object_poses[:, :2], axis=1)
    assert np.all(moved > 0.05), moved


def test_after_every_valid_step_no_penetration_and_no_overlap(whole_arm_scene):
    """Property over random sweeps: the invariants of docs/design.md hold after each valid step."""
    physics = Physics(whole_arm_scene, SIM)
    rng = np.random.default_rng(7)
    world, tol = physics.world, physics.options.penetration_tolerance
    checked = 0
    for _ in range(4):
        state = whole_arm_scene.initial_state()
        direction = rng.normal(size=7) * np.array([1, 0.2, 0.2, 0.2, 0.2, 0.2, 0.2])
        direction *= 0.006 / np.abs(direction).max()
        for _ in range(80):
            result = physics.step(state, state.q + direction)
            if not result.valid:
                break
            state = result.state
            poses = physics.robot.shape_poses(state.q)
            assert world.arm_object_penetration(poses, state.objects) <= tol + 1e-9
            assert world.object_overlaps(state.objects, tol=physics.options.overlap_tolerance) == []
            assert world.objects_off_table(state.objects) == []
            checked += 1
    assert checked > 100


def test_the_hand_pushing_the_target_moves_it_along(panda, push_q):
    """Tool on the pushing plane at (0.5, 0); a box ahead in +y; sweeping joint 1 pushes it +y."""
    tool = panda.tool_pose(push_q)[:3, 3]
    scene = make_scene([box("target", [tool[0] - 0.03, tool[1] + 0.16, 0.0])], push_q, robot=panda)
    physics = Physics(scene, SIM)
    state, results = sweep(physics, scene.initial_state(), 0, 0.004, 100)
    assert all(r.valid for r in results), results[-1].detail
    delta = state.objects[0] - scene.object_poses[0]
    assert delta[1] > 0.05
    assert any(r.moved_objects for r in results)


@pytest.mark.parametrize("calls", [10, 100])
def test_chopping_a_motion_gives_the_same_result(whole_arm_scene, calls):
    """One call, 10 calls or 100 calls along the same joint-space line: same object poses within
    2 mm and 0.05 rad (cylinders: their yaw is weakly determined) over a 0.6 rad sweep that
    pushes both objects ~20 cm (substeps bound the shape motion, so the chopping hardly
    matters; 1.2 mm measured with 100 calls)."""
    physics = Physics(whole_arm_scene, SIM)
    start = whole_arm_scene.initial_state()
    goal_q = start.q.copy()
    goal_q[0] += 0.6
    whole = physics.step(start, goal_q)
    assert whole.valid and whole.moved_objects
    state = start
    for i in range(1, calls + 1):
        result = physics.step(state, start.q + (goal_q - start.q) * (i / calls))
        assert result.valid, result.detail
        state = result.state
    np.testing.assert_allclose(state.objects[:, :2], whole.state.objects[:, :2], atol=2e-3)
    np.testing.assert_allclose(state.objects[:, 2], whole.state.objects[:, 2], atol=0.05)


def test_a_step_in_free_space_is_one_substep(panda):
    """No object within reach of the swept arm: one substep at q_next, no object moves."""
    q = np.array(LOW_ARM)
    q[0] -= 0.7
    scene = make_scene([cylinder("far", [0.70, 0.48, 0.0])], q, robot=panda)
    physics = Physics(scene, SIM)
    start = scene.initial_state()
    result = physics.step(start, q + np.array([0.5, 0, 0, 0, 0, 0, 0]))
    assert result.valid and result.substeps == 1
    np.testing.assert_array_equal(result.state.objects, start.objects)


def test_a_long_step_through_an_object_is_not_free_space(panda):
    """Both ends of the motion are clear of the object, the sweep between them is not: the
    free-space shortcut must not skip the substeps that push it."""
    q = np.array(LOW_ARM)
    q[0] -= 0.7
    scene = make_scene([cylinder("a", polar(0.5, 0.45))], q, robot=panda)
    physics = Physics(scene, SIM)
    start = scene.initial_state()
    q_next = q + np.array([1.8, 0, 0, 0, 0, 0, 0])
    for end in (q, q_next):
        assert physics.world.object_candidates(panda.shape_poses(end), start.objects)[0].size == 0
    result = physics.step(start, q_next)
    assert result.valid and result.substeps > 100 and result.moved_objects == {0}
    assert np.linalg.norm(result.state.objects[0, :2] - start.objects[0, :2]) > 0.1


def test_limit_surface_c_uses_each_objects_footprint(panda):
    scene = make_scene([cylinder("can", [0.5, 0.3, 0.0], radius=0.04),
                        box("block", [0.5, -0.3, 0.0], size=(0.06, 0.08, 0.1))],
                       LOW_ARM, robot=panda)
    physics = Physics(scene, SIM)
    # Uniform pressure's c times the nominal support's scale (model.scene.NOMINAL_C_SCALE).
    assert physics.c[0] == pytest.approx(2 * 0.04 / 3 * NOMINAL_C_SCALE, rel=1e-12)
    # 6 x 8 cm rectangle: mean distance from the centre, by numerical integration.
    xs = (np.arange(600) + 0.5) / 600 * 0.06 - 0.03
    ys = (np.arange(800) + 0.5) / 800 * 0.08 - 0.04
    rbar = np.hypot(*np.meshgrid(xs, ys)).mean()
    assert physics.c[1] == pytest.approx(rbar * NOMINAL_C_SCALE, rel=1e-5)
    assert physics.arrays.obj_props[1, OBJ_C] == physics.c[1]


def test_step_is_deterministic(whole_arm_scene):
    physics = Physics(whole_arm_scene, SIM)
    start = whole_arm_scene.initial_state()
    q = start.q.copy()
    q[0] += 0.5
    a, b = physics.step(start, q), physics.step(start, q)
    assert np.array_equal(a.state.objects, b.state.objects)


def test_pusher_displacement_is_the_link_motion(panda):
    """The rigid link transform used for the pusher displacement equals J(p) dq to first order."""
    q = np.array(LOW_ARM)
    dq = np.random.default_rng(3).normal(size=7) * 1e-5
    poses_a, poses_b = panda.shape_poses(q), panda.shape_poses(q + dq)
    s = [i for i, sh in enumerate(panda.contact_shapes) if sh.link == "panda_link5"][0]
    p = poses_b[s, :3, 3] + 0.02 * poses_b[s, :3, 0]
    t_a, t_b = poses_a[s], poses_b[s]
    p_before = t_a[:3, :3] @ (t_b[:3, :3].T @ (p - t_b[:3, 3])) + t_a[:3, 3]
    np.testing.assert_allclose(p - p_before, panda.shape_jacobian(q, s, p)[:3] @ dq, atol=1e-9)


# -- every invalid reason, each from a constructed case --------------------------------------


def test_invalid_joint_limit(whole_arm_scene):
    physics = Physics(whole_arm_scene, SIM)
    start = whole_arm_scene.initial_state()
    q = start.q.copy()
    q[3] = 0.1
    result = physics.step(start, q)
    assert result.reason is Invalid.JOINT_LIMIT and "panda_joint4" in result.detail
    assert result.state is start


def test_invalid_arm_table_penetration(panda, push_q):
    scene = make_scene([box("far", [0.6, -0.45, 0.0])], push_q, robot=panda)
    _, results = sweep(Physics(scene, SIM), scene.initial_state(), 1, 0.01, 40)  # shoulder down
    assert results[-1].reason is Invalid.ARM_TABLE and "table" in results[-1].detail


def test_invalid_arm_obstacle_penetration(panda, push_q):
    tool = panda.tool_pose(push_q)[:3, 3]
    post = {"name": "post", "shape": "box", "size": [0.05, 0.05, 0.3],
            "pose": [tool[0], tool[1] + 0.15, 0.0]}
    scene = make_scene([box("far", [0.6, -0.45, 0.0])], push_q, obstacles=[post], robot=panda)
    _, results = sweep(Physics(scene, SIM), scene.initial_state(), 0, 0.005, 100)
    assert results[-1].reason is Invalid.ARM_OBSTACLE and "'post'" in results[-1].detail


def _pushed_into(panda, push_q, second=(), obstacles=(), table=TABLE, gap=0.005,
                 options=None):
    """The hand pushes a box ('target') in +y; `second`/`obstacles`/`table` get the target's
    +y face position and place something just beyond it."""
    tool = panda.tool_pose(push_q)[:3, 3]
    target = [tool[0] - 0.03, tool[1] + 0.16, 0.0]
    face = target[1] + 0.03 + gap
    scene = make_scene([box("target", target), *second(face)], push_q,
                       obstacles=obstacles(face) if obstacles else (), robot=panda,
                       table=table(face) if callable(table) else table)
    _, results = sweep(Physics(scene, options or SIM), scene.initial_state(), 0, 0.004, 100)
    return results[-1]


def test_invalid_object_object_overlap_without_object_contact(panda, push_q):
    """King et al.'s model (object_contact off): objects never touch."""
    last = _pushed_into(panda, push_q, lambda face: [box("other", [0.47, face + 0.03, 0.0])],
                        options=dataclasses.replace(SIM, object_contact=False))
    assert last.reason is Invalid.OBJECT_OVERLAP
    assert "'target'" in last.detail and "'other'" in last.detail


def test_a_pushed_object_pushes_the_next_with_object_contact(panda, push_q):
    """With object contact (the default), the target pushed into another box pushes it along:
    both move, neither penetrates the other beyond the contact tolerance."""
    from rearrangement_planner.physics.kernels import BOX, prism_penetration

    last = _pushed_into(panda, push_q, lambda face: [box("other", [0.47, face + 0.03, 0.0])])
    assert last.valid and last.moved_objects == {0, 1}
    (x0, y0, yaw0), (x1, y1, yaw1) = last.state.objects
    size = np.array([0.06, 0.06, 0.12])
    assert prism_penetration(BOX, size, x0, y0, yaw0, BOX, size, x1, y1, yaw1) \
        < SIM.contact_tolerance
    assert y1 > y0 + 0.03                                # pushed ahead, not passed through


def test_invalid_object_obstacle_overlap(panda, push_q):
    def wall(face):
        return [{"name": "wall", "shape": "box", "size": [0.3, 0.04, 0.3],
                 "pose": [0.47, face + 0.02, 0.0]}]

    last = _pushed_into(panda, push_q, lambda face: [], obstacles=wall)
    assert last.reason is Invalid.OBJECT_OBSTACLE and "'wall'" in last.detail


def test_invalid_object_off_table(panda, push_q):
    def narrow(face):
        edge = face - 0.02   # the target's centre is 0.015 m from the edge
        return {"center": [0.55, (edge - 0.6) / 2], "size": [0.8, edge + 0.6], "height": 0.0}

    last = _pushed_into(panda, push_q, lambda face: [], table=narrow)
    assert last.reason is Invalid.OFF_TABLE and "'target'" in last.detail


def test_invalid_contact_from_above(panda, push_q):
    """A flat object under the wrist: the links meet its top face, not its sides."""
    poses = panda.shape_poses(push_q)
    wrist = [i for i, s in enumerate(panda.contact_shapes) if s.link == "panda_link7"][0]
    centre = poses[wrist, :3, 3]
    flat = box("flat", [centre[0], centre[1] + 0.1, 0.0], size=(0.06, 0.06, 0.02))
    scene = make_scene([flat], push_q, robot=panda)
    _, results = sweep(Physics(scene, SIM), scene.initial_state(), 0, 0.004, 100)
    assert results[-1].reason is Invalid.CONTACT_FROM_ABOVE and "from above" in results[-1].detail


def _pinch_robot(panda):
    """The Panda with two test pushers at object height: a fixed post on the base link and a
    post on link 1 that joint 1 swings towards it, squeezing whatever stands between them."""
    data = yaml.safe_load(panda.config.source.read_text())
    data["contact_shapes"] = [
        {"link": "panda_link0", "type": "capsule", "radius": 0.02,
         "points": [[0.5, 0.05, 0.03], [0.5, 0.05, 0.10]]},
        {"link": "panda_link1", "type": "capsule", "radius": 0.02,
         "points": [[0.5, -0.05, -0.30], [0.5, -0.05, -0.23]]},
    ]
    return RobotModel(RobotConfig.from_dict(data, base_dir=panda.config.source.parent))


def test_invalid_jamming_between_two_links(panda):
    robot = _pinch_robot(panda)
    q = np.zeros(7)
    q[3], q[5] = -1.5, 1.5
    scene = make_scene([box("squeezed", [0.5, 0.0, 0.0], size=(0.06, 0.058, 0.12))], q,
                       robot=robot)
    _, results = sweep(Physics(scene, SIM), scene.initial_state(), 0, 0.002, 20)
    assert results[-1].reason is Invalid.JAMMING
    assert "'squeezed'" in results[-1].detail and "jammed" in results[-1].detail


def test_invalid_residual_penetration():
    """With a zero tolerance and a receding pusher left inside the object, the penetration
    that no push can undo is reported."""
    scene = load_scene("config/scenes/default.yaml")
    physics = Physics(scene, PhysicsOptions(tipping=False, max_turn=0.0, penetration_tolerance=0.0))
    robot = scene.robot
    q = np.array(default_push_configuration(robot, 0.0))
    tool = robot.tool_pose(q)[:3, 3]
    objects = scene.object_poses.copy()
    objects[0] = [tool[0] + 0.01, tool[1], 0.0]  # the finger tips inside the target
    objects[1:] = [[0.3, -0.45, 0.0], [0.3, 0.45, 0.0]]
    state = State(q, objects)
    q2 = q.copy()
    q2[0] += 1e-4
    result = physics.step(state, q2)
    assert result.reason is Invalid.RESIDUAL_PENETRATION and "mm" in result.detail


def test_check_state_reports_a_resting_state(whole_arm_scene):
    physics = Physics(whole_arm_scene, SIM)
    assert physics.check_state(whole_arm_scene.initial_state()) is None
    bad = whole_arm_scene.initial_state().with_objects(
        np.array([[0.43, 0.2, 0.0], [0.44, 0.2, 0.0]]))
    problem = physics.check_state(bad)
    assert problem is not None and problem[0] in (Invalid.OBJECT_OVERLAP,
                                                  Invalid.RESIDUAL_PENETRATION)


# --------------------------------------------------------------------------------------------
# Tipping (docs/design.md "Quasistatic pushing physics")
# --------------------------------------------------------------------------------------------


def test_the_tipping_condition_depends_on_height_friction_and_footprint(panda):
    from rearrangement_planner.physics.step import tips_over

    tall = make_scene([{**box("tall", [0.5, 0.0, 0.0], size=(0.04, 0.08, 0.25)),
                        "support_friction": 1.0}], panda.home, robot=panda).objects[0]
    along_x, along_y = np.array([1e-3, 0.0, 0.0]), np.array([0.0, 1e-3, 0.0])
    assert tips_over(tall, along_x, 0.09)                  # mu h = 0.09 > 0.02 (half of 4 cm)
    assert not tips_over(tall, along_x, 0.015)             # a low push slides it
    assert not tips_over(tall, along_y, 0.035)             # 0.035 < 0.04: the wide side leads
    assert not tips_over(tall, np.array([0.0, 0.0, 0.01]), 0.2)   # turning in place


def test_a_tipping_push_is_invalid_and_the_same_push_slides_without_the_check(panda):
    """The hand, on the pushing plane (tool 6 cm up), pushes a tall narrow box on a grippy
    table along +x: with the tipping check the first pushing step is invalid (object_would_tip);
    without it the box slides (the model of King et al.)."""
    path = _push_path(panda, 0.50)
    tall = {**box("tall", [0.46, 0.0, 0.0], size=(0.04, 0.08, 0.25)), "support_friction": 1.0}
    scene = make_scene([tall], path[0], robot=panda)
    reasons = {}
    for tipping in (True, False):
        physics = Physics(scene, PhysicsOptions(tipping=tipping))
        state, reason = scene.initial_state(), None
        for q_next in path[1:]:
            result = physics.step(state, q_next)
            if not result.valid:
                reason = result.reason
                break
            state = result.state
        reasons[tipping] = (reason, state.objects[0, 0] - 0.46)
    assert reasons[True][0] is Invalid.TIPPING
    assert reasons[False][0] is None and reasons[False][1] > 0.01


def test_a_push_that_turns_its_object_fast_is_invalid_with_max_turn(panda):
    """Pushed 2.8 cm off its centre line the box turns about a radian over the push (6 rad
    per metre at first): refused with max_turn 5, named with its rate; the centred push and
    the 1.5 cm offset one (the pads' face still reaches the centre line) go straight and stay
    valid."""
    path = _push_path(panda, 0.55)

    def push(offset, max_turn):
        scene = make_scene([box("b", [0.46, offset, 0.0], size=(0.06, 0.08, 0.12))], path[0],
                           robot=panda)
        physics = Physics(scene, PhysicsOptions(max_turn=max_turn))
        state = scene.initial_state()
        for q_next in path[1:]:
            result = physics.step(state, q_next)
            if not result.valid:
                return result, state
            state = result.state
        return result, state

    result, state = push(0.028, 0.0)
    assert result.valid and state.objects[0, 2] > 0.8
    result, state = push(0.028, 5.0)
    assert result.reason is Invalid.TURNING and state.objects[0, 0] == 0.46
    assert result.detail == "'b' would turn too fast: 6.0 rad per m it moves"
    for offset in (0.0, 0.015):
        result, state = push(offset, 5.0)
        assert result.valid and abs(state.objects[0, 2]) < 1e-3 and state.objects[0, 0] > 0.55


def test_the_turn_limit_leaves_cylinders_alone(panda):
    """The finger tips push a cylinder 2.5 cm off its centre line: it turns faster than
    5 rad per m (its turn leaves its footprint where it was) and the push stays valid under
    max_turn 5; a box pushed the same way is refused."""
    path = _push_path(panda, 0.55)
    for obj, valid in ((cylinder("c", [0.46, 0.025, 0.0], radius=0.03), True),
                       (box("b", [0.46, 0.025, 0.0], size=(0.06, 0.06, 0.12)), False)):
        scene = make_scene([obj], path[0], robot=panda)
        result, state = _walk(Physics(scene, PhysicsOptions(max_turn=5.0)),
                              scene.initial_state(), path[1:])
        assert result.valid is valid, result.detail
        if valid:
            moved = math.hypot(*(state.objects[0, :2] - scene.object_poses[0][:2]))
            assert moved > 0.05 and abs(state.objects[0, 2]) > 5.0 * 0.05
        else:
            assert result.reason is Invalid.TURNING


def test_the_packed_options_follow_the_named_columns(panda):
    """The compiled step reads `World.options` by the OPT_* constants: each column holds the
    `PhysicsOptions` field `OPTION_FIELDS` names (distinct values, so a swapped column shows),
    and every setting the kernels read is packed."""
    from rearrangement_planner.physics import step

    options = PhysicsOptions(max_substep=0.0031, penetration_tolerance=0.0021,
                             overlap_tolerance=0.00011, vertical_normal_limit=0.61,
                             tipping=True, max_turn=7.5, object_contact=True,
                             tip_judgement=True, contact_tolerance=0.0017)
    packed = step.packed_options(options)
    columns = {"max_substep": step.OPT_MAX_SUBSTEP, "penetration_tolerance": step.OPT_PENETRATION,
               "overlap_tolerance": step.OPT_OVERLAP,
               "vertical_normal_limit": step.OPT_VERTICAL_NORMAL, "tipping": step.OPT_TIPPING,
               "max_turn": step.OPT_MAX_TURN, "object_contact": step.OPT_OBJECT_CONTACT,
               "tip_judgement": step.OPT_TIP_JUDGEMENT,
               "contact_tolerance": step.OPT_CONTACT_TOLERANCE}
    assert len(packed) == len(step.OPTION_FIELDS) == len(columns) + 1
    for name, column in columns.items():
        assert step.OPTION_FIELDS[column] == name
        assert packed[column] == float(getattr(options, name)), name
    assert packed[step.OPT_FREE_SPACE] == step.FREE_SPACE_MARGIN
    settings = {s.name for s in PhysicsOptions.describe()}
    assert settings <= set(step.OPTION_FIELDS)        # every setting reaches the kernels
    scene = make_scene([box("b", [0.5, -0.3, 0.0], size=(0.06, 0.08, 0.1),
                            )], LOW_ARM, robot=panda)
    props = Physics(scene, SIM).arrays.obj_props[0]
    obj = scene.objects[0]
    assert props[step.OBJ_CENTRE_Z] == pytest.approx(scene.table.height + 0.05)
    assert props[step.OBJ_PUSHER_MU] == obj.pusher_friction
    assert props[step.OBJ_SUPPORT_MU] == obj.support_friction
    assert props[step.OBJ_FOOTPRINT] == obj.footprint_radius
    assert props[step.OBJ_STATIC] == 0.0
    assert (props[step.OBJ_COF_X], props[step.OBJ_COF_Y]) == obj.support.centre == (0.0, 0.0)
    assert props[step.OBJ_MASS] == obj.mass
