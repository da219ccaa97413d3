"""`world_sim`: a simulated arm and table world that executes joint trajectories open loop.

What a real cell would give the planner, simulated with the planner's own quasistatic physics
(`physics.Physics`, docs/design.md "Quasistatic pushing physics"):

- the arm's `joint_states` (sensor_msgs/JointState, stamped, at `rate` Hz) and the object poses
  (geometry_msgs/PoseArray in the planning frame, at `object_rate` Hz, on the topic
  `object_poses_topic`, by default the planner node's `rearrangement_planner/object_poses`);
- a position-controlled arm behind a `joint_trajectory` command topic
  (trajectory_msgs/JointTrajectory), executed **open loop** the way ros2_control's
  joint_trajectory_controller does: the trajectory starts when it arrives (header.stamp zero,
  "start now"), positions are interpolated linearly in time between the points (a first point
  with time_from_start > 0 is reached from the current position), a new trajectory replaces
  the running one, and an empty one stops the arm where it is;
- the outcome of every execution on `~/outcome` (std_msgs/String holding one JSON object,
  transient-local, depth 1) and in the log: the goal object's distance to the goal point and
  whether it is in the goal region, how far every object moved, and whether the physics met an
  invalid state (the arm hitting the table or an obstacle, an object pushed off the table,
  jamming ...). An invalid step aborts the execution: the arm and the objects stay at the last
  valid state, and the outcome says why (status ABORTED);
- `~/reset` (std_srvs/Trigger): stop any execution and put the world back in its initial state.

Open-loop robustness is probed by making the simulated world differ from what the planner
sees (all fixed at start-up from `seed`):
- `pose_noise` / `yaw_noise`: the TRUE initial object poses are the scene's plus a random
  offset (normal, std dev in m and rad), while the published poses keep showing the scene's
  (a constant perception error): the planner plans on the poses it is shown, and the world it
  acts in is elsewhere. Perturbing the published poses instead would only hand the planner a
  different, still exact, problem.
- `friction_scale`: multiplies the support and pusher friction of the simulated objects. In
  the quasistatic model the limit surface's c = m_max / f_max does not depend on the support
  friction, so only the pusher friction (the motion cone: when the arm sticks or slides on an
  object) changes the motion.

Time: one controller update advances the trajectory by 1/`rate` s; with `time_scale` k the sim
runs k times faster than the wall clock (k updates per 1/`rate` s of wall time), so tests and
the demo execute a 30 s trajectory in a few seconds. The updates are a fixed sequence in
trajectory time, so an execution's result does not depend on how the wall clock ticked.

Physics fidelity: within an update the arm passes through every trajectory point it crosses
(the piecewise-linear joint path the planner simulated), and `Physics.step` cuts each move into
substeps of at most `max_substep` of contact-shape motion: 1 mm by default, finer than the
planner's 4 mm, so that the simulated world is converged (its outcome no longer changes with
`rate` or a finer step). The planner's coarser prediction is not always converged: a plan can
reach the goal in the planner's physics and, simulated finely, push the goal object into
another object. world_sim reports that as it happens (status ABORTED, object_object_overlap).

The ROS-free part (`OpenLoopExecution`, the outcome, the perturbed world) is
`execution/open_loop.py`; the command checks are `msg_adapters/command.py`; this module is the
node (`WorldSim`) and `main`.
"""

from __future__ import annotations

import json
import math
import threading
import time
from typing import Any

import numpy as np
import rclpy
from builtin_interfaces.msg import Time
from geometry_msgs.msg import PoseArray, PoseStamped
from rclpy.callback_groups import MutuallyExclusiveCallbackGroup, ReentrantCallbackGroup
from rclpy.exceptions import InvalidParameterTypeException, InvalidParameterValueException
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.logging import get_logger
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy, qos_profile_sensor_data
from sensor_msgs.msg import JointState
from std_msgs.msg import String
from std_srvs.srv import Trigger
from trajectory_msgs.msg import JointTrajectory

