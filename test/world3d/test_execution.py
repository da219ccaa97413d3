"""The execution check in MuJoCo (docs/design.md): a straight push moves a box as the
quasistatic model predicts and leaves an untouched object where it was; a real plan is played
ideal and servo-driven, compared with its prediction point by point; perturbed executions;
the reasons it refuses to run. Headless, CPU only."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import yaml

from rearrangement_planner.execution.open_loop import OpenLoopExecution
from rearrangement_planner.model.command import Command
from rearrangement_planner.model.perturbation import Perturbation
from rearrangement_planner.physics.options import simulation_options
from rearrangement_planner.physics.step import Physics
from rearrangement_planner.physics.validation import load_scene, parse_scene
from rearrangement_planner.planning import PCRRTOptions, PlanRequest, plan_scene
from rearrangement_planner.planning.requests.trajectory import Trajectory
from rearrangement_planner.world3d.execution import (
    Execution,
    check_execution,
    check_perturbed,
    controller_command,
)
from rearrangement_planner.world3d.mujoco_model import (
    ExecutionCheckError,
    ExecutionOptions,
    build_model,
)

BOX = {"name": "box", "shape": "box", "size": [0.06, 0.08, 0.12], "pose": [0.46, 0.0, 0.0],
       "mass": 0.4, "support_friction": 0.4, "pusher_friction": 0.3}
BYSTANDER = {"name": "bystander", "shape": "cylinder", "radius": 0.03, "height": 0.1,
             "pose": [0.5, 0.3, 0.0]}


@pytest.fixture(scope="module")
def straight_push(pushed):
    """A box 3 cm ahead of the finger tips on the push line, a cylinder well aside."""
    return pushed([BOX, BYSTANDER])


def test_a_straight_push_moves_the_box_as_the_quasistatic_model_predicts(straight_push):
    scene, trajectory, predicted = straight_push
    report = check_execution(scene, trajectory, [predicted] * len(trajectory))
    box, bystander = report.objects
    moved = np.asarray(box.pose[:2]) - scene.objects[0].pose[:2]
    expected = predicted.objects[0, :2] - scene.objects[0].pose[:2]
    assert expected[0] > 0.10 and abs(expected[1]) < 1e-3            # pushed ~13 cm along x
    # Within 1 cm (0.9 mm measured): the finger capsules reach where the real finger pads do.
    assert np.linalg.norm(moved - expected) < 0.01, (moved, expected)
    assert abs(box.pose[2]) < 0.02 and not box.toppled and box.max_tilt_deg < 2.0
    assert bystander.moved_m < 1e-3 and not bystander.toppled
    assert report.arm_collisions == {} and report.object_contacts == ()


@pytest.mark.parametrize(("offset", "turn"), [(0.015, 0.0), (0.03, 1.0)])
def test_an_off_centre_push_turns_the_box_as_much_as_in_mujoco(pushed, offset, turn):
    """The finger pads' flat tip face spans 3 cm: pushed 1.5 cm off its centre line the box
    still goes straight (the face reaches the line through its centre), pushed 3 cm off it
    turns by about a radian; in MuJoCo and in the model alike (within 0.25 rad, 1.5 cm)."""
    box = {**BOX, "pose": [0.46, offset, 0.0]}
    scene, trajectory, predicted = pushed([box])
    executed = np.asarray(check_execution(scene, trajectory).objects[0].pose)
    start = scene.object_poses[0]
    for pose in (executed, predicted.objects[0]):
        assert abs(pose[2] - start[2] - turn) < 0.25, (pose, predicted.objects[0])
    assert np.linalg.norm(executed[:2] - predicted.objects[0, :2]) < 0.015


def test_a_centre_of_friction_off_the_push_line_turns_the_box_the_same_way_in_both(
        panda, push_path, pushed):
    """The box pushed 3 cm off its centre line, with its weight resting 1 cm towards the
    finger or 1 cm away from it (`SupportPressure.centre`; MuJoCo moves the centre of mass
    there): away from the finger it turns more, in the model and in MuJoCo alike."""
    from rearrangement_planner.model.scene import SupportPressure

    box = {**BOX, "pose": [0.46, 0.03, 0.0]}
    scene, trajectory, _ = pushed([box])
    times, positions = push_path
    turns = {}
    for side in (-1.0, 1.0):        # the finger meets the box at y = -3 cm in its frame
        obj = dataclasses.replace(scene.objects[0],
                                  support=SupportPressure(1.0, (0.0, 0.01 * side)))
        world = dataclasses.replace(scene, objects=(obj,))
        executed = check_execution(world, trajectory).objects[0].pose[2]
        run = OpenLoopExecution(Physics(world, dataclasses.replace(simulation_options(),
                                                                   max_substep=0.001)),
                                world.initial_state(), Command(times, positions), period=0.01)
        run.run()
        turns[side] = (executed, float(run.state.objects[0, 2]))
    for which in (0, 1):            # MuJoCo, then the model
        assert turns[1.0][which] > turns[-1.0][which] + 0.05, turns


SMALL_BOX = {**BOX, "size": [0.05, 0.05, 0.1], "mass": 0.3}
CAN = {"name": "can", "shape": "cylinder", "radius": 0.03, "height": 0.1, "mass": 0.3,
       "support_friction": 0.4, "pusher_friction": 0.3}


@pytest.mark.parametrize("row", [
    [("second", BOX, (0.525, 0.0))],                                  # two in a row
    [("second", BOX, (0.525, 0.025))],                                # the second off the line
    [("second", SMALL_BOX, (0.525, 0.0)), ("can", CAN, (0.585, 0.0))],   # three in a row
    [("can", CAN, (0.525, -0.02))],                                   # a can off the line
], ids=["two", "offset", "three", "can"])
def test_a_row_of_objects_moves_as_in_mujoco(pushed, row):
    """The box pushed into one or two more (object contact, `PhysicsOptions.object_contact`):
    each object ends where MuJoCo puts it, within 5 mm (0.4-2.2 mm measured)."""
    objects = [BOX] + [{**spec, "name": name, "pose": [x, y, 0.0]}
                       for name, spec, (x, y) in row]
    scene, trajectory, predicted = pushed(objects)
    executed = check_execution(scene, trajectory)
    touched = {name for pair in executed.object_contacts for name in pair.split("<->")}
    assert touched == {o["name"] for o in objects}, executed.object_contacts   # recorded
    for i, outcome in enumerate(executed.objects):
        assert outcome.moved_m > 0.05, outcome.name            # all of them pushed along
        error = np.hypot(*(np.asarray(outcome.pose[:2]) - predicted.objects[i, :2]))
        assert error < 0.005, (outcome.name, outcome.pose, predicted.objects[i])


def test_the_arm_meeting_an_obstacle_is_recorded_with_its_depth(panda, push_path):
    """A post stands in the straight push's way: the execution names the link that meets it
    and how deep it went (`ExecutionReport.arm_collisions`); the objects on the table are not
    collisions."""
    times, positions = push_path
    scene = parse_scene({
        "table": {"center": [0.55, 0.0], "size": [0.8, 1.2], "height": 0.0},
        "start_configuration": positions[0].tolist(), "objects": [BYSTANDER],
        "obstacles": [{"name": "post", "shape": "box", "size": [0.04, 0.2, 0.2],
                       "pose": [0.54, 0.0, 0.0]}],
        "goal": {"object": "bystander", "position": [0.5, 0.3], "radius": 0.05}}, robot=panda)
    trajectory = Trajectory(panda.joint_names, times, positions, np.zeros_like(positions))
    report = check_execution(scene, trajectory)
    assert report.arm_collisions, "the hand drives into the post"
    assert all(key.endswith("->post") and depth > 0.0
               for key, depth in report.arm_collisions.items()), report.arm_collisions
    assert report.object_contacts == ()


def _deepest_push(scene, trajectory, options):
    """The deepest arm-box penetration (m) over the straight push in MuJoCo."""
    model = build_model(scene, options)
    run = Execution(model, scene, controller_command(trajectory, scene.robot.joint_names), None,
                    options)
    run.begin()
    box = model.body(scene.objects[0].name).id
    deepest, t = 0.0, 0.0
    while t < trajectory.times[-1]:
        t += 0.01
        run.advance(t)
        for contact in run.data.contact[:run.data.ncon]:
            bodies = {model.geom_bodyid[contact.geom1], model.geom_bodyid[contact.geom2]}
            if box in bodies and model.geom(contact.geom1).name != "table" \
                    and model.geom(contact.geom2).name != "table":
                deepest = max(deepest, -contact.dist)
    return deepest


def test_a_finger_does_not_sink_into_the_box_it_pushes(straight_push):
    """Rigid finger, rigid box: MuJoCo's contacts undo a penetration within 5 ms
    (`contact_timeconst`), so the finger stays within 0.1 mm of the box's face (0.05 mm
    measured). With MuJoCo's default 20 ms it sank six times deeper here, and 9 mm into a
    cylinder on a plan's sliding push, which dragged the cylinder round where the planner's
    rigid model pushed it along (docs/experiments.md, 2026-11-27)."""
    scene, trajectory, _ = straight_push
    stiff = _deepest_push(scene, trajectory, ExecutionOptions())
    soft = _deepest_push(scene, trajectory, ExecutionOptions(contact_timeconst=0.02))
    assert stiff < 1e-4 and soft > 4.0 * stiff, (stiff, soft)


def test_the_contact_time_constant_is_checked_against_the_timestep():
    with pytest.raises(ValueError, match=r"contact_timeconst must be in \[2 timestep, 0.1\]"):
        ExecutionOptions(timestep=0.002, contact_timeconst=0.003)


def test_servo_arm_tracks_the_straight_push_like_the_ideal_arm(straight_push):
    scene, trajectory, _ = straight_push
    ideal = check_execution(scene, trajectory)
    servo = check_execution(scene, trajectory, options=ExecutionOptions(arm="servo"))
    assert servo.max_tracking_error_rad < 0.01
    assert ideal.max_tracking_error_rad < 1e-6
    np.testing.assert_allclose(servo.objects[0].pose[:2], ideal.objects[0].pose[:2], atol=0.003)


def test_the_servo_feed_forward_is_kv_over_kp_of_the_compiled_servos(straight_push):
    scene, trajectory, _ = straight_push
    kp = tuple(500.0 + 100.0 * i for i in range(7))
    kv = tuple(20.0 + 5.0 * i for i in range(7))
    options = ExecutionOptions(arm="servo", kp=kp, kv=kv)
    command = Command(trajectory.times, trajectory.positions)
    run = Execution(build_model(scene, options), scene, command, None, options)
    np.testing.assert_allclose(run.feedforward, np.array(kv) / np.array(kp))
    default = ExecutionOptions(arm="servo")
    run = Execution(build_model(scene, default), scene, command, None, default)
    np.testing.assert_allclose(run.feedforward, [150 / 3000] * 4 + [40 / 1000] * 3)



def test_the_command_is_sampled_once_at_every_step_as_the_controller_plays_it(straight_push):
    """The execution samples the command once for all its steps (the settling, the
    trajectory, the hold): each step's reference and slope are `Command.sample` and
    `Command.velocity` at that step's start time."""
    scene, trajectory, _ = straight_push
    options = ExecutionOptions(arm="servo", settle=0.05, hold=0.05)
    command = Command(trajectory.times, trajectory.positions)
    run = Execution(build_model(scene, options), scene, command, None, options)
    steps = len(run.slope)
    assert steps * options.timestep >= options.settle + command.duration + options.hold
    for k in range(0, steps, 7):
        t = k * options.timestep - options.settle
        np.testing.assert_allclose(run.reference[k], command.sample(t), atol=1e-12)
        np.testing.assert_allclose(run.slope[k], command.velocity(t), atol=1e-9)

