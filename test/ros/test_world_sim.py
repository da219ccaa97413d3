"""world_sim over DDS: state publishing, open-loop execution of a recorded plan, rejection of
bad commands, invalid steps, preemption, and perturbed worlds where a good plan fails.

The plan is the committed reference plan of the `easy_push_1obj` bag
(bags/plans/easy_push_1obj.plan.mcap), executed in that bag's ground-truth world: a fixed
trajectory, independent of later planner changes. Isolated from other runs: localhost
discovery and a domain id from the pid (160..189; test_node uses 10..159).
"""

from __future__ import annotations

import copy
import gc
import json
import math
import os
import time
from pathlib import Path
from types import SimpleNamespace

os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
DOMAIN_ID = 110 + os.getpid() % 40

import numpy as np  # noqa: E402
import pytest  # noqa: E402
import yaml  # noqa: E402
from builtin_interfaces.msg import Duration  # noqa: E402
from geometry_msgs.msg import PoseArray  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402
from rclpy.qos import (  # noqa: E402
    DurabilityPolicy,
    QoSProfile,
    ReliabilityPolicy,
    qos_profile_sensor_data,
)
from sensor_msgs.msg import JointState  # noqa: E402
from std_srvs.srv import Trigger  # noqa: E402
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint  # noqa: E402

from msg_adapters import goal_to_pose_stamped, pose_array_to_objects  # noqa: E402
from msg_adapters.command import command_from_msg  # noqa: E402
from rearrangement_planner.execution.open_loop import OpenLoopExecution  # noqa: E402
from rearrangement_planner.model.command import Command  # noqa: E402
from rearrangement_planner.model.errors import InputError, RearrangementError  # noqa: E402
from rearrangement_planner.physics.options import simulation_options  # noqa: E402
from rearrangement_planner.physics.step import Physics  # noqa: E402
from rearrangement_planner.physics.validation import load_scene  # noqa: E402
from rearrangement_planner.ros.sim.replay import (  # noqa: E402
    OutcomeListener,
    Session,
    read_bag,
    wait_until,
)
from rearrangement_planner.ros.sim.world_sim import MAX_SUBSTEP, WorldSim  # noqa: E402

BAGS = Path(__file__).resolve().parents[2] / "bags"
FRAME = "world"
TIME_SCALE = 20.0
COMMAND_QOS = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE,
                         durability=DurabilityPolicy.VOLATILE)


def load_reference(name: str, folder: Path) -> SimpleNamespace:
    """Bag `name`'s ground-truth world (written as a scene file into `folder`) and the
    trajectory of its reference plan."""
    bag = read_bag(BAGS / f"{name}.mcap")
    plan = read_bag(BAGS / "plans" / f"{name}.plan.mcap")
    world_file = folder / f"{name}.world.yaml"
    world_file.write_text(yaml.safe_dump(bag.input_metadata()["world"], sort_keys=False))
    scene = load_scene(world_file)
    trajectory = plan.last("/rearrangement_planner/trajectory")
    return SimpleNamespace(world_file=world_file, scene=scene, trajectory=trajectory,
                           command=command_from_msg(trajectory, scene.robot,
                                                    scene.start_configuration, 0.01))


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    """The easy_push_1obj bag's world and reference plan."""
    return load_reference("easy_push_1obj", tmp_path_factory.mktemp("world"))


@pytest.fixture(scope="module")
def session():
    with Session(domain_id=DOMAIN_ID, name="world_sim_test") as s:
        yield s


class Sim:
    """A WorldSim in its own namespace, with a command publisher and an outcome listener."""

    def __init__(self, session: Session, namespace: str, world_file: Path, **parameters):
        settings = {"scene": str(world_file), "time_scale": TIME_SCALE, **parameters}
        self.session = session
        self.ns = namespace
        self.node = session.add(WorldSim(
            context=session.context, namespace=namespace,
            parameter_overrides=[Parameter(k, value=v) for k, v in settings.items()]))
        self.commands = session.node.create_publisher(JointTrajectory,
                                                      f"{namespace}/joint_trajectory",
                                                      COMMAND_QOS)
        self.outcomes = OutcomeListener(session.node, f"{namespace}/world_sim/outcome")
        assert wait_until(lambda: self.node.command_publisher_count() > 0, 10.0)

    def send(self, msg: JointTrajectory, timeout: float = 30.0) -> dict:
        """Publish a command; the outcome it ends with."""
        seen = self.outcomes.count()
        self.commands.publish(msg)
        return self.outcomes.wait_next(seen, timeout)

    def close(self) -> None:
        with self.session.paused():
            self.session.node.destroy_publisher(self.commands)
        self.session.remove(self.node)