from msg_adapters import objects_to_pose_array, pose_stamped_to_goal
from msg_adapters.command import command_from_msg
from rearrangement_planner.execution.mujoco_engine import MujocoExecution
from rearrangement_planner.execution.open_loop import (
    ABORTED,
    CANCELLED,
    PREEMPTED,
    REJECTED,
    SUCCEEDED,
    Execution,
    ExecutionRecord,
    Goal,
    OpenLoopExecution,
    execution_outcome,
    perturbed_world,
)
from rearrangement_planner.model.errors import InputError, RearrangementError
from rearrangement_planner.model.scene import Scene
from rearrangement_planner.model.state import State, wrap_angle
from rearrangement_planner.physics.options import simulation_options
from rearrangement_planner.physics.step import Physics
from rearrangement_planner.physics.validation import load_scene
from rearrangement_planner.ros.parameters import (
    ParameterSpec,
    declare_parameters,
    read_parameters,
)

NODE_NAME = "world_sim"
MAX_SUBSTEP = 0.001
"""Default `max_substep` (m): the simulated world's physics substep (the planner's is 4 mm)."""

_Spec = ParameterSpec
PARAMETERS: tuple[ParameterSpec, ...] = (
    _Spec("scene", "default", "Scene simulated: a shipped scene name (config/scenes) or a scene "
          "YAML path; the planner node's `scene`. Its goal judges the outcome until a goal "
          "arrives on goal_topic.", read_only=True),
    _Spec("start_configuration", (), "Initial arm configuration (rad, planning-joint order), "
          "read at start-up; [] = the scene's.", empty_type="double"),
    _Spec("rate", 50.0, "Controller update and joint_states rate, Hz (each update advances the "
          "trajectory by 1/rate s).", 1.0, 1000.0, read_only=True),
    _Spec("object_rate", 30.0, "Object pose publishing rate, Hz.", 0.1, 1000.0,
          read_only=True),
    _Spec("time_scale", 1.0, "Simulated seconds per wall-clock second of trajectory execution "
          "(> 1: faster than real time).", 0.01, 1000.0),
    _Spec("pose_noise", 0.0, "Std dev of the offset (m, x and y) between each object's true "
          "initial pose and the published one (a constant perception error).", 0.0, 0.5,
          read_only=True),
    _Spec("yaw_noise", 0.0, "Std dev of that offset in yaw, rad.", 0.0, math.pi,
          read_only=True),
    _Spec("friction_scale", 1.0, "Multiplies the support and pusher friction of the simulated "
          "objects (the world then differs from the planner's model).", 0.0, 100.0,
          read_only=True),
    _Spec("seed", 0, "Seed of the pose offsets.", 0, 2**31 - 1, read_only=True),
    _Spec("engine", "quasistatic", "Physics of the simulated world: 'quasistatic' (the planner's "
          "own model, stepped at max_substep) or 'mujoco' (an independent engine: the arm's "
          "real collision meshes, objects as free rigid bodies; docs/design.md).", read_only=True),
    _Spec("max_substep", MAX_SUBSTEP, "Largest motion (m) of any point of the arm's contact "
          "shapes within one physics substep. Finer than the planner's 4 mm so that the "
          "simulated world is converged: its result no longer depends on the step size or on "
          "the rate.", 0.0001, 0.05, read_only=True),
    _Spec("start_tolerance", 0.01, "Largest distance (rad, per joint) between a trajectory's "
          "point at time 0 and the current position; farther is rejected. 0 = no check.",
          0.0, 10.0),
    _Spec("frame_id", "world", "Frame of the published object poses and of accepted goals (the "
          "robot base frame, as the planner's planning_frame); '' = the robot config's base "
          "frame name.", read_only=True),
    _Spec("object_poses_topic", "rearrangement_planner/object_poses", "Topic of the published "
          "object poses (PoseArray, scene object order).", read_only=True),
    _Spec("goal_topic", "rearrangement_planner/goal", "Topic of the goal point (PoseStamped) the "
          "outcome is judged against.", read_only=True),
)