def test_a_real_plan_is_compared_with_its_prediction_point_by_point(panda):
    scene = load_scene("easy_push", robot=panda)
    output = plan_scene(PlanRequest.first_plan(scene, "pc-rrt", PCRRTOptions(time_limit=60),
                                               seed=1))
    report = check_execution(scene, output.trajectory, output.trajectory_states)
    (target,) = report.objects
    assert report.executed_paths.shape == (len(output.trajectory), 1, 3)
    np.testing.assert_allclose(report.executed_paths[-1, 0, :2], target.pose[:2], atol=0.01)
    assert target.max_error_m >= target.final_error_m > 0.0
    assert report.reached == (report.goal_distance_m <= scene.goal.radius)
    record = report.to_dict()
    assert set(record["objects"]["target"]) >= {"final_error_m", "error_from_s", "toppled"}


def test_perturbed_executions_are_reproducible_and_counted(straight_push):
    scene, trajectory, _ = straight_push
    small = Perturbation(friction=0.1, mass=0.1, pose_noise=0.002, yaw_noise=0.01)
    first = check_perturbed(scene, trajectory, trials=2, seed=3, perturbation=small)
    again = check_perturbed(scene, trajectory, trials=2, seed=3, perturbation=small)
    assert first.trials == 2 and 0 <= first.reached <= 2
    assert [r.goal_distance_m for r in first.reports] == [r.goal_distance_m
                                                          for r in again.reports]
    assert first.reports[0].goal_distance_m != first.reports[1].goal_distance_m