def replayed_offline(scene, command: Command, period: float = 1.0 / 50.0) -> OpenLoopExecution:
    """What world_sim (default rate and physics substep) should do, computed here."""
    physics = Physics(scene, simulation_options(MAX_SUBSTEP))
    execution = OpenLoopExecution(physics, scene.initial_state(), command, period)
    execution.run()
    return execution


def straight_move(q0, q1, duration: float, names) -> JointTrajectory:
    return JointTrajectory(joint_names=list(names), points=[
        JointTrajectoryPoint(positions=[float(v) for v in q0], time_from_start=Duration()),
        JointTrajectoryPoint(positions=[float(v) for v in q1],
                             time_from_start=Duration(sec=int(duration),
                                                      nanosec=int(duration % 1 * 1e9)))])


# --------------------------------------------------------------------------------------------
# Commands (no DDS)
# --------------------------------------------------------------------------------------------


def _bad_commands(msg: JointTrajectory, q0: np.ndarray) -> list[tuple[JointTrajectory, str]]:
    cases = []

    def variant(change, field):
        bad = copy.deepcopy(msg)
        change(bad)
        cases.append((bad, field))

    variant(lambda m: m.joint_names.__setitem__(6, "panda_joint8"),
            "joint_trajectory.joint_names")
    variant(lambda m: m.joint_names.__setitem__(6, "panda_joint1"),
            "joint_trajectory.joint_names")
    variant(lambda m: setattr(m.points[5], "time_from_start", m.points[4].time_from_start),
            "joint_trajectory.points[5].time_from_start")
    variant(lambda m: m.points[3].positions.__setitem__(2, float("nan")),
            "joint_trajectory.points[3].positions[panda_joint3]")
    variant(lambda m: m.points[3].velocities.__setitem__(1, float("inf")),
            "joint_trajectory.points[3].velocities[panda_joint2]")
    variant(lambda m: setattr(m.points[2], "positions", list(m.points[2].positions)[:6]),
            "joint_trajectory.points[2].positions")
    variant(lambda m: m.points[4].positions.__setitem__(3, 0.5),       # limit: [-3.07, -0.07]
            "joint_trajectory.points[4].positions[panda_joint4]")
    variant(lambda m: m.points[0].positions.__setitem__(0, q0[0] + 0.3),
            "joint_trajectory.points[0].positions[panda_joint1]")
    variant(lambda m: setattr(m.header.stamp, "sec", 12), "joint_trajectory.header.stamp")
    return cases


def test_command_checks_name_the_field(reference):
    q0 = reference.scene.start_configuration
    robot = reference.scene.robot
    for bad, field in _bad_commands(reference.trajectory, q0):
        with pytest.raises(InputError) as info:
            command_from_msg(bad, robot, q0, start_tolerance=0.01)
        assert info.value.field == field, str(info.value)
    # Any joint order is accepted (reordered to the robot's); a first point later than 0 is
    # reached from the current position, as joint_trajectory_controller does.
    msg = reference.trajectory
    order = list(reversed(range(7)))
    shuffled = JointTrajectory(joint_names=[msg.joint_names[j] for j in order], points=[
        JointTrajectoryPoint(positions=[p.positions[j] for j in order],
                             time_from_start=Duration(sec=p.time_from_start.sec + 1,
                                                      nanosec=p.time_from_start.nanosec))
        for p in msg.points])
    current = q0 + 0.2
    command = command_from_msg(shuffled, robot, current, start_tolerance=0.01)
    assert np.array_equal(command.positions[0], current) and command.times[1] == 1.0
    assert np.allclose(command.positions[1:], reference.command.positions)


# --------------------------------------------------------------------------------------------
# Over DDS
# --------------------------------------------------------------------------------------------


