"""planner_node over DDS (docs/design.md): real rclpy nodes, inputs published like a robot would.

One PlannerNode on the `easy_push` scene runs in a MultiThreadedExecutor thread; a separate
client node publishes the joint state and object poses at 20 Hz, subscribes to the outputs and
calls the services. Isolated from other runs: localhost discovery and a domain id from the pid.
"""

from __future__ import annotations

import copy
import json
import os
import re
import threading
import time
from pathlib import Path

os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
DOMAIN_ID = 10 + os.getpid() % 100

import numpy as np  # noqa: E402
import pytest  # noqa: E402
import rclpy  # noqa: E402
import yaml  # noqa: E402
from action_msgs.msg import GoalStatus  # noqa: E402
from diagnostic_msgs.msg import DiagnosticArray  # noqa: E402
from geometry_msgs.msg import PoseArray, PoseStamped, Quaternion  # noqa: E402
from rclpy.callback_groups import ReentrantCallbackGroup  # noqa: E402
from rclpy.context import Context  # noqa: E402
from rclpy.exceptions import InvalidHandle  # noqa: E402
from rclpy.executors import (  # noqa: E402
    ExternalShutdownException,
    MultiThreadedExecutor,
    ShutdownException,
    SingleThreadedExecutor,
)
from rclpy.node import Node  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402
from rclpy.parameter_client import AsyncParameterClient  # noqa: E402
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy  # noqa: E402
from rclpy.waitable import NumberOfEntities, Waitable  # noqa: E402
from sensor_msgs.msg import JointState  # noqa: E402
from std_srvs.srv import Trigger  # noqa: E402
from trajectory_msgs.msg import JointTrajectory  # noqa: E402
from visualization_msgs.msg import MarkerArray  # noqa: E402

from msg_adapters import (  # noqa: E402
    configuration_to_joint_state,
    diagnostics_to_status,
    goal_to_pose_stamped,
    msg_to_status,
    msg_to_trajectory,
    objects_to_pose_array,
)
from rearrangement_interfaces.action import PlanRearrangement  # noqa: E402
from rearrangement_interfaces.msg import ErrorCode  # noqa: E402
from rearrangement_interfaces.msg import PlannerStatus as PlannerStatusMsg  # noqa: E402
from rearrangement_planner.model.resources import NODE_NAME, config_dir  # noqa: E402
from rearrangement_planner.model.state import State  # noqa: E402
from rearrangement_planner.physics.step import Physics  # noqa: E402
from rearrangement_planner.physics.validation import load_scene  # noqa: E402
from rearrangement_planner.planning.machinery.propagation import replay  # noqa: E402
from rearrangement_planner.planning.requests.request import request_settings  # noqa: E402
from rearrangement_planner.ros import plan_request as plan_request_module  # noqa: E402
from rearrangement_planner.ros import replan  # noqa: E402
from rearrangement_planner.ros.action import RESULT_CHARS  # noqa: E402
from rearrangement_planner.ros.client import action_client  # noqa: E402
from rearrangement_planner.ros.node import (  # noqa: E402
    EXECUTOR_THREADS,
    REPORT_CHARS,
    PlannerNode,
)
from rearrangement_planner.ros.parameters import DEFAULTS, PARAMETERS  # noqa: E402
from rearrangement_planner.ros.sim.replay import wait_until  # noqa: E402

FRAME = "world"
NS = f"/{NODE_NAME}"
SUMMARY = re.compile(r"^plan (\S+): ([A-Z_]+) in ([\d.]+) s, (\d+) iterations, mcap (.+)$")