def test_a_tipping_push_topples_the_box(straight_push, panda):
    """A tall, light box on a grippy table, pushed at the tool's height: it falls over."""
    scene, trajectory, _ = straight_push
    data = yaml.safe_load(yaml.safe_dump(scene.to_dict()))
    data["objects"][0].update(size=[0.04, 0.08, 0.25], support_friction=1.0, mass=0.2)
    tall = parse_scene(data, robot=panda)
    report = check_execution(tall, trajectory)
    assert report.objects[0].toppled and "box" in report.toppled and not report.reached


def test_the_check_refuses_what_it_cannot_model(straight_push):
    scene, trajectory, predicted = straight_push
    with pytest.raises(ExecutionCheckError, match="3 predicted states for"):
        check_execution(scene, trajectory, [predicted] * 3)
    bad = Trajectory(("a", "b", "c", "d", "e", "f", "g"), trajectory.times,
                     trajectory.positions, trajectory.velocities)
    with pytest.raises(ExecutionCheckError, match="the trajectory has no panda_joint1"):
        check_execution(scene, bad)
    with pytest.raises(ValueError, match="arm must be 'ideal' or 'servo'"):
        ExecutionOptions(arm="loose")




def test_a_robot_without_a_usable_collision_urdf_is_refused_by_name(straight_push, tmp_path):
    """The check simulates the scene's own arm from its collision URDF; when that cannot be read
    it says so (Collada meshes, which MuJoCo cannot read, end the same way)."""
    from rearrangement_planner.model.robot import RobotConfig, RobotModel

    scene, trajectory, _ = straight_push
    data = yaml.safe_load(scene.robot.config.source.read_text())
    data["collision_urdf"] = str(tmp_path / "gone.urdf")
    robot = RobotModel(RobotConfig.from_dict(data, base_dir=scene.robot.config.source.parent))
    with pytest.raises(ExecutionCheckError, match="cannot read the arm's URDF .*gone.urdf"):
        check_execution(dataclasses.replace(scene, robot=robot), trajectory)