class WorldSim(Node):
    """The `world_sim` node (module docstring). Raises `RearrangementError` when the scene or
    the perturbation parameters give no valid world."""

    def __init__(self, **kwargs: Any):
        super().__init__(NODE_NAME, **kwargs)
        self._lock = threading.Lock()   # held by every callback; `stop` waits for it
        self._stopped = False
        self._execution: Execution | None = None
        try:
            self._setup()
        except BaseException:
            self.destroy_node()
            raise

    def _setup(self) -> None:
        for spec in PARAMETERS:
            try:
                declare_parameters(self, (spec,))
            except (InvalidParameterValueException, InvalidParameterTypeException) as exc:
                raise InputError(f"parameter {spec.name}", f"{exc}; {spec.description}"
                                 ) from None
        p = read_parameters(self, PARAMETERS)
        self._nominal = load_scene(p["scene"])
        robot = self._nominal.robot
        start = None
        if len(p["start_configuration"]):
            start = np.asarray(p["start_configuration"], dtype=float)
            if start.shape != (robot.nq,):
                raise InputError("parameter start_configuration",
                                 f"has {start.size} values; give {robot.nq}, one per joint "
                                 f"{', '.join(robot.joint_names)}, or [] for the scene's")
        self._world, self._offsets = perturbed_world(
            self._nominal, start, p["pose_noise"], p["yaw_noise"], p["friction_scale"],
            int(p["seed"]))
        if p["engine"] not in ("quasistatic", "mujoco"):
            raise InputError("parameter engine", f"is {p['engine']!r}; use 'quasistatic' or "
                                                 f"'mujoco'")
        self._engine = p["engine"]
        self._physics = Physics(self._world, simulation_options(p["max_substep"]))
        self._frame = p["frame_id"] or robot.config.base_frame
        self._period = 1.0 / p["rate"]
        self._heights = np.array([self._world.table.height + 0.5 * o.height
                                  for o in self._world.objects])
        self._settings = {"time_scale": None, "engine": p["engine"],
                          "max_substep_m": p["max_substep"],
                          "pose_noise_m": p["pose_noise"],
                          "yaw_noise_rad": p["yaw_noise"],
                          "friction_scale": p["friction_scale"], "seed": int(p["seed"])}
        goal = self._world.goal
        self._goal = Goal(self._world.goal_index, goal.object, goal.position, goal.radius)
        self._state = self._world.initial_state()
        self._record: ExecutionRecord | None = None
        self._records: list[ExecutionRecord] = []
        self._started = 0.0          # monotonic time the running execution started
        self._time_scale = 1.0       # of the running execution
        self._count = 0

        # Every callback runs under self._lock (see `_guarded`), so the executor may dispatch
        # them concurrently: in a mutually exclusive group rclpy's MultiThreadedExecutor leaves
        # a timer that fires while another callback runs out of its wait set until something
        # else wakes it up, which throttled joint_states to ~14 Hz. The commands and the goals
        # each have a mutually exclusive group of their own: in the reentrant one, two messages
        # that came together ran in two threads and could take the lock out of order, leaving
        # the older goal in force (test_preemption_goal_updates_empty_trajectory_and_reset
        # failed so, once in a full run).
        group = ReentrantCallbackGroup()
        commands, goals = MutuallyExclusiveCallbackGroup(), MutuallyExclusiveCallbackGroup()
        self._joint_pub = self.create_publisher(JointState, "joint_states", 10)
        self._objects_pub = self.create_publisher(PoseArray, p["object_poses_topic"],
                                                  qos_profile_sensor_data)
        self._outcome_pub = self.create_publisher(
            String, "~/outcome", QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                                            durability=DurabilityPolicy.TRANSIENT_LOCAL))
        self._command_sub = self.create_subscription(
            JointTrajectory, "joint_trajectory", self._guarded(self._on_command),
            QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE,
                       durability=DurabilityPolicy.VOLATILE), callback_group=commands)
        self.create_subscription(PoseStamped, p["goal_topic"], self._guarded(self._on_goal), 10,
                                 callback_group=goals)
        self.create_service(Trigger, "~/reset", self._guarded(self._on_reset),
                            callback_group=group)
        self.create_timer(self._period, self._guarded(self._on_update, tick=True),
                          callback_group=group)
        self.create_timer(1.0 / p["object_rate"], self._guarded(self._publish_objects, tick=True),
                          callback_group=group)
        perturbed = ", ".join(f"{o.name} {np.hypot(*d[:2]) * 1000:.1f} mm/{d[2]:+.3f} rad"
                              for o, d in zip(self._world.objects, self._offsets, strict=True))
        self.get_logger().info(
            f"ready: scene {self._world.source} ({len(self._world.objects)} objects), "
            f"{p['rate']:g} Hz joint_states, {p['object_rate']:g} Hz object poses on "
            f"{self._objects_pub.topic_name} in '{self._frame}', commands on "
            f"{self._command_sub.topic_name}; friction_scale {p['friction_scale']:g}; true "
            f"poses off the published ones by: {perturbed}")

    # -- public, for in-process users (demo, tests) ----------------------------------------------

    @property
    def world(self) -> Scene:
        """The simulated (true) world: perturbed initial poses and frictions."""
        return self._world

    @property
    def offsets(self) -> np.ndarray:
        """(M, 3) true initial pose minus published pose of every object."""
        return self._offsets.copy()

    @property
    def state(self) -> State:
        """The current true state (arm, objects)."""
        return self._state

    @property
    def executions(self) -> list[ExecutionRecord]:
        """Every execution so far (finished ones have an outcome)."""
        return list(self._records)

    def stop(self) -> None:
        """Stop updating and publishing (call before destroy_node while an executor may still
        run this node's callbacks): any execution ends where it is, without an outcome."""
        with self._lock:   # waits for a running callback; later ones return at once
            self._stopped = True
            self._execution = None

    def destroy_node(self) -> None:
        self.stop()
        super().destroy_node()

    def command_publisher_count(self) -> int:
        """Publishers matched with the `joint_trajectory` subscription (the controller's
        command topic): wait for one before sending a command."""
        return self._command_sub.get_publisher_count()

    def _guarded(self, callback, tick: bool = False):
        """`callback` run under the node's lock, and not at all once the node is stopped. A
        timer `tick` that finds the lock taken (the previous one still running) is skipped:
        the next one catches up."""
        def run(*args):
            if not self._lock.acquire(blocking=not tick):
                return None
            try:
                if self._stopped:
                    return args[-1] if len(args) == 2 else None   # a service's response
                return callback(*args)
            finally:
                self._lock.release()
        return run

    # -- publishing -------------------------------------------------------------------------------

    def _stamp(self) -> Time:
        return self.get_clock().now().to_msg()

    def _publish_joints(self) -> None:
        execution = self._execution
        velocity = (execution.command.velocity(execution.t) if execution is not None
                    else np.zeros(len(self._state.q)))
        msg = JointState(name=list(self._world.robot.joint_names),
                         position=[float(v) for v in self._state.q],
                         velocity=[float(v) for v in velocity])
        msg.header.stamp = self._stamp()
        self._joint_pub.publish(msg)

    def _publish_objects(self) -> None:
        perceived = self._state.objects - self._offsets
        perceived[:, 2] = wrap_angle(perceived[:, 2])
        self._objects_pub.publish(objects_to_pose_array(perceived, self._frame, self._heights,
                                                        self._stamp()))

    # -- callbacks --------------------------------------------------------------------------------

    def _on_update(self) -> None:
        """The controller update: run the updates the wall clock asks for, publish the state."""
        execution, record = self._execution, self._record
        if execution is not None:
            assert record is not None  # _on_command sets both together
            due = (time.monotonic() - self._started) * self._time_scale
            budget = time.monotonic() + self._period   # never hold the executor longer
            while not execution.done and execution.t + 1e-12 < min(due, execution.command.duration):
                execution.update()
                record.objects.append(execution.state.objects)
                record.tool.append(self._world.robot.tool_pose(execution.state.q)[:2, 3])
                if time.monotonic() > budget:
                    break
            self._state = execution.state
            if execution.done:
                self._finish("")
        self._publish_joints()

    def _on_command(self, msg: JointTrajectory) -> None:
        """A new trajectory replaces the running one; an empty one stops the arm; an unusable
        one is rejected and changes nothing (as joint_trajectory_controller does)."""
        self._count += 1
        if not msg.points:
            if self._execution is not None:
                self._finish(CANCELLED)
            self.get_logger().info(f"execution {self._count}: empty trajectory; the arm holds "
                                   f"its current position")
            return
        try:
            command = command_from_msg(msg, self._world.robot, self._state.q,
                                       self.get_parameter("start_tolerance").value)
        except InputError as exc:
            self._publish_outcome({
                "status": REJECTED, "execution": self._count, "field": exc.field,
                "problem": exc.problem,
                "message": f"execution {self._count}: REJECTED: {exc}"
                           + ("; the running trajectory continues" if self._execution else
                              "; the arm holds")}, error=True)
            return
        if self._execution is not None:
            self._finish(PREEMPTED)
        self._time_scale = float(self.get_parameter("time_scale").value)
        self._execution = (
            MujocoExecution(self._world, self._state, command, self._period)
            if self._engine == "mujoco"
            else OpenLoopExecution(self._physics, self._state, command, self._period))
        self._record = ExecutionRecord(self._count, command, [self._state.objects],
                                       [self._world.robot.tool_pose(self._state.q)[:2, 3]])
        self._records.append(self._record)
        self._started = time.monotonic()
        self.get_logger().info(
            f"execution {self._count}: {len(msg.points)} points, {command.duration:.2f} s of "
            f"trajectory at time_scale {self._time_scale:g}")

    def _on_goal(self, msg: PoseStamped) -> None:
        try:
            position = pose_stamped_to_goal(msg, self._frame)
        except InputError as exc:
            self.get_logger().warning(f"rejected goal: {exc}")
            return
        self._goal = Goal(self._goal.index, self._goal.name, position, self._goal.radius)

    def _on_reset(self, request: Trigger.Request, response: Trigger.Response
                  ) -> Trigger.Response:
        if self._execution is not None:
            self._finish(CANCELLED)
        self._state = self._world.initial_state()
        response.success = True
        response.message = "world reset to its initial state"
        self.get_logger().info(response.message)
        return response

    # -- outcome ----------------------------------------------------------------------------------

    def _finish(self, status: str) -> None:
        """End the running execution with `status` ('' = ran to its end: judge the goal)."""
        execution, record = self._execution, self._record
        # Only called while an execution runs; _on_command sets both together.
        assert execution is not None and record is not None
        self._execution = None
        self._state = execution.state
        wall = time.monotonic() - self._started
        settings = {**self._settings, "time_scale": self._time_scale}
        if execution.invalid is not None and status == "":
            status = ABORTED
        outcome = execution_outcome(status, execution, self._goal, self._world.object_names,
                                    record.number, wall, settings)
        record.outcome = outcome
        self._publish_outcome(outcome, error=status == ABORTED)

    def _publish_outcome(self, outcome: dict[str, Any], error: bool = False) -> None:
        self._outcome_pub.publish(String(data=json.dumps(outcome, sort_keys=True)))
        if error:
            self.get_logger().error(outcome["message"])
        elif outcome["status"] == SUCCEEDED:
            self.get_logger().info(outcome["message"])
        else:
            self.get_logger().warning(outcome["message"])


def main(args: list[str] | None = None) -> int:
    """`world_sim`: init, spin, clean up."""
    rclpy.init(args=args)
    node = None
    executor = SingleThreadedExecutor()
    try:
        node = WorldSim()
        executor.add_node(node)
        executor.spin()
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except RearrangementError as exc:
        get_logger(NODE_NAME).fatal(f"cannot start: {exc}")
        return 1
    finally:
        executor.shutdown()
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