def test_publishes_state_at_its_rates(session, reference):
    # Rates below the defaults (50 and 30 Hz), so a sim that ignored its parameters would
    # publish more than the upper bounds below; low enough that a loaded CI machine keeps up
    # (at 50 Hz one CI run saw 20 Hz).
    sim = Sim(session, "/rates", reference.world_file, rate=20.0, object_rate=8.0)
    joints: list[tuple[float, JointState]] = []
    objects: list[tuple[float, PoseArray]] = []
    subs = [session.node.create_subscription(JointState, "/rates/joint_states",
                                             lambda m: joints.append((time.time(), m)), 10),
            session.node.create_subscription(PoseArray, "/rates/rearrangement_planner/object_poses",
                                             lambda m: objects.append((time.time(), m)),
                                             qos_profile_sensor_data)]
    try:
        assert wait_until(lambda: joints and objects, 10.0)
        joints.clear()
        objects.clear()
        time.sleep(2.5)
        received_joints, received_objects = list(joints), list(objects)
    finally:
        for sub in subs:
            session.node.destroy_subscription(sub)
        sim.close()
    scene = reference.scene
    # Rates on a loaded 2-core machine (rclpy timers skip the periods they miss): at least
    # half the nominal, never more than the nominal.
    assert 0.5 * 50 <= len(received_joints) <= 52, len(received_joints)
    assert 0.5 * 20 <= len(received_objects) <= 22, len(received_objects)
    stamps = [m.header.stamp.sec + m.header.stamp.nanosec * 1e-9 for _, m in received_joints]
    assert all(b > a for a, b in zip(stamps, stamps[1:], strict=False))
    for received, msg in received_joints:
        assert abs(received - (msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9)) < 0.5
        assert list(msg.name) == list(scene.robot.joint_names)
        assert np.array_equal(msg.position, scene.start_configuration)
        assert np.array_equal(msg.velocity, np.zeros(7))
    for _, msg in received_objects:
        assert msg.header.frame_id == FRAME
        assert np.allclose(pose_array_to_objects(msg, scene.object_names, FRAME),
                           scene.object_poses, atol=1e-12)
        assert msg.poses[0].position.z == pytest.approx(0.5 * scene.objects[0].height)


def test_executes_a_plan_open_loop_into_the_goal_region(session, reference):
    sim = Sim(session, "/exec", reference.world_file)
    last: list[JointState] = []
    sub = session.node.create_subscription(JointState, "/exec/joint_states", last.append, 10)
    try:
        t0 = time.monotonic()
        outcome = sim.send(reference.trajectory)
        wall = time.monotonic() - t0
        # Joint states published before the outcome may still be in flight: wait (bounded)
        # for the stream to settle on the last trajectory point.
        end = reference.command.positions[-1]
        deadline = time.monotonic() + 3.0
        while time.monotonic() < deadline and not (
                last and np.allclose(last[-1].position, end, atol=1e-12)):
            time.sleep(0.05)
        final_joints = last[-1]
    finally:
        session.node.destroy_subscription(sub)
        sim.close()
    scene, command = reference.scene, reference.command
    offline = replayed_offline(scene, command)
    assert outcome["status"] == "SUCCEEDED", outcome["message"]
    goal = outcome["goal"]
    assert goal["reached"] and goal["distance_m"] <= goal["radius_m"] == scene.goal.radius
    assert goal["distance_m"] == pytest.approx(
        scene.goal.distance(offline.state.objects[scene.goal_index, :2]), abs=1e-12)
    # The same fixed sequence of controller updates as offline, whatever the wall clock did.
    assert np.allclose(outcome["objects"]["target"]["final"], offline.state.objects[0],
                       atol=1e-12)
    assert outcome["moved_objects"] == ["target"]
    assert outcome["objects"]["target"]["displacement_m"] > 0.1
    assert outcome["invalid"] is None
    assert outcome["executed_s"] == pytest.approx(command.duration)
    assert outcome["time_scale"] == TIME_SCALE
    # Faster than real time, and the arm ends at the last point and reports zero velocity.
    print(f"\n{command.duration:.1f} s trajectory executed in {wall:.2f} s at time scale "
          f"{TIME_SCALE:g}: {outcome['message']}")
    assert wall < command.duration / 2       # a loaded machine may not reach TIME_SCALE
    assert np.allclose(final_joints.position, command.positions[-1], atol=1e-12)
    assert np.array_equal(final_joints.velocity, np.zeros(7))