def test_a_second_arm_plans_and_its_plan_reaches_the_goal_in_mujoco():
    """The xArm7 (config fitted by `rearrangement-robot fit`, its own meshes in MuJoCo): the
    default scene's first plan of one tree, seed 3, executed with the ideal and the servo arm.
    A first plan is not a robust one: of seeds 0-5 with the nominal support fitted to MuJoCo
    (2026-11-30), seeds 1-5 reach the goal (3 ends 2.5 cm from its point) and seed 0 topples
    the goal object (3 of 6 reached before)."""
    scene = load_scene("default_xarm7")
    assert scene.robot.name == "xarm7"
    output = plan_scene(PlanRequest.first_plan(scene, "pc-rrt", PCRRTOptions(time_limit=60.0),
                                               seed=3))
    assert output.solved
    for arm in ("ideal", "servo"):
        report = check_execution(scene, output.trajectory, output.trajectory_states,
                                 ExecutionOptions(arm=arm))
        assert report.reached and not report.toppled, (arm, report.goal_distance_m)


def test_the_nominal_support_turns_pushed_objects_as_far_as_mujoco_does(pushed):
    """The nominal object's c (`model.scene.NOMINAL_C_SCALE`) is fitted to MuJoCo: sixteen
    boxes and cylinders of drawn sizes, frictions and masses, pushed 1.5-3.5 cm off their
    centre line, turn about as far in the model as in MuJoCo (the median ratio within 0.8-1.2,
    1.05 measured; under uniform pressure, c x 1.0, the model turned them 1.36 x as far)."""
    rng = np.random.default_rng(5)
    ratios = []
    while len(ratios) < 16:
        height = float(rng.uniform(0.06, 0.12))
        if rng.uniform() < 0.4:
            radius = float(rng.uniform(0.025, 0.045))
            obj, half = {"shape": "cylinder", "radius": radius, "height": height}, radius
        else:
            size = [float(rng.uniform(0.04, 0.09)), float(rng.uniform(0.04, 0.09)), height]
            obj, half = {"shape": "box", "size": size}, 0.5 * size[0]
        offset = float(rng.choice([-1.0, 1.0]) * rng.uniform(0.015, 0.035))
        obj.update(name="pushed", pose=[0.44 + half, offset, 0.0],
                   mass=float(rng.uniform(0.2, 0.8)),
                   support_friction=float(rng.uniform(0.2, 0.5)),
                   pusher_friction=float(rng.uniform(0.2, 0.5)))
        scene, trajectory, predicted = pushed([obj])
        executed = check_execution(scene, trajectory).objects[0]
        if abs(executed.pose[2]) > 0.2 and not executed.toppled:
            ratios.append(float(predicted.objects[0, 2]) / executed.pose[2])
    assert 0.8 < float(np.median(ratios)) < 1.2, sorted(ratios)