class Client:
    """The test's side: a node publishing inputs at 20 Hz and recording every output."""

    def __init__(self, context: Context, scene):
        self.node = Node("planner_test_client", context=context)
        self.scene = scene
        names = scene.robot.joint_names
        self.good_joint_state = configuration_to_joint_state(scene.start_configuration, names)
        self.good_objects = objects_to_pose_array(scene.object_poses, FRAME)
        self.joint_state: JointState | None = self.good_joint_state
        self.objects: PoseArray | None = self.good_objects
        n = self.node
        self.joint_pub = n.create_publisher(JointState, "/joint_states", 10)
        self.objects_pub = n.create_publisher(PoseArray, f"{NS}/object_poses", 10)
        self.goal_pub = n.create_publisher(PoseStamped, f"{NS}/goal", 10)
        self.lock = threading.Lock()
        self.statuses: list[tuple[float, object]] = []
        self.last_level = b"\x00"
        self.diagnosed = None
        """The last status on /diagnostics."""
        self.commands: list[JointTrajectory] = []
        self.controller = False
        """Act as the arm's controller: a command moves the published joint state to its end."""
        self.stall = 0
        """Act as a controller that stops halfway for this many commands (the joint state
        goes to the trajectory's middle point, not its end)."""
        self.world: list[PoseArray | None] = []
        """A scripted world: each command with points sets the published object poses to the
        next entry (None: they stop arriving)."""
        self.on_stop: PoseArray | None = None
        """The object poses the next stop (an empty command) publishes."""
        n.create_subscription(PlannerStatusMsg, f"{NS}/status", self._on_status, 50)
        n.create_subscription(DiagnosticArray, "/diagnostics", self._on_diagnostics, 50)
        n.create_subscription(JointTrajectory, "/joint_trajectory", self._on_command, 10)
        self.clients = {name: n.create_client(Trigger, f"{NS}/{name}")
                        for name in ("plan", "cancel", "execute")}
        self.action = action_client(n, PlanRearrangement, f"{NS}/plan_rearrangement")
        self.parameters = AsyncParameterClient(n, NODE_NAME)
        n.create_timer(0.05, self._publish_inputs)

    def _publish_inputs(self) -> None:
        if self.joint_state is not None:
            self.joint_pub.publish(self.joint_state)
        if self.objects is not None:
            self.objects_pub.publish(self.objects)

    def _on_status(self, msg: PlannerStatusMsg) -> None:
        with self.lock:
            self.statuses.append((time.monotonic(), msg_to_status(msg)))

    def _on_diagnostics(self, msg: DiagnosticArray) -> None:
        """The same status for the ROS diagnostics tools; keeps its level."""
        if [s.name for s in msg.status] != [NS]:
            return                                     # another planner node's
        status = diagnostics_to_status(msg, name=NS)
        with self.lock:
            self.last_level = msg.status[0].level
            self.diagnosed = status

    def _on_command(self, msg: JointTrajectory) -> None:
        with self.lock:
            self.commands.append(msg)
            if self.controller and msg.points:
                point = msg.points[len(msg.points) // 2 if self.stall else -1]
                self.stall = max(0, self.stall - 1)
                self.joint_state = JointState(name=list(msg.joint_names),
                                              position=list(point.positions))
            if self.world and msg.points:
                self.objects = self.world.pop(0)
            if not msg.points and self.on_stop is not None:
                self.objects, self.on_stop = self.on_stop, None

    def reset_world(self) -> None:
        """No controller, no scripted world: the good joint state and object poses again."""
        with self.lock:
            self.controller, self.stall, self.world, self.on_stop = False, 0, [], None
            self.joint_state = self.good_joint_state
            self.objects = self.good_objects

    # -- calls ----------------------------------------------------------------------------------

    def call_async(self, service: str):
        client = self.clients[service]
        assert client.wait_for_service(timeout_sec=10.0), f"{NS}/{service} not available"
        return client.call_async(Trigger.Request())

    def call(self, service: str, timeout: float = 30.0) -> Trigger.Response:
        future = self.call_async(service)
        assert wait_until(future.done, timeout), f"{NS}/{service} did not answer in {timeout} s"
        return future.result()

    def send_goal(self, goal: PlanRearrangement.Goal, feedback: list | None = None):
        """Send `goal`; its goal handle once the node has accepted or refused it."""
        assert self.action.wait_for_server(timeout_sec=10.0), f"{NS}/plan_rearrangement"
        future = self.action.send_goal_async(
            goal, feedback_callback=(lambda m: feedback.append((time.monotonic(), m.feedback)))
            if feedback is not None else None)
        assert wait_until(future.done, 10.0), "the goal was neither accepted nor refused"
        return future.result()

    def run_goal(self, goal: PlanRearrangement.Goal, feedback: list | None = None,
                 timeout: float = 60.0):
        """Send `goal` and wait for its (status, result)."""
        handle = self.send_goal(goal, feedback)
        assert handle.accepted
        future = handle.get_result_async()
        assert wait_until(future.done, timeout), f"no result in {timeout} s"
        return future.result().status, future.result().result

    def set(self, **values) -> None:
        """Set planner_node parameters; every set must succeed."""
        assert self.parameters.wait_for_services(timeout_sec=10.0)
        params = [Parameter(k, Parameter.Type.STRING_ARRAY, v) if isinstance(v, list)
                  else Parameter(k, value=v) for k, v in values.items()]
        future = self.parameters.set_parameters(params)
        assert wait_until(future.done, 10.0)
        results = future.result().results
        assert all(r.successful for r in results), [r.reason for r in results]

    def try_set(self, name: str, value) -> tuple[bool, str]:
        future = self.parameters.set_parameters([Parameter(name, value=value)])
        assert wait_until(future.done, 10.0)
        result = future.result().results[0]
        return result.successful, result.reason

    def publish_goal(self, msg: PoseStamped) -> None:
        assert wait_until(lambda: self.goal_pub.get_subscription_count() > 0, 10.0)
        self.goal_pub.publish(msg)

    def statuses_since(self, t0: float) -> list:
        with self.lock:
            return [(t, s) for t, s in self.statuses if t >= t0]

    def wait_status(self, t0: float, predicate, timeout: float = 10.0):
        """The first status received after t0 that satisfies `predicate`."""
        found: list = []

        def check() -> bool:
            found[:] = [s for _, s in self.statuses_since(t0) if predicate(s)]
            return bool(found)

        assert wait_until(check, timeout), \
            f"no such status; got {[s.message for _, s in self.statuses_since(t0)][-5:]}"
        return found[0]

    def wait_inputs_flowing(self) -> None:
        """Let the 20 Hz input publishers reach the planner (state_timeout is generous)."""
        assert wait_until(lambda: self.joint_pub.get_subscription_count() > 0
                          and self.objects_pub.get_subscription_count() > 0, 10.0)
        time.sleep(0.25)


def parse_summary(message: str) -> tuple[str, str, float, int, str]:
    match = SUMMARY.match(message.split("; ")[0])
    assert match, f"summary does not match the contract: {message!r}"
    plan_id, outcome, t, n, mcap = match.groups()
    return plan_id, outcome, float(t), int(n), mcap


def _spin(executor, stop: threading.Event) -> None:
    """`executor.spin()` until `stop`, except that a wait set built while another thread
    destroys one of its entities spins on: rclpy raises InvalidHandle from the QoS event
    handler of a subscription whose destruction was requested (a test's late subscriber, a
    removed node). Under a loaded clean-clone run that killed the client's spin thread once,
    and every later test of the module waited in vain for an answer."""
    while not stop.is_set() and executor.context.ok():
        try:
            executor.spin_once(timeout_sec=0.1)
        except InvalidHandle:
            continue
        except (ShutdownException, ExternalShutdownException):
            return


@pytest.fixture(scope="module")
def ros(tmp_path_factory):
    context = Context()
    rclpy.init(context=context, domain_id=DOMAIN_ID)
    record_dir = tmp_path_factory.mktemp("plans")
    planner = PlannerNode(context=context, parameter_overrides=[
        Parameter("scene", value="easy_push"), Parameter("record_dir", value=str(record_dir)),
        Parameter("time_limit", value=20.0), Parameter("state_timeout", value=5.0),
        # A seed that plans easy_push in well under a second: these tests are about the node,
        # and a loaded CI machine must not turn them into planner-speed tests.
        Parameter("seed", value=1)])
    executor = MultiThreadedExecutor(num_threads=EXECUTOR_THREADS, context=context)
    executor.add_node(planner)
    scene = load_scene("easy_push")
    client = Client(context, scene)
    client_executor = SingleThreadedExecutor(context=context)
    client_executor.add_node(client.node)
    stop = threading.Event()
    threads = [threading.Thread(target=_spin, args=(e, stop), daemon=True)
               for e in (executor, client_executor)]
    for thread in threads:
        thread.start()
    client.wait_inputs_flowing()
    yield {"context": context, "planner": planner, "client": client, "scene": scene,
           "record_dir": record_dir, "executor": executor}
    planner.stop()
    stop.set()
    executor.shutdown()
    client_executor.shutdown()
    # The spin threads leave their wait before the nodes and the context go: a thread still
    # waiting on a destroyed context raises in its wait set.
    for thread in threads:
        thread.join(timeout=5.0)
    planner.destroy_node()
    client.node.destroy_node()
    rclpy.shutdown(context=context)


def check_controller_contract(msg: JointTrajectory, joint_names) -> None:
    """What joint_trajectory_controller checks before it accepts a trajectory."""
    assert list(msg.joint_names) == list(joint_names)
    assert msg.header.stamp.sec == 0 and msg.header.stamp.nanosec == 0
    assert len(msg.points) >= 2
    times = [p.time_from_start.sec + p.time_from_start.nanosec * 1e-9 for p in msg.points]
    assert times[0] == 0.0 and all(b > a for a, b in zip(times, times[1:], strict=False))
    for point in msg.points:
        assert len(point.positions) == 7 and len(point.velocities) == 7
        assert np.all(np.isfinite(point.positions)) and np.all(np.isfinite(point.velocities))
    assert np.allclose(msg.points[-1].velocities, 0.0)


# --------------------------------------------------------------------------------------------


class _DestroyedWhileWaiting(Waitable):
    """An entity whose destruction another thread requests while the executor builds its
    wait set: the first wait set it joins raises InvalidHandle, as rclpy's QoS event handler
    of such a subscription does."""

    def __init__(self):
        super().__init__(ReentrantCallbackGroup())
        self.raised = 0

    def is_ready(self, wait_set) -> bool:
        return False

    def take_data(self):
        return None

    async def execute(self, taken_data) -> None:
        return None

    def get_num_entities(self) -> NumberOfEntities:
        return NumberOfEntities()

    def add_to_wait_set(self, wait_set) -> None:
        if not self.raised:
            self.raised += 1
            raise InvalidHandle("cannot use Destroyable because destruction was requested")


def test_the_spin_threads_survive_entities_destroyed_while_they_wait():
    """The module's spin threads (`_spin`) outlive an entity destroyed while they build a
    wait set (`executor.spin()` itself dies of the InvalidHandle), and a subscriber created
    and destroyed from the test's thread two hundred times while messages flow."""
    context = Context()
    rclpy.init(context=context, domain_id=DOMAIN_ID)
    node = Node("spin_survivor", context=context)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    publisher = node.create_publisher(JointState, "~/ticks", 10)
    node.create_timer(0.001, lambda: publisher.publish(JointState()))
    destroyed = _DestroyedWhileWaiting()
    node.add_waitable(destroyed)
    stop = threading.Event()
    thread = threading.Thread(target=_spin, args=(executor, stop), daemon=True)
    thread.start()
    try:
        assert wait_until(lambda: destroyed.raised, 5.0)
        node.remove_waitable(destroyed)
        for _ in range(200):
            sub = node.create_subscription(JointState, "~/ticks", lambda m: None, 10)
            time.sleep(0.0005)
            node.destroy_subscription(sub)
        received: list[JointState] = []
        node.create_subscription(JointState, "~/ticks", received.append, 10)
        assert wait_until(lambda: received, 5.0)
        assert thread.is_alive()
    finally:
        stop.set()
        executor.shutdown()
        thread.join(timeout=5.0)
        node.destroy_node()
        rclpy.shutdown(context=context)
    assert not thread.is_alive()


def test_parameters_declared_once_with_descriptions_and_yaml_defaults(ros):
    planner = ros["planner"]
    # docs/design.md: the node is `rearrangement_planner` and takes messages in `world` by default
    # (every test here publishes in FRAME = "world" without setting planning_frame).
    assert planner.get_name() == "rearrangement_planner" == NODE_NAME
    assert planner.get_parameter("planning_frame").value == "world" == FRAME
    names = [p.name for p in PARAMETERS]
    assert len(names) == len(set(names))
    for required in ("scene", "robot_description", "object_ids", "goal_object", "goal_radius",
                     "planning_frame", "seed", "time_limit", "planner", "shortcut_time",
                     "max_tool_speed", "record_dir", "record", "auto_execute", "execute_fragile",
                     "plan_on_goal",
                     "state_timeout", "max_iterations", "k_actions", "dt", "max_speed",
                     "max_yaw_rate", "min_duration", "max_duration", "nullspace_speed",
                     "sampler", "goal_bias", "arm_weight", "object_weight", "goal_weight",
                     "progress_period"):
        assert planner.has_parameter(required), required
    for descriptor, spec in zip(planner.describe_parameters(names), PARAMETERS, strict=True):
        assert descriptor.description, spec.name
        numeric = isinstance(spec.default, (int, float)) and not isinstance(spec.default, bool)
        assert bool(descriptor.floating_point_range or descriptor.integer_range) == numeric
        assert descriptor.read_only == (spec.name in ("scene", "robot_description",
                                                      "live_view_port"))
    for setting in request_settings():      # the planners', the pushing model's, the stages'
        assert DEFAULTS[setting.name] == setting.default, setting.name
    data = yaml.safe_load((config_dir() / "planner.yaml").read_text())
    file_defaults = data[NODE_NAME]["ros__parameters"]
    assert file_defaults == {k: list(v) if isinstance(v, tuple) else v
                             for k, v in DEFAULTS.items()}
    client = ros["client"]
    assert client.try_set("scene", "clutter")[0] is False          # read-only
    assert client.try_set("k_actions", 0)[0] is False              # out of range
    assert client.try_set("time_limit", "long")[0] is False        # wrong type


def test_plan_succeeds_publishes_records_and_executes(ros):
    client, scene = ros["client"], ros["scene"]
    client.wait_inputs_flowing()
    t0 = time.monotonic()
    response = client.call("plan")
    answered = time.monotonic() - t0
    assert response.success, response.message
    plan_id, outcome, plan_time, iterations, mcap = parse_summary(response.message)
    assert outcome == "SUCCEEDED" and iterations > 0
    assert Path(mcap).is_file() and Path(mcap).parent == ros["record_dir"]
    assert Path(mcap).name == f"{plan_id}.mcap"
    # The recording, read back with an independent reader, holds every topic and the metadata.
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory

    with open(mcap, "rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        topics = {channel.topic for _, channel, _, _ in reader.iter_decoded_messages()}
        f.seek(0)
        metadata = {m.name: m.metadata for m in make_reader(f).iter_metadata()}
    assert {"/joint_states", f"{NS}/object_poses", f"{NS}/goal", f"{NS}/trajectory",
            f"{NS}/predicted_object_poses", f"{NS}/markers"} <= topics
    assert metadata["rearrangement_plan"]["plan_id"] == plan_id
    assert metadata["rearrangement_plan"]["outcome"] == "SUCCEEDED"
    # Two trees raced (the `trees` default); the parameters recorded say so.
    assert " of 2 (tree seed " in metadata["rearrangement_plan"]["message"]
    assert json.loads(metadata["rearrangement_plan"]["parameters"])["trees"] == 2
    # What the node adds to the pipeline's phases (recording, publishing, answering) stays small.
    # The phases themselves are the benchmark's to time: the first plan's warm-up waits for the
    # race's worker process the node started, seconds on a loaded machine (one CI run: 3.06 s).
    phases = json.loads(metadata["rearrangement_plan"]["statistics"])["phases"]
    pipeline = sum(v for k, v in phases.items() if k.endswith("_s"))
    overhead = answered - pipeline
    print(f"\n~/plan answered {answered:.3f} s after the request; planning {plan_time:.3f} s; "
          f"phases {phases}; the node's own {overhead:.3f} s")
    assert overhead < 3.0

    # A late subscriber still gets the plan (transient local, depth 1).
    received: list[JointTrajectory] = []
    latched = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                         durability=DurabilityPolicy.TRANSIENT_LOCAL)
    sub = client.node.create_subscription(JointTrajectory, f"{NS}/trajectory", received.append,
                                          latched)
    markers: list[MarkerArray] = []
    markers_sub = client.node.create_subscription(MarkerArray, f"{NS}/markers", markers.append,
                                                  latched)
    try:
        assert wait_until(lambda: received and markers, 10.0)
    finally:
        client.node.destroy_subscription(sub)
        client.node.destroy_subscription(markers_sub)
    msg = received[0]
    check_controller_contract(msg, scene.robot.joint_names)
    assert {m.ns for m in markers[0].markers} >= {"ee_path", "object_paths", "goal"}

    # The trajectory, replayed through the physics from the published start, reaches the goal.
    trajectory = msg_to_trajectory(msg)
    start = State(scene.start_configuration, scene.object_poses)
    assert np.allclose(trajectory.positions[0], start.q, atol=1e-9)
    states, problem = replay(Physics(scene), start, trajectory.positions)
    assert problem == ""
    assert scene.goal.reached(states[-1].objects[scene.goal_index, :2])

    final = client.wait_status(t0, lambda s: s.plan_id == plan_id and s.finished)
    assert final.state == "succeeded" and final.outcome == "SUCCEEDED"

    # ~/execute sends that plan to the controller topic.
    with client.lock:
        client.commands.clear()
    executed = client.call("execute", timeout=10.0)
    assert executed.success, executed.message
    assert wait_until(lambda: client.commands, 5.0)
    assert client.commands[0].points[-1].positions == msg.points[-1].positions


def test_the_node_plans_with_the_slice_based_rrt(ros):
    """planner:=slice-rrt (learned oracle, the shipped weights) answers with a plan."""
    client = ros["client"]
    client.wait_inputs_flowing()
    client.set(planner="slice-rrt")
    try:
        response = client.call("plan", timeout=60.0)
    finally:
        client.set(planner="pc-rrt")
    assert response.success, response.message
    plan_id, outcome, _, iterations, mcap = parse_summary(response.message)
    assert outcome == "SUCCEEDED" and iterations > 0
    from mcap.reader import make_reader

    with open(mcap, "rb") as f:
        metadata = {m.name: m.metadata for m in make_reader(f).iter_metadata()}
    parameters = json.loads(metadata["rearrangement_plan"]["parameters"])
    assert parameters["planner"] == "slice-rrt" and parameters["oracle"] == "learned"


def test_another_domain_does_not_see_this_node(ros):
    """Two test runs at once use different domain ids (from the pid): a node on another domain
    finds neither the planner's services nor its topics, while this run's client does."""
    from std_srvs.srv import Trigger

    other = Context()
    rclpy.init(context=other, domain_id=(DOMAIN_ID + 1 - 10) % 100 + 10)
    try:
        stranger = rclpy.create_node("stranger", context=other)
        client = stranger.create_client(Trigger, f"{NS}/plan")
        assert not client.wait_for_service(timeout_sec=1.5)
        assert stranger.count_publishers(f"{NS}/status") == 0
        stranger.destroy_node()
    finally:
        rclpy.shutdown(context=other)
    assert ros["client"].node.count_publishers(f"{NS}/status") >= 1


def test_plan_on_goal_plans_when_a_goal_arrives(ros):
    client, scene = ros["client"], ros["scene"]
    client.wait_inputs_flowing()
    client.set(plan_on_goal=True)
    try:
        t0 = time.monotonic()
        client.publish_goal(goal_to_pose_stamped([2.0, 0.0], FRAME))      # off the table
        invalid = client.wait_status(t0, lambda s: s.finished)
        assert invalid.outcome == "GOAL_INVALID" and "goal.position" in invalid.message
        t1 = time.monotonic()
        client.publish_goal(goal_to_pose_stamped(scene.goal.position, FRAME))
        solved = client.wait_status(t1, lambda s: s.finished, timeout=30.0)
        assert solved.outcome == "SUCCEEDED", solved.message
        assert solved.plan_id != invalid.plan_id
    finally:
        client.set(plan_on_goal=False)


def test_busy_refusal_progress_and_cancel_within_200ms(ros):
    client, scene = ros["client"], ros["scene"]
    client.wait_inputs_flowing()
    # A goal on the table far beyond a few seconds of planning: the plan keeps running.
    client.set(goal_radius=0.01, goal_margin=0.0, time_limit=20.0)
    client.publish_goal(goal_to_pose_stamped([0.93, 0.58], FRAME))
    time.sleep(0.2)
    try:
        t0 = time.monotonic()
        first = client.call_async("plan")
        client.wait_status(t0, lambda s: s.state == "planning" and s.iterations > 0)
        t_refuse = time.monotonic()
        refused = client.call("plan", timeout=5.0)
        # Refused at once, not after the 20 s plan (a wide margin for a loaded machine).
        assert time.monotonic() - t_refuse < 5.0
        assert not refused.success and "busy" in refused.message
        time.sleep(1.2)
        planning = [(t, s) for t, s in client.statuses_since(t0) if s.state == "planning"]
        span = planning[-1][0] - planning[0][0]
        assert span > 0.8 and (len(planning) - 1) / span >= 2.0, (len(planning), span)
        iterations = [s.iterations for _, s in planning]
        assert iterations == sorted(iterations) and iterations[-1] > iterations[0]
        assert not first.done()

        t_cancel = time.monotonic()
        cancelled = client.call("cancel", timeout=5.0)
        cancel_latency = time.monotonic() - t_cancel
        assert cancelled.success, cancelled.message
        assert wait_until(first.done, 10.0)
        answer = first.result()
        assert not answer.success and parse_summary(answer.message)[1] == "CANCELLED"
        print(f"\n~/cancel answered {cancel_latency * 1e3:.0f} ms after the request "
              f"({cancelled.message})")
        # The planner stops within 200 ms of the cancel (the node measures it); the round
        # trip also holds DDS and both executors' scheduling, which a loaded run once
        # stretched to 1.25 s with planning stopped 22 ms after the cancel: a wide margin.
        stopped_ms = re.search(r"planning stopped (\d+) ms after the cancel", cancelled.message)
        assert stopped_ms and int(stopped_ms.group(1)) < 200, cancelled.message
        assert cancel_latency < 5.0
        status = client.wait_status(t_cancel, lambda s: s.finished)
        assert status.state == "cancelled"
    finally:
        client.set(goal_radius=0.0, goal_margin=DEFAULTS["goal_margin"])
        client.publish_goal(goal_to_pose_stamped(scene.goal.position, FRAME))
        time.sleep(0.2)
    assert client.call("cancel", timeout=5.0).success is False   # nothing running


def _tilted(objects: PoseArray) -> PoseArray:
    msg = copy.deepcopy(objects)
    msg.poses[0].orientation = Quaternion(x=float(np.sin(0.15)), w=float(np.cos(0.15)))
    return msg                                               # tilted 0.3 rad about x


def test_bad_inputs_are_reported_and_the_node_keeps_serving(ros):
    client, scene = ros["client"], ros["scene"]
    good_q = list(client.good_joint_state.position)
    names = list(client.good_joint_state.name)
    nan_q = list(good_q)
    nan_q[2] = float("nan")
    bad_cases = [
        ("joint_state", JointState(name=names[:6], position=good_q[:6]), "joint_states.name"),
        ("joint_state", JointState(name=names, position=nan_q),
         "joint_states.position[panda_joint3]"),
        ("objects", PoseArray(header=client.good_objects.header, poses=[]),
         "object_poses.poses"),
        ("objects", objects_to_pose_array(scene.object_poses, "map"),
         "object_poses.header.frame_id"),
        ("objects", _tilted(client.good_objects), "object_poses.poses[0].orientation"),
    ]
    try:
        for kind, msg, field in bad_cases:
            t0 = time.monotonic()
            setattr(client, kind if kind == "objects" else "joint_state", msg)
            status = client.wait_status(t0, lambda s, f=field: f in s.message)
            assert "rejected" in status.message
            client.joint_state, client.objects = client.good_joint_state, client.good_objects
        t0 = time.monotonic()
        client.publish_goal(goal_to_pose_stamped(scene.goal.position, "map"))
        client.wait_status(t0, lambda s: "goal.header.frame_id" in s.message)

        # Objects off the table: the start state is invalid (the object is named).
        off = scene.object_poses
        off[0, 0] = 2.0
        client.objects = objects_to_pose_array(off, FRAME)
        # Wait for the planner to hold them (a fixed 0.3 s once was not enough on a busy run).
        planner = ros["planner"]
        assert wait_until(lambda: planner._objects.get() is not None
                          and planner._objects.get().value[0, 0] == 2.0, 10.0)
        response = client.call("plan")
        assert not response.success
        assert parse_summary(response.message)[1] == "START_INVALID"
        assert "objects[0].pose" in response.message
        client.objects = client.good_objects
        assert wait_until(lambda: planner._objects.get().value[0, 0] != 2.0, 10.0)

        # An invalid parameter combination is named.
        client.set(min_duration=3.0)
        try:
            response = client.call("plan")
        finally:
            client.set(min_duration=0.5)
        assert parse_summary(response.message)[1] == "INVALID_INPUT"
        assert "min_duration" in response.message

        # Stale state: the publishers stop.
        client.set(state_timeout=0.3)
        client.joint_state = None
        time.sleep(0.6)
        response = client.call("plan")
        assert not response.success and parse_summary(response.message)[1] == "NO_STATE"
        assert "joint state" in response.message and "old" in response.message
    finally:
        client.joint_state, client.objects = client.good_joint_state, client.good_objects
        client.set(state_timeout=5.0)
    client.wait_inputs_flowing()
    response = client.call("plan")
    assert response.success, response.message


def test_a_flood_of_varied_bad_inputs_is_one_short_report_a_second(ros):
    """A JointState of 100,000 names is rejected with a report of a few hundred characters, and
    200 different bad messages in a burst give one report per second, not 200."""
    client = ros["client"]
    good = client.good_joint_state
    try:
        client.joint_state = None                  # the test publishes by hand
        t0 = time.monotonic()
        huge = JointState(name=[f"joint_{i:06d}" for i in range(100_000)],
                          position=[0.0] * 100_000)
        rejected = []

        def reported() -> bool:      # a 1.5 MB best-effort message may be dropped: send again
            rejected[:] = [s for _, s in client.statuses_since(t0)
                           if "rejected joint_states" in s.message]
            if not rejected:
                client.joint_pub.publish(huge)
            return bool(rejected)

        assert wait_until(reported, 20.0, period=0.3), "the huge joint state was not reported"
        status = rejected[0]
        assert "joint_states.name" in status.message
        assert len(status.message) <= REPORT_CHARS + 60, len(status.message)
        time.sleep(1.1)
        t1 = time.monotonic()
        for i in range(200):
            client.joint_pub.publish(JointState(name=[*good.name[:6], f"extra_{i}"],
                                                position=[*good.position[:6], float(i)]))

        def burst_reports() -> list:
            return [s for _, s in client.statuses_since(t1)
                    if "rejected joint_states" in s.message]

        # A loaded machine may take seconds to deliver the burst: wait for its first report,
        # then count over the whole window, at most one a second (not one per message).
        assert wait_until(lambda: bool(burst_reports()), 20.0, period=0.1), "burst not reported"
        time.sleep(1.5)
        window = time.monotonic() - t1
        reports = burst_reports()
        assert 1 <= len(reports) <= 2 + window, (len(reports), window)
    finally:
        client.joint_state = good
    client.wait_inputs_flowing()


def test_unwritable_record_dir_keeps_the_plan_and_reports(ros, tmp_path):
    client = ros["client"]
    blocker = tmp_path / "a_file"
    blocker.write_text("not a folder")
    client.set(record_dir=str(blocker / "plans"))   # mkdir fails even for root
    try:
        client.wait_inputs_flowing()
        t0 = time.monotonic()
        response = client.call("plan")
    finally:
        client.set(record_dir=str(ros["record_dir"]))
    assert response.success, response.message
    plan_id, outcome, _, _, mcap = parse_summary(response.message)
    assert outcome == "SUCCEEDED" and mcap.startswith("not recorded:")
    client.wait_status(t0, lambda s: "recording" in s.message and "failed" in s.message)
    final = client.wait_status(t0, lambda s: s.plan_id == plan_id and s.finished)
    assert final.state == "succeeded" and "not recorded" in final.message


def test_unexpected_error_is_internal_and_the_node_keeps_serving(ros, monkeypatch):
    client = ros["client"]

    def broken(*args, **kwargs):
        raise RuntimeError("simulated planner bug")

    monkeypatch.setattr(plan_request_module, "plan_scene", broken)
    client.wait_inputs_flowing()
    response = client.call("plan")
    assert not response.success
    assert parse_summary(response.message)[1] == "INTERNAL"
    assert "simulated planner bug" in response.message
    monkeypatch.undo()
    assert ros["planner"]._worker.is_alive()


def test_fresh_node_without_state_says_no_state(ros):
    """A second planner (own namespace) that has received nothing yet."""
    context, client = ros["context"], ros["client"]
    fresh = PlannerNode(context=context, namespace="fresh", parameter_overrides=[
        Parameter("scene", value="easy_push"), Parameter("record", value=False)])
    ros["executor"].add_node(fresh)
    try:
        calls = {name: client.node.create_client(Trigger, f"/fresh{NS}/{name}")
                 for name in ("plan", "execute")}
        for c in calls.values():
            assert c.wait_for_service(timeout_sec=10.0)
        future = calls["plan"].call_async(Trigger.Request())
        assert wait_until(future.done, 10.0)
        response = future.result()
        assert not response.success
        assert parse_summary(response.message)[1] == "NO_STATE"
        assert "no joint state" in response.message and "/fresh/joint_states" in response.message
        future = calls["execute"].call_async(Trigger.Request())
        assert wait_until(future.done, 10.0)
        assert not future.result().success and "no successful plan" in future.result().message
    finally:
        ros["executor"].remove_node(fresh)
        fresh.destroy_node()


def test_robustness_is_in_the_answer_the_status_and_the_recording(ros):
    """The plan's robustness (docs/design.md) is reported in the ~/plan answer, the final
    ~/status message and the MCAP metadata statistics: the 3D judge's share of perturbed
    worlds, with what its nominal world saw; the model's rollouts' when the judge is off."""
    client = ros["client"]
    client.wait_inputs_flowing()
    client.set(min_robustness=0.1, rollouts=5, judge_worlds=4, both_planners=False)
    try:
        t0 = time.monotonic()
        response = client.call("plan")
        client.set(judge_worlds=0)
        model = client.call("plan")
    finally:
        client.set(min_robustness=0.0, rollouts=10, judge_worlds=8, both_planners=True)
    assert response.success, response.message
    assert re.search(r"; robustness \d+% of 4 perturbed 3D worlds \(nominal: (reached|missed|"
                     r"tipped)[^)]*; (pc-rrt|slice-rrt), \d mends\)", response.message), \
        response.message
    assert re.search(r"; robustness \d+% of 5 perturbed rollouts$", model.message)
    status = client.wait_status(t0, lambda s: s.state == "succeeded")
    assert "robustness" in status.message
    from mcap.reader import make_reader

    with open(parse_summary(response.message)[4], "rb") as f:
        metadata = {m.name: m.metadata for m in make_reader(f).iter_metadata()}
    statistics = json.loads(metadata["rearrangement_plan"]["statistics"])
    assert statistics["robustness"] in (0.0, 0.25, 0.5, 0.75, 1.0)
    assert statistics["judged"]["worlds"] == 4 and statistics["model_robustness"] >= 0.1


def test_a_fragile_plan_is_said_to_be_fragile_and_not_executed_unless_asked(ros, judge_says):
    """A plan whose 3D robustness is below fragile_below is answered, but the answer, the
    status (level WARN, fragile) and the recording say FRAGILE, and auto_execute does not send
    it unless execute_fragile is set."""
    from diagnostic_msgs.msg import DiagnosticStatus
    from mcap.reader import make_reader

    judge_says(reached=True, share=0.25)
    client = ros["client"]
    client.wait_inputs_flowing()
    client.set(min_robustness=1.0, rollouts=5, candidates=1, auto_execute=True, judge_worlds=4,
               both_planners=False)
    try:
        with client.lock:
            client.commands.clear()
        t0 = time.monotonic()
        response = client.call("plan")
        assert response.success, response.message
        assert "; robustness 25% of 4 perturbed 3D worlds (nominal: reached; pc-rrt, 0 mends); " \
            "FRAGILE: it reached the goal in 25% of the perturbed 3D worlds" in response.message
        status = client.wait_status(t0, lambda s: s.state == "succeeded")
        assert status.fragile and "FRAGILE" in status.message
        assert wait_until(lambda: client.last_level == DiagnosticStatus.WARN, 5.0)
        assert client.diagnosed.fragile and client.diagnosed.plan_id == status.plan_id
        time.sleep(0.5)
        with client.lock:
            assert client.commands == []           # not sent to the controller
        with open(parse_summary(response.message)[4], "rb") as f:
            metadata = {m.name: m.metadata for m in make_reader(f).iter_metadata()}
        assert metadata["rearrangement_plan"]["fragile"] == "true"
        assert json.loads(metadata["rearrangement_plan"]["statistics"])["fragile"] is True
        client.set(execute_fragile=True)
        response = client.call("plan")
        assert "FRAGILE" in response.message
        assert wait_until(lambda: client.commands, 5.0)   # asked for: sent
    finally:
        client.set(min_robustness=0.0, rollouts=10, candidates=3, auto_execute=False,
                   execute_fragile=False, judge_worlds=8, both_planners=True)


# --------------------------------------------------------------------------------------------
# The action ~/plan_rearrangement (rearrangement_interfaces/action/PlanRearrangement.action)
# --------------------------------------------------------------------------------------------

ROBUST = ["min_robustness=0.5", "rollouts=5", "candidates=1", "judge_worlds=0"]
"""Settings of a goal that plans easy_push (seed 1) to a success in about a second: the model's
plan, not judged in 3D (the judge has tests of its own, below, and in test/planning)."""


def _far_goal(**fields) -> PlanRearrangement.Goal:
    """A goal no plan reaches in seconds: a 1 cm region in the table's far corner."""
    goal = PlanRearrangement.Goal(use_goal_point=True, goal_radius=0.01,
                                  settings=["goal_margin=0.0", *ROBUST], **fields)
    goal.goal_point.x, goal.goal_point.y = 0.93, 0.58
    return goal


def test_action_plans_with_feedback_and_a_typed_result(ros):
    client, scene = ros["client"], ros["scene"]
    client.wait_inputs_flowing()
    feedback: list = []
    status, result = client.run_goal(PlanRearrangement.Goal(settings=ROBUST), feedback)
    assert status == GoalStatus.STATUS_SUCCEEDED, result.message
    assert result.error_code.val == ErrorCode.SUCCESS
    assert parse_summary(result.message)[1] == "SUCCEEDED"
    check_controller_contract(result.trajectory, scene.robot.joint_names)
    poses = result.predicted_object_poses
    assert len(poses) == len(result.trajectory.points)
    assert all(p.header.frame_id == FRAME and len(p.poses) == 1 for p in poses)
    start, end = poses[0].poses[0].position, poses[-1].poses[-1].position
    assert (start.x, start.y) == pytest.approx(tuple(scene.object_poses[0, :2]), abs=1e-6)
    assert np.hypot(end.x - scene.goal.position[0], end.y - scene.goal.position[1]) \
        < scene.goal.radius
    assert 0.5 <= result.robustness <= 1.0
    assert Path(result.mcap_path).name == f"{result.plan_id}.mcap"
    assert Path(result.mcap_path).is_file()
    # At least one feedback (the first goes out when the goal starts, however quick the plan;
    # it travels on its own topic, so it may be taken after the result).
    assert wait_until(lambda: feedback, 5.0)
    assert {f.phase for _, f in feedback} <= {"waiting", "planning", "recording"}
    assert [f.elapsed for _, f in feedback] == sorted(f.elapsed for _, f in feedback)

    # The recording holds the goal, the feedback and the result with their schemas: both
    # mcap_ros2 (from the schema text) and rclpy (from the generated types) decode them.
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory
    from rclpy.serialization import deserialize_message

    action = f"{NS}/plan_rearrangement"
    with open(result.mcap_path, "rb") as f:
        decoded = [(channel.topic, schema.name, message, decoded)
                   for schema, channel, message, decoded in make_reader(
                       f, decoder_factories=[DecoderFactory()]).iter_decoded_messages(
                       topics=[f"{action}/goal", f"{action}/feedback", f"{action}/result"])]
    kinds = {topic: name for topic, name, _, _ in decoded}
    assert kinds == {f"{action}/{part.lower()}":
                     f"rearrangement_interfaces/action/PlanRearrangement_{part}"
                     for part in ("Goal", "Feedback", "Result")}
    recorded = {topic: (message, value) for topic, _, message, value in decoded}
    message, value = recorded[f"{action}/result"]
    assert value.error_code.val == ErrorCode.SUCCESS and value.plan_id == result.plan_id
    assert value.mcap_path == result.mcap_path and value.message == result.message
    typed = deserialize_message(message.data, PlanRearrangement.Result)
    assert typed.trajectory == result.trajectory and typed.robustness == result.robustness
    goal = deserialize_message(recorded[f"{action}/goal"][0].data, PlanRearrangement.Goal)
    assert list(goal.settings) == ROBUST


def test_action_executes_and_waits_for_the_arm(ros):
    """goal.execute sends the plan to joint_trajectory and answers once joint_states reach its
    end; an arm that never gets there is EXECUTION_FAILED after execution_timeout."""
    client = ros["client"]
    client.wait_inputs_flowing()
    try:
        with client.lock:
            client.controller = True
            client.commands.clear()
        status, result = client.run_goal(PlanRearrangement.Goal(settings=ROBUST, execute=True))
        assert status == GoalStatus.STATUS_SUCCEEDED, result.message
        assert "executed: the arm reached the plan's end" in result.message
        with client.lock:
            assert len(client.commands) == 1
            assert client.commands[0].points[-1].positions == \
                result.trajectory.points[-1].positions
            client.controller = False
            client.joint_state = client.good_joint_state
        client.set(execution_timeout=1.0)
        client.wait_inputs_flowing()
        status, result = client.run_goal(PlanRearrangement.Goal(settings=ROBUST, execute=True))
        assert status == GoalStatus.STATUS_ABORTED
        assert result.error_code.val == ErrorCode.EXECUTION_FAILED, result.message
        assert "did not reach the trajectory's last point within 1.0 s" in result.message
        assert len(result.trajectory.points) > 1             # the plan is still answered
    finally:
        client.set(execution_timeout=0.0)
        with client.lock:
            client.controller = False
            client.joint_state = client.good_joint_state


def test_execute_is_refused_while_a_goal_runs(ros):
    """~/execute sends the last plan, whose first point is its start at t = 0: while a goal's
    plan executes, that would command the arm back to its start mid-motion. It is refused,
    and the goal runs on."""
    client = ros["client"]
    client.wait_inputs_flowing()
    client.set(execution_timeout=3.0)
    try:
        with client.lock:
            client.commands.clear()                   # no controller: the arm never arrives
        handle = client.send_goal(PlanRearrangement.Goal(settings=ROBUST, execute=True))
        assert handle.accepted
        assert wait_until(lambda: client.commands, 30.0)       # the goal's plan was sent
        response = client.call("execute")
        assert not response.success and "refused: plan" in response.message
        assert "is running" in response.message
        future = handle.get_result_async()
        assert wait_until(future.done, 30.0)
        assert future.result().result.error_code.val == ErrorCode.EXECUTION_FAILED
        with client.lock:
            assert len(client.commands) == 1          # ~/execute sent nothing
    finally:
        client.set(execution_timeout=0.0)


def _objects_at(x: float, y: float) -> PoseArray:
    return objects_to_pose_array(np.array([[x, y, 0.0]]), FRAME)


def test_action_closes_the_loop_until_the_goal_is_observed_reached(ros):
    """replan_attempts 2 in a scripted world: the first execution leaves the object 13 cm
    beyond the goal (clear of the arm), the node observes that, plans again from there and
    executes; after the second execution the object is observed in the goal region. (The
    scripted object jumps: seen before the arm's jump it would count as straying, so the watch
    is off here; the next test is about it.)"""
    client, scene = ros["client"], ros["scene"]
    client.wait_inputs_flowing()
    feedback: list = []
    client.set(divergence_bound=0.0)
    try:
        with client.lock:
            client.controller = True
            client.commands.clear()
            client.world = [_objects_at(0.52, -0.23), _objects_at(*scene.goal.position)]
        status, result = client.run_goal(PlanRearrangement.Goal(
            settings=ROBUST, execute=True, replan_attempts=2), feedback)
        assert status == GoalStatus.STATUS_SUCCEEDED, result.message
        plan_id = result.plan_id
        assert (f"attempt 1 ({plan_id}): 'target' observed 0.130 m from the goal"
                in result.message)
        assert f"attempt 2 ({plan_id}-attempt2): 'target' observed 0.000 m" in result.message
        assert result.message.endswith("goal reached after 1 re-plans")
        with client.lock:
            assert len(client.commands) == 2            # no retreat: the arm ended clear
            assert client.commands[1].points[-1].positions == \
                result.trajectory.points[-1].positions     # the answer is the last plan
        assert {2} <= {f.attempt for _, f in feedback}
        assert "observing" in {f.phase for _, f in feedback}
        assert (ros["record_dir"] / f"{plan_id}-attempt1.mcap").is_file()
    finally:
        client.set(divergence_bound=0.05)
        client.reset_world()


def test_the_loop_replans_past_its_attempts_while_it_closes_in(ros):
    """replan_attempts 1, replan_closing 2: the first execution leaves the object 13 cm from
    the goal, the second 11.5 cm (1.5 cm nearer): past its one re-plan the loop goes on, and
    the third execution reaches. With replan_closing 0 it stops after the one re-plan."""
    client, scene = ros["client"], ros["scene"]
    client.wait_inputs_flowing()
    goal = np.asarray(scene.goal.position)
    away = (np.array([0.52, -0.23]) - goal) / np.linalg.norm(np.array([0.52, -0.23]) - goal)

    def at(distance):
        return _objects_at(*(goal + distance * away))

    client.set(divergence_bound=0.0)
    try:
        for closing, code in ((2, ErrorCode.SUCCESS), (0, ErrorCode.GOAL_NOT_REACHED)):
            client.set(replan_closing=closing)
            with client.lock:
                client.controller = True
                client.world = [at(0.13), at(0.115), at(0.0)]
            _, result = client.run_goal(PlanRearrangement.Goal(
                settings=ROBUST, execute=True, replan_attempts=1))
            assert result.error_code.val == code, result.message
            assert "observed 0.115 m from the goal" in result.message
            client.reset_world()
            client.wait_inputs_flowing()
        assert "the goal (radius 0.08 m); not reached after 1 re-plans" in result.message
    finally:
        client.set(divergence_bound=0.05, replan_closing=2)
        client.reset_world()


def test_action_stops_the_arm_when_an_object_strays_and_replans(ros):
    """The arm stalls halfway through the first plan while the object is seen 7 cm off its
    predicted pose (divergence_bound 0.05 m): the node stops the arm with an empty trajectory,
    observes, plans again from there and executes; then the object is seen in the goal."""
    client, scene = ros["client"], ros["scene"]
    client.wait_inputs_flowing()
    try:
        with client.lock:
            client.controller, client.stall = True, 1
            client.commands.clear()
            client.world = [_objects_at(0.52, 0.03), _objects_at(*scene.goal.position)]
        status, result = client.run_goal(PlanRearrangement.Goal(
            settings=ROBUST, execute=True, replan_attempts=1))
        assert status == GoalStatus.STATUS_SUCCEEDED, result.message
        assert (f"attempt 1 ({result.plan_id}): stopped the arm: 'target' strayed 0.070 m from "
                f"its predicted path" in result.message)
        assert "divergence_bound 0.05 m" in result.message
        assert result.message.endswith("goal reached after 1 re-plans")
        with client.lock:      # plan, stop, re-plan (then maybe a stop: the scripted object
            # jumps to the goal at once, which the watch may see before the arm's jump)
            assert [len(c.points) > 0 for c in client.commands][:3] == [True, False, True]
    finally:
        client.reset_world()


def test_action_stops_the_arm_when_an_object_begins_to_tip_and_replans(ros):
    """The arm stalls halfway through the first plan while the object is seen tilted 0.3 rad,
    past max_object_tilt (the watch's divergence bound is off: the tilt alone stops it): the
    node stops the arm before the object falls, observes it upright again, plans again from
    there and executes; then the object is seen in the goal."""
    client, scene = ros["client"], ros["scene"]
    client.wait_inputs_flowing()
    client.set(divergence_bound=0.0)
    try:
        with client.lock:
            client.controller, client.stall = True, 1
            client.commands.clear()
            client.world = [_tilted(_objects_at(0.52, 0.03)), _objects_at(*scene.goal.position)]
            client.on_stop = _objects_at(0.52, 0.03)
        status, result = client.run_goal(PlanRearrangement.Goal(
            settings=ROBUST, execute=True, replan_attempts=1))
        assert status == GoalStatus.STATUS_SUCCEEDED, result.message
        assert (f"attempt 1 ({result.plan_id}): stopped the arm: 'target' began to tip: seen "
                f"tilted 0.300 rad (max_object_tilt 0.05 rad)" in result.message), result.message
        assert result.message.endswith("goal reached after 1 re-plans")
        with client.lock:
            assert [len(c.points) > 0 for c in client.commands][:3] == [True, False, True]
    finally:
        client.set(divergence_bound=0.05)
        client.reset_world()


def test_cancel_stops_the_loop_while_it_waits_for_an_observation(ros, monkeypatch):
    client = ros["client"]
    # The loop would wait 30 s for poses: a cancel answered within 10 s stopped the wait.
    monkeypatch.setattr(replan, "OBSERVE_TIMEOUT", 30.0)
    client.wait_inputs_flowing()
    feedback: list = []
    try:
        with client.lock:
            client.controller = True
            client.world = [None]                # no object poses after the execution
        handle = client.send_goal(PlanRearrangement.Goal(
            settings=ROBUST, execute=True, replan_attempts=2), feedback)
        assert handle.accepted
        assert wait_until(lambda: any(f.phase == "observing" for _, f in feedback), 30.0)
        t_cancel = time.monotonic()
        cancel = handle.cancel_goal_async()
        result_future = handle.get_result_async()
        assert wait_until(result_future.done, 10.0)
        waited = time.monotonic() - t_cancel
        print(f"\nloop result {waited:.2f} s after the cancel")
        assert cancel.done() and waited < 10.0
        assert result_future.result().status == GoalStatus.STATUS_CANCELED
        assert "cancelled while observing" in result_future.result().result.message
    finally:
        client.reset_world()


def test_action_loop_ends_when_no_usable_observation_arrives(ros):
    """After the first execution the object poses come tilted (a toppled object): the node
    rejects them, says why, answers NO_OBSERVATION and keeps serving."""
    client = ros["client"]
    client.wait_inputs_flowing()
    try:
        with client.lock:
            client.controller = True
            client.world = [_tilted(client.good_objects)]
        status, result = client.run_goal(PlanRearrangement.Goal(
            settings=ROBUST, execute=True, replan_attempts=1))
        assert status == GoalStatus.STATUS_ABORTED
        assert result.error_code.val == ErrorCode.NO_OBSERVATION, result.message
        assert "no object poses arrived within 5.5 s after the execution; the last were " \
               "rejected" in result.message and "tilt" in result.message
    finally:
        client.reset_world()
    client.wait_inputs_flowing()
    status, result = client.run_goal(PlanRearrangement.Goal(settings=ROBUST))
    assert status == GoalStatus.STATUS_SUCCEEDED, result.message


def test_action_refuses_a_second_goal_and_cancels_through_the_protocol(ros):
    client = ros["client"]
    client.wait_inputs_flowing()
    feedback: list = []
    handle = client.send_goal(_far_goal(time_limit=20.0), feedback)
    assert handle.accepted
    assert wait_until(lambda: any(f.iterations > 0 for _, f in feedback), 10.0)
    second = client.send_goal(PlanRearrangement.Goal(settings=ROBUST))
    assert not second.accepted                                  # one goal at a time
    refused = client.call("plan", timeout=5.0)                   # nor a ~/plan call
    assert not refused.success and "busy" in refused.message
    time.sleep(1.0)
    span = feedback[-1][0] - feedback[0][0]
    assert span > 0.8 and (len(feedback) - 1) / span >= 2.0, (len(feedback), span)
    t_cancel = time.monotonic()
    cancel = handle.cancel_goal_async()
    assert wait_until(cancel.done, 5.0) and len(cancel.result().goals_canceling) == 1
    result_future = handle.get_result_async()
    assert wait_until(result_future.done, 10.0)
    print(f"\naction result {time.monotonic() - t_cancel:.2f} s after the cancel")
    assert result_future.result().status == GoalStatus.STATUS_CANCELED
    result = result_future.result().result
    assert result.error_code.val == ErrorCode.PREEMPTED
    assert parse_summary(result.message)[1] == "CANCELLED"
    assert len(result.trajectory.points) == 0


@pytest.mark.parametrize(("goal", "code", "words"), [
    (_far_goal(time_limit=0.5), ErrorCode.TIMED_OUT, "TIMEOUT"),
    (PlanRearrangement.Goal(settings=["max_iterations=1", *ROBUST]), ErrorCode.PLANNING_FAILED,
     "no plan within max_iterations 1"),
    (PlanRearrangement.Goal(goal_object="nope"), ErrorCode.GOAL_INVALID, "no object named 'nope'"),
    (PlanRearrangement.Goal(goal_radius=5.0, settings=["trees=2"]), ErrorCode.GOAL_INVALID,
     "goal.radius: 5 m is larger than the table"),
    (PlanRearrangement.Goal(goal_radius=1e-300, settings=["trees=2"]), ErrorCode.GOAL_INVALID,
     "goal.radius: must be between 0.001 and 5 m"),
    (PlanRearrangement.Goal(settings=["k_actions=0"]), ErrorCode.INVALID_INPUT,
     "goal.settings[0]: k_actions must be in"),
    (PlanRearrangement.Goal(settings=["warp=9"]), ErrorCode.INVALID_INPUT, "goal.settings[0]"),
    (PlanRearrangement.Goal(planner="a-star"), ErrorCode.INVALID_INPUT, "goal.planner"),
    (PlanRearrangement.Goal(settings=["x" * 100_000]), ErrorCode.INVALID_INPUT,
     "more characters)"),
    (PlanRearrangement.Goal(settings=["trees=64"]), ErrorCode.INVALID_INPUT,
     "goal.settings[0]: trees 64 is more than the node's max_trees 4"),
    (PlanRearrangement.Goal(time_limit=-1.0), ErrorCode.INVALID_INPUT, "goal.time_limit"),
    (PlanRearrangement.Goal(replan_attempts=21), ErrorCode.INVALID_INPUT,
     "goal.replan_attempts"),
    (PlanRearrangement.Goal(start_object_poses=objects_to_pose_array(np.array([[5.0, 0, 0]]),
                                                                      FRAME)),
     ErrorCode.START_STATE_INVALID, "start invalid"),
    (PlanRearrangement.Goal(start_joint_state=JointState(name=["panda_joint1"], position=[0.0])),
     ErrorCode.INVALID_INPUT, "goal.start_joint_states"),
    (PlanRearrangement.Goal(start_joint_state=JointState(position=[float("nan")] * 7)),
     ErrorCode.INVALID_INPUT, "goal.start_joint_state.name: is empty while the state gives 7"),
], ids=["timed-out", "planning-failed", "goal-invalid", "radius-too-large", "radius-too-small",
        "setting-range", "setting-unknown", "setting-huge", "too-many-trees",
        "planner-unknown", "time-limit", "replan", "start-invalid", "start-joints",
        "start-unnamed"])
def test_action_error_codes(ros, goal, code, words):
    client = ros["client"]
    client.wait_inputs_flowing()
    status, result = client.run_goal(goal)
    assert status == GoalStatus.STATUS_ABORTED
    assert result.error_code.val == code and words in result.message, result.message[:500]
    assert len(result.message) <= RESULT_CHARS + 40        # the message is bounded
    assert ros["planner"]._worker.is_alive()


def test_action_answers_fragile_and_internal(ros, monkeypatch, judge_says):
    """FRAGILE_PLAN: a plan whose 3D judge says it tips an object in the nominal world comes
    back with its trajectory, not executed, never SUCCEEDED; INTERNAL: a defect is an error
    code, and the node keeps serving."""
    client = ros["client"]
    client.wait_inputs_flowing()
    judge_says(reached=False, share=0.25, tipped=("target",))
    with client.lock:
        client.commands.clear()
    status, result = client.run_goal(PlanRearrangement.Goal(
        settings=["min_robustness=1.0", "rollouts=5", "candidates=1", "judge_worlds=4",
                  "mends=0", "both_planners=false"], execute=True))
    assert status == GoalStatus.STATUS_ABORTED
    assert result.error_code.val == ErrorCode.FRAGILE_PLAN, result.message
    assert "FRAGILE: executed in the 3D judge's nominal world it tipped target" in \
        result.message and "not executed" in result.message
    assert result.robustness == 0.25 and len(result.trajectory.points) > 1
    time.sleep(0.3)
    with client.lock:
        assert client.commands == []
    monkeypatch.undo()

    def broken(*args, **kwargs):
        raise RuntimeError("simulated planner bug")

    monkeypatch.setattr(plan_request_module, "plan_scene", broken)
    status, result = client.run_goal(PlanRearrangement.Goal())
    assert result.error_code.val == ErrorCode.INTERNAL and "simulated planner bug" in \
        result.message
    monkeypatch.undo()
    status, result = client.run_goal(PlanRearrangement.Goal(settings=ROBUST))
    assert result.error_code.val == ErrorCode.SUCCESS, result.message


def test_a_burst_of_goals_is_answered_whole(ros):
    """20 goals sent at once: each is accepted or refused (one at a time: one accepted, the
    rest refused while it runs), none left unanswered; the accepted one is cancelled."""
    client = ros["client"]
    client.wait_inputs_flowing()
    assert client.action.wait_for_server(timeout_sec=10.0)
    futures = [client.action.send_goal_async(_far_goal(time_limit=30.0)) for _ in range(20)]
    assert wait_until(lambda: all(f.done() for f in futures), 30.0), \
        f"{sum(not f.done() for f in futures)} of 20 goals got no answer"
    accepted = [f.result() for f in futures if f.result().accepted]
    assert len(accepted) == 1
    cancel = accepted[0].cancel_goal_async()
    assert wait_until(cancel.done, 10.0)
    result = accepted[0].get_result_async()
    assert wait_until(result.done, 20.0)
    assert result.result().result.error_code.val == ErrorCode.PREEMPTED


class _HeldSend:
    """An action client's handle that holds each goal request `hold` s after sending it, so
    that the spinning thread could take the response before the request is registered
    (ros2/rclpy#1123); it counts the goal responses taken meanwhile."""

    def __init__(self, handle, hold: float):
        self._handle, self._hold = handle, hold
        self.holding = False
        self.taken_while_holding = 0

    def __getattr__(self, name):
        return getattr(self._handle, name)

    def __enter__(self):
        return self._handle.__enter__()

    def __exit__(self, *exc):
        return self._handle.__exit__(*exc)

    def send_goal_request(self, request):
        number = self._handle.send_goal_request(request)
        self.holding = True
        time.sleep(self._hold)
        self.holding = False
        return number

    def take_goal_response(self, response_type):
        taken = self._handle.take_goal_response(response_type)
        self.taken_while_holding += self.holding and all(taken)
        return taken


def test_a_goal_response_cannot_overtake_its_request(ros):
    """`action_client` holds its lock while a request is sent and registered, and while the
    executor takes responses. With rclpy's own ActionClient, a response taken before its
    request is registered is dropped ("Ignoring unexpected goal response"), and the goal's
    future never completes; a clean-clone run of node_demo's test failed this way. Here each
    goal request is held 1 s after sending, against a small server on the spinning node: the
    response is never taken in that second, and the goal is answered."""
    from rclpy.action import ActionServer

    node = ros["client"].node

    def execute(handle):
        handle.succeed()
        return PlanRearrangement.Result(message="done")

    server = ActionServer(node, PlanRearrangement, "/overtake_check", execute_callback=execute)
    action = action_client(node, PlanRearrangement, "/overtake_check")
    try:
        assert action.wait_for_server(timeout_sec=10.0)
        held = _HeldSend(action._client_handle, 1.0)
        action._client_handle = held
        sent = action.send_goal_async(PlanRearrangement.Goal())
        assert wait_until(sent.done, 10.0) and sent.result().accepted
        answer = sent.result().get_result_async()
        assert wait_until(answer.done, 10.0)
        assert answer.result().result.message == "done"
        assert held.taken_while_holding == 0
    finally:
        action.destroy()
        server.destroy()