def test_bad_trajectory_is_rejected_and_the_node_keeps_running(session, reference):
    sim = Sim(session, "/bad", reference.world_file)
    q0 = reference.scene.start_configuration
    try:
        for bad, field in _bad_commands(reference.trajectory, q0)[::4]:   # a few over DDS
            outcome = sim.send(bad, timeout=10.0)
            assert outcome["status"] == "REJECTED" and outcome["field"] == field
            assert field in outcome["message"]
            assert np.array_equal(sim.node.state.q, q0)
        # Still alive: a good (short) command runs.
        q1 = q0 + np.array([0.1, 0, 0, 0, 0, 0, 0])
        outcome = sim.send(straight_move(q0, q1, 1.0, reference.scene.robot.joint_names))
        assert outcome["status"] in ("SUCCEEDED", "GOAL_NOT_REACHED"), outcome["message"]
        assert outcome["executed_s"] == pytest.approx(1.0)
        assert np.allclose(sim.node.state.q, q1)
    finally:
        sim.close()


def test_invalid_step_aborts_and_is_reported(session, reference):
    """Driving the hand into the table: the execution stops at the last valid state and the
    outcome says where and why."""
    sim = Sim(session, "/abort", reference.world_file)
    scene = reference.scene
    q0 = scene.start_configuration
    q1 = q0 + np.array([0, 1.2, 0, 0.6, 0, 0, 0])
    command = straight_move(q0, q1, 2.0, scene.robot.joint_names)
    try:
        outcome = sim.send(command)
        state = sim.node.state
    finally:
        sim.close()
    assert outcome["status"] == "ABORTED"
    assert outcome["invalid"]["reason"] == "arm_table_penetration"
    assert "table" in outcome["invalid"]["detail"] and "table" in outcome["message"]
    t_invalid = outcome["invalid"]["time_from_start_s"]
    assert 0 < t_invalid < 2.0 and outcome["executed_s"] < t_invalid
    assert not outcome["goal"]["reached"]
    expected = q0 + (q1 - q0) * outcome["executed_s"] / 2.0
    assert np.allclose(state.q, expected, atol=1e-9)
    assert Physics(scene).check_state(state) is None        # the last valid state


def test_preemption_goal_updates_empty_trajectory_and_reset(session, reference):
    sim = Sim(session, "/preempt", reference.world_file, time_scale=1.0)
    scene = reference.scene
    q0 = scene.start_configuration
    names = scene.robot.joint_names
    goal_pub = session.node.create_publisher(type(goal_to_pose_stamped([0, 0], FRAME)),
                                             "/preempt/rearrangement_planner/goal", 10)
    try:
        assert wait_until(lambda: goal_pub.get_subscription_count() > 0, 10.0)
        goal_pub.publish(goal_to_pose_stamped([0.3, 0.4], FRAME))        # replaced by the next
        goal_pub.publish(goal_to_pose_stamped([0.45, -0.2], FRAME))
        goal_pub.publish(goal_to_pose_stamped([0.1, 0.1], "map"))         # wrong frame: ignored
        time.sleep(0.3)
        seen = sim.outcomes.count()
        q1 = q0 + np.array([0.3, 0, 0, 0, 0, 0, 0])
        sim.commands.publish(straight_move(q0, q1, 10.0, names))       # 10 s in real time
        time.sleep(0.5)
        q_now = sim.node.state.q.copy()
        assert 0 < q_now[0] < 0.3
        q2 = q_now + np.array([-0.05, 0, 0, 0, 0, 0, 0])
        sim.commands.publish(straight_move(q_now, q2, 10.0, names))    # replaces the first
        preempted = sim.outcomes.wait_next(seen, 5.0)
        assert preempted["status"] == "PREEMPTED" and preempted["executed_s"] < 10.0
        assert preempted["goal"]["position"] == [0.45, -0.2]
        time.sleep(0.3)
        sim.commands.publish(JointTrajectory(joint_names=list(names)))  # empty: stop
        cancelled = sim.outcomes.wait_next(seen + 1, 5.0)
        assert cancelled["status"] == "CANCELLED" and cancelled["executed_s"] < 10.0
        stopped = sim.node.state.q.copy()
        time.sleep(0.3)
        assert np.array_equal(sim.node.state.q, stopped)                # holds
        assert sim.node.executions[-1].outcome["status"] == "CANCELLED"

        reset = session.node.create_client(Trigger, "/preempt/world_sim/reset")
        assert reset.wait_for_service(timeout_sec=10.0)
        future = reset.call_async(Trigger.Request())
        assert wait_until(future.done, 10.0) and future.result().success
        assert np.array_equal(sim.node.state.q, q0)
    finally:
        session.node.destroy_publisher(goal_pub)
        sim.close()


# Perturbations that make a good reference plan fail (chosen for these recorded plans: pose
# noise of 3 cm std dev with seed 8 leaves the easy_push box 0.10 m from the goal, 1 cm with
# seed 1 aborts the default scene's plan on an invalid step). Each plan succeeds unperturbed;
# the plans, made with the 5 cm goal margin, survive five times the friction.
PERTURBATIONS = (("easy_push_1obj", {"pose_noise": 0.03, "seed": 8}),
                 ("default_3obj", {"pose_noise": 0.01, "seed": 1}))


@pytest.mark.parametrize(("name", "parameters"), PERTURBATIONS, ids=lambda v: str(v))
def test_a_good_plan_fails_in_a_perturbed_world_and_the_outcome_says_so(
        session, tmp_path, name, parameters):
    ref = load_reference(name, tmp_path)
    scene, command = ref.scene, ref.command
    unperturbed = replayed_offline(scene, command)
    assert unperturbed.invalid is None
    assert scene.goal.reached(unperturbed.state.objects[scene.goal_index, :2])

    sim = Sim(session, f"/perturbed_{name}", ref.world_file, **parameters)
    try:
        world, offsets = sim.node.world, sim.node.offsets
        outcome = sim.send(ref.trajectory)
    finally:
        sim.close()
    print(f"\n{name} {parameters}: {outcome['message']}")
    assert outcome["status"] in ("GOAL_NOT_REACHED", "ABORTED"), outcome["message"]
    goal = outcome["goal"]
    assert not goal["reached"] and "outside" in outcome["message"]
    # Honest: what the true world's physics gives, whether the step was invalid or not.
    offline = replayed_offline(world, command)
    assert goal["distance_m"] == pytest.approx(
        world.goal.distance(offline.state.objects[world.goal_index, :2]), abs=1e-12)
    if offline.invalid is not None:
        assert outcome["status"] == "ABORTED"
        assert outcome["invalid"]["reason"] == offline.invalid.reason
        assert offline.invalid.reason in outcome["message"]
    else:
        assert outcome["status"] == "GOAL_NOT_REACHED" and outcome["invalid"] is None
        assert goal["distance_m"] > goal["radius_m"]
    assert outcome["pose_noise_m"] == parameters.get("pose_noise", 0.0)
    assert outcome["friction_scale"] == parameters.get("friction_scale", 1.0)
    if "pose_noise" in parameters:
        # The world is off from what is published (and planned on) by the offsets.
        assert np.allclose(world.object_poses - offsets, scene.object_poses, atol=1e-12)
        assert math.hypot(*offsets[0, :2]) > 0.005
    else:
        for true, nominal in zip(world.objects, scene.objects, strict=True):
            assert true.pusher_friction == pytest.approx(
                nominal.pusher_friction * parameters["friction_scale"])
    assert json.dumps(outcome)   # plain JSON


def test_bad_parameters_are_named(session, reference):
    cases = [({"start_configuration": [0.0, 1.0]}, "start_configuration"),
             ({"pose_noise": 0.4, "seed": 3}, "pose_noise"),
             ({"scene": "no_such_scene"}, "no_such_scene"),
             ({"rate": 0.0}, "parameter rate")]
    for parameters, named in cases:
        settings = {"scene": str(reference.world_file), **parameters}
        with pytest.raises(RearrangementError) as info:
            WorldSim(context=session.context, namespace="/broken",
                     parameter_overrides=[Parameter(k, value=v) for k, v in settings.items()])
        assert named in str(info.value)


# --------------------------------------------------------------------------------------------
# make demo (node_demo): world_sim + planner_node, plan, execute, outcome
# --------------------------------------------------------------------------------------------


def test_node_demo_exit_code_is_the_open_loop_outcome(tmp_path, monkeypatch, capsys,
                                                    judge_says):
    """The demo on the fast easy_push scene: exit 0 when the goal object ends in its region,
    1 when a perturbed world (pose noise) makes the same plan miss it, 0 again when the node
    closes the loop there (--replan), 2 for bad arguments."""
    from rearrangement_planner.ros.sim import node_demo

    monkeypatch.setenv("ROS_DOMAIN_ID", str(DOMAIN_ID))
    # Seed 8's plan ends 3 mm from the goal point; a world seen 3 cm off (seed 5) leaves it
    # 8.2 cm away, just outside (with the nominal support fitted to MuJoCo, seed 1's plan
    # reached in all of 30 such worlds).
    common = ["--scene", "easy_push", "--seed", "8", "--time-limit", "20", "--time-scale", "20",
              "--record-dir", str(tmp_path), "--execute-fragile", "--engine", "quasistatic"]
    plot = tmp_path / "demo.png"
    assert node_demo.main([*common, "--plot", str(plot)]) == 0
    out = capsys.readouterr().out
    assert "outcome: execution 1: SUCCEEDED" in out and "inside radius 0.080 m" in out
    assert "time scale 20" in out and f"top view: {plot}" in out
    recording = out.split("recording: ")[1].split()[0]
    assert Path(recording).is_file() and plot.stat().st_size > 10_000

    assert node_demo.main([*common, "--pose-noise", "0.03", "--world-seed", "5"]) == 1
    out = capsys.readouterr().out
    assert "outcome: execution 1: GOAL_NOT_REACHED" in out and "outside radius" in out

    # The closed loop mends that miss: the arm backs out of contact (execution 2), the node
    # plans again from the observed poses, and the goal object ends inside. (Without the
    # watch: at time scale 20 on a loaded machine, when it fires would depend on the load.)
    assert node_demo.main([*common, "--pose-noise", "0.03", "--world-seed", "5",
                           "--replan", "2", "--divergence-bound", "0"]) == 0
    out = capsys.readouterr().out
    assert "re-planning up to 2 times" in out and "goal reached after 1 re-plans" in out
    assert "\n  attempt 2 (" in out and "outcome: execution 1: GOAL_NOT_REACHED" in out
    assert "outcome: execution 3: SUCCEEDED" in out

    # make demo's default world is MuJoCo: the exit code is what happened there.
    code = node_demo.main([*common[:-1], "mujoco"])
    gc.collect()      # a callback task that failed at teardown would print when collected
    captured = capsys.readouterr()
    out = captured.out
    assert "never retrieved" not in captured.err
    assert "mujoco physics" in out and "outcome: execution 1: " in out
    assert code == (0 if "outcome: execution 1: SUCCEEDED" in out else 1)

    # make demo's request (the default scene, seed 1): its plan (robustness 95 %) is not
    # fragile, so the node sends it without --execute-fragile, as make demo runs it.
    demo = ["--scene", "default", "--seed", "1", "--time-limit", "60", "--record-dir",
            str(tmp_path), "--engine", "quasistatic"]
    node_demo.main(demo)
    out = capsys.readouterr().out
    assert "FRAGILE" not in out and "outcome: execution 1: " in out
    makefile = (BAGS.parent / "Makefile").read_text().splitlines()
    defaults = dict(line.replace(" ", "").split("?=") for line in makefile if "?=" in line)
    make_demo = [defaults.get(arg[2:-1], arg) if arg.startswith("$(") else arg
                 for arg in next(line for line in makefile if "node_demo" in line
                                 and not line.startswith("#")).split("node_demo", 1)[1].split()]
    parsed = node_demo.build_parser().parse_args(make_demo)
    assert not parsed.execute_fragile and parsed.live == 8765   # make demo shows the live view

    # A fragile plan (every candidate judged to reach in a quarter of the perturbed 3D
    # worlds, below fragile_below): without --execute-fragile the node does not send it, and
    # the demo ends at the answer rather than waiting for an execution that never comes.
    judge_says(reached=True, share=0.25)
    assert node_demo.main(demo) == 1
    captured = capsys.readouterr()
    assert "FRAGILE" in captured.out and "not executed" in captured.out
    assert "--execute-fragile sends it" in captured.err and "no outcome" not in captured.err
    assert "outcome: execution" not in captured.out

    for bad, named in ((["--time-scale", "0"], "--time-scale"),
                       (["--goal-margin", "0.5"], "--goal-margin"),
                       (["--pose-noise", "-1"], "--pose-noise"),
                       (["--replan", "-1"], "--replan"),
                       (["--scene", "no_such_scene"], "no_such_scene")):
        assert node_demo.main(bad) == 2
        assert named in capsys.readouterr().err
