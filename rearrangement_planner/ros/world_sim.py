"""`world_sim`: a simulated arm and table world that executes joint trajectories open loop.

What a real cell would give the planner, simulated with the planner's own quasistatic physics
(`physics.Physics`, DESIGN §5):

- the arm's `joint_states` (sensor_msgs/JointState, stamped, at `rate` Hz) and the object poses
  (geometry_msgs/PoseArray in the planning frame, at `object_rate` Hz, on the topic
  `object_poses_topic`, by default the planner node's `planner_node/object_poses`);
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

The ROS-free part (command checks, `OpenLoopExecution`, outcome) is at the top; the node
(`WorldSim`) and `main` below it.
"""

from __future__ import annotations

import json
import math
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import rclpy
from builtin_interfaces.msg import Time
from geometry_msgs.msg import PoseArray, PoseStamped
from rclpy.callback_groups import ReentrantCallbackGroup
from rclpy.exceptions import InvalidParameterTypeException, InvalidParameterValueException
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.logging import get_logger
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy, qos_profile_sensor_data
from sensor_msgs.msg import JointState
from std_msgs.msg import String
from std_srvs.srv import Trigger
from trajectory_msgs.msg import JointTrajectory

from msg_adapters import objects_to_pose_array, pose_stamped_to_goal
from rearrangement_planner.model.errors import InputError, RearrangementError, SceneError
from rearrangement_planner.model.robot import RobotModel
from rearrangement_planner.model.scene import Scene
from rearrangement_planner.model.state import State, wrap_angle
from rearrangement_planner.physics.step import Physics, PhysicsOptions
from rearrangement_planner.physics.validation import load_scene, parse_scene
from rearrangement_planner.ros.parameters import ParameterSpec

NODE_NAME = "world_sim"
MAX_SUBSTEP = 0.001
"""Default `max_substep` (m): the simulated world's physics substep (the planner's is 4 mm)."""
MOVED_DISTANCE = 1e-3
"""An object counts as moved when its centre moved more than this (m) ..."""
MOVED_ROTATION = 1e-2
"""... or it turned more than this (rad)."""

# Outcome statuses (the "status" of ~/outcome)
SUCCEEDED = "SUCCEEDED"              # executed to the end, goal object in the goal region
GOAL_NOT_REACHED = "GOAL_NOT_REACHED"  # executed to the end, goal object outside the region
ABORTED = "ABORTED"                  # an invalid physics step stopped the execution
PREEMPTED = "PREEMPTED"              # replaced by a newer trajectory
CANCELLED = "CANCELLED"              # stopped by an empty trajectory or ~/reset
REJECTED = "REJECTED"                # not executed: the command is unusable (field named)


# --------------------------------------------------------------------------------------------
# Commands (ROS-free apart from reading the message's fields)
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Command:
    """A checked controller command: `times` (N,) s, strictly increasing from 0, and
    `positions` (N, n) rad in the robot's planning-joint order; linear interpolation between
    the points (a joint trajectory controller given positions only)."""

    times: np.ndarray
    positions: np.ndarray

    @property
    def duration(self) -> float:
        return float(self.times[-1])

    def sample(self, t: float) -> np.ndarray:
        """Positions at trajectory time t (s), clamped to the first/last point."""
        if t <= 0.0:
            return self.positions[0].copy()
        if t >= self.duration:
            return self.positions[-1].copy()
        i = int(np.searchsorted(self.times, t, side="right")) - 1
        alpha = (t - self.times[i]) / (self.times[i + 1] - self.times[i])
        return (1.0 - alpha) * self.positions[i] + alpha * self.positions[i + 1]

    def velocity(self, t: float) -> np.ndarray:
        """The slope of the segment at time t (rad/s of trajectory time); zero outside."""
        if t < 0.0 or t >= self.duration:
            return np.zeros(self.positions.shape[1])
        i = int(np.searchsorted(self.times, t, side="right")) - 1
        return (self.positions[i + 1] - self.positions[i]) / (self.times[i + 1] - self.times[i])


def _seconds(sec: int, nanosec: int) -> float:
    return sec + nanosec * 1e-9


def command_from_msg(msg: JointTrajectory, robot: RobotModel, current: np.ndarray,
                     start_tolerance: float) -> Command:
    """Check a non-empty controller command against the arm and return it as a `Command`.

    Joints may come in any order but must be exactly the planning joints. Points need finite
    positions for every joint (velocities and accelerations are optional, as for
    joint_trajectory_controller, but finite when given), strictly increasing time_from_start
    and positions within the joint limits. header.stamp must be zero ("start now"). A first
    point at time 0 must be within `start_tolerance` (rad, per joint; 0 = no check) of the
    current position `current`, since the arm would have to jump there; a first point later
    than 0 is reached by interpolating from `current`. Raises InputError naming the field
    (``joint_trajectory.points[3].time_from_start``) and the problem.
    """
    names = list(msg.joint_names)
    expected = list(robot.joint_names)
    stamp = msg.header.stamp
    if stamp.sec != 0 or stamp.nanosec != 0:
        raise InputError("joint_trajectory.header.stamp",
                         f"is {stamp.sec} s {stamp.nanosec} ns; this controller starts "
                         f"trajectories on arrival: send stamp 0 (start now)")
    duplicates = sorted({n for n in names if names.count(n) > 1})
    missing = [n for n in expected if n not in names]
    unknown = [n for n in names if n not in expected]
    if duplicates or missing or unknown:
        problems = []
        if missing:
            problems.append(f"missing {', '.join(missing)}")
        if unknown:
            problems.append(f"unknown {', '.join(unknown)}")
        if duplicates:
            problems.append(f"repeated {', '.join(duplicates)}")
        raise InputError("joint_trajectory.joint_names",
                         f"{'; '.join(problems)}; name each of the arm's joints "
                         f"{', '.join(expected)} once (any order)")
    order = [names.index(n) for n in expected]
    count = len(msg.points)
    times = np.empty(count)
    positions = np.empty((count, len(expected)))
    for i, point in enumerate(msg.points):
        where = f"joint_trajectory.points[{i}]"
        if len(point.positions) != len(names):
            raise InputError(f"{where}.positions",
                             f"has {len(point.positions)} values for {len(names)} joint names; "
                             f"give one position per joint")
        for what in ("velocities", "accelerations"):
            values = getattr(point, what)
            if len(values) not in (0, len(names)):
                raise InputError(f"{where}.{what}",
                                 f"has {len(values)} values for {len(names)} joint names; give "
                                 f"none or one per joint")
            bad = [names[j] for j, v in enumerate(values) if not math.isfinite(v)]
            if bad:
                raise InputError(f"{where}.{what}[{bad[0]}]",
                                 f"is {values[names.index(bad[0])]}; must be a finite number")
        q = np.array([point.positions[j] for j in order], dtype=float)
        for name, value, lo, hi in zip(expected, q, robot.lower, robot.upper, strict=True):
            if not math.isfinite(value):
                raise InputError(f"{where}.positions[{name}]",
                                 f"is {value}; joint positions must be finite numbers (rad)")
            if not lo - 1e-9 <= value <= hi + 1e-9:
                raise InputError(f"{where}.positions[{name}]",
                                 f"is {value:.4f} rad, outside the joint limits "
                                 f"[{lo:.4f}, {hi:.4f}]")
        d = point.time_from_start
        if d.sec < 0 or not 0 <= d.nanosec < 1_000_000_000:
            raise InputError(f"{where}.time_from_start",
                             f"is ({d.sec} s, {d.nanosec} ns); need sec >= 0 and "
                             f"0 <= nanosec < 1e9")
        times[i] = _seconds(d.sec, d.nanosec)
        if i > 0 and times[i] <= times[i - 1]:
            raise InputError(f"{where}.time_from_start",
                             f"is {times[i]:.9f} s, not after point {i - 1} "
                             f"({times[i - 1]:.9f} s); times must strictly increase")
        positions[i] = q
    current = np.asarray(current, dtype=float)
    if times[0] > 0.0:   # reach the first point from where the arm is (joint_trajectory_controller)
        times = np.concatenate([[0.0], times])
        positions = np.vstack([current, positions])
    elif start_tolerance > 0:
        gap = np.abs(positions[0] - current)
        j = int(np.argmax(gap))
        if gap[j] > start_tolerance:
            raise InputError(f"joint_trajectory.points[0].positions[{expected[j]}]",
                             f"is {positions[0, j]:.4f} rad at time 0 but the arm is at "
                             f"{current[j]:.4f} rad ({gap[j]:.4f} rad away, start_tolerance "
                             f"{start_tolerance:g} rad); start the trajectory at the current "
                             f"joint state")
    if len(times) < 2:
        raise InputError("joint_trajectory.points",
                         "has one point at time 0; give a point later than 0 to move to")
    times.setflags(write=False)
    positions.setflags(write=False)
    return Command(times, positions)


# --------------------------------------------------------------------------------------------
# Open-loop execution through the physics (ROS-free)
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class InvalidStep:
    """An invalid physics step met during an execution."""

    reason: str
    detail: str
    time_from_start: float
    """Trajectory time (s) of the configuration the arm could not move to."""


class OpenLoopExecution:
    """One command executed open loop on the simulated world, one controller update at a time.

    `update()` advances the trajectory time by `period` s: the arm moves through every point
    the command crosses in that interval, then to the interpolated position at its end, each
    move stepped through `physics` (the objects follow). The first invalid step ends the
    execution (`invalid`); the state stays the last valid one.
    """

    def __init__(self, physics: Physics, start: State, command: Command, period: float):
        self.physics = physics
        self.command = command
        self.period = float(period)
        self.start = start
        self.state = start
        self.t = 0.0
        self.updates = 0
        self.steps = 0
        self.invalid: InvalidStep | None = None
        self.moved: set[int] = set()

    @property
    def done(self) -> bool:
        return self.invalid is not None or self.t >= self.command.duration

    def update(self) -> None:
        if self.done:
            return
        times = self.command.times
        t_end = min((self.updates + 1) * self.period, self.command.duration)
        crossed = np.flatnonzero((times > self.t) & (times < t_end))
        targets = [(float(times[k]), self.command.positions[k]) for k in crossed]
        targets.append((t_end, self.command.sample(t_end)))
        for t, q in targets:
            result = self.physics.step(self.state, q)
            self.steps += 1
            if not result.valid:
                assert result.reason is not None  # Physics.step gives a reason for every failure
                self.invalid = InvalidStep(result.reason.value, result.detail, t)
                return
            self.state = result.state
            self.moved |= set(result.moved_objects)
            self.t = t
        self.updates += 1

    def run(self) -> None:
        """Execute to the end (or the first invalid step) at once."""
        while not self.done:
            self.update()


@dataclass(frozen=True)
class Goal:
    """What the outcome is judged against: object index and name, goal point (m), radius."""

    index: int
    name: str
    position: np.ndarray
    radius: float


@dataclass
class ExecutionRecord:
    """The path of one execution (one entry per controller update) and its outcome."""

    number: int
    command: Command
    objects: list[np.ndarray] = field(default_factory=list)   # (M, 3) per update
    tool: list[np.ndarray] = field(default_factory=list)      # tool (x, y) per update
    outcome: dict[str, Any] | None = None


def execution_outcome(status: str, execution: OpenLoopExecution, goal: Goal,
                      names: tuple[str, ...], number: int, wall_time: float,
                      settings: dict[str, Any]) -> dict[str, Any]:
    """The ~/outcome JSON object of a finished (or stopped) execution."""
    start, final = execution.start.objects, execution.state.objects
    objects = {}
    for i, name in enumerate(names):
        displacement = float(np.hypot(*(final[i, :2] - start[i, :2])))
        rotation = abs(float(wrap_angle(final[i, 2] - start[i, 2])))
        objects[name] = {"start": [float(v) for v in start[i]],
                         "final": [float(v) for v in final[i]],
                         "displacement_m": displacement, "rotation_rad": rotation,
                         "moved": displacement > MOVED_DISTANCE or rotation > MOVED_ROTATION}
    distance = float(np.hypot(*(final[goal.index, :2] - goal.position)))
    reached = distance <= goal.radius
    if status == "":   # ran to its end
        status = SUCCEEDED if reached else GOAL_NOT_REACHED
    invalid = execution.invalid
    moved = [f"{n} {o['displacement_m']:.3f} m" for n, o in objects.items() if o["moved"]]
    message = (f"execution {number}: {status}: '{goal.name}' is {distance:.3f} m from the goal "
               f"({'inside' if reached else 'outside'} radius {goal.radius:.3f} m) after "
               f"{execution.t:.2f} of {execution.command.duration:.2f} s of trajectory "
               f"({wall_time:.2f} s wall); moved: {', '.join(moved) or 'nothing'}")
    if invalid is not None:
        message += (f"; invalid step at t = {invalid.time_from_start:.2f} s: {invalid.reason}: "
                    f"{invalid.detail} (arm and objects stopped at the last valid state)")
    return {
        "status": status, "execution": number, "message": message,
        "goal": {"object": goal.name, "position": [float(v) for v in goal.position],
                 "radius_m": goal.radius, "distance_m": distance, "reached": reached},
        "objects": objects,
        "moved_objects": [n for n, o in objects.items() if o["moved"]],
        "invalid": None if invalid is None else {
            "reason": invalid.reason, "detail": invalid.detail,
            "time_from_start_s": invalid.time_from_start},
        "duration_s": execution.command.duration, "executed_s": execution.t,
        "wall_time_s": wall_time, "physics_steps": execution.steps,
        "final_configuration": [float(v) for v in execution.state.q],
        **settings,
    }


# --------------------------------------------------------------------------------------------
# The simulated world
# --------------------------------------------------------------------------------------------


def perturbed_world(scene: Scene, start_configuration: np.ndarray | None, pose_noise: float,
                    yaw_noise: float, friction_scale: float, seed: int
                    ) -> tuple[Scene, np.ndarray]:
    """The true world of the simulation and the perception offset.

    Returns the scene whose objects are at their TRUE initial poses (the scene's plus a normal
    offset of std dev `pose_noise` m in x and y and `yaw_noise` rad in yaw, drawn from `seed`)
    with frictions scaled by `friction_scale`, and the offsets (M, 3): published pose = true
    pose - offset. Raises InputError (naming the parameter) when the result is not a valid
    world, e.g. noise that pushes an object into another or off the table.
    """
    offsets = np.zeros((len(scene.objects), 3))
    if pose_noise > 0 or yaw_noise > 0:
        rng = np.random.default_rng(seed)
        offsets = rng.normal(0.0, 1.0, size=offsets.shape) * [pose_noise, pose_noise, yaw_noise]
    data = scene.to_dict()
    if start_configuration is not None:
        data["start_configuration"] = [float(v) for v in start_configuration]
    for entry, offset in zip(data["objects"], offsets, strict=True):
        x, y, yaw = np.asarray(entry["pose"]) + offset
        entry["pose"] = [float(x), float(y), float(wrap_angle(yaw))]
        entry["support_friction"] = float(entry["support_friction"]) * friction_scale
        entry["pusher_friction"] = float(entry["pusher_friction"]) * friction_scale
    try:
        world = parse_scene(data, base_dir=Path(scene.source).parent, name=scene.source,
                            robot=scene.robot)
    except SceneError as exc:
        if exc.field.startswith("start_configuration"):
            raise InputError("parameter start_configuration", str(exc)) from None
        raise InputError("parameters pose_noise/yaw_noise/friction_scale/seed",
                         f"pose_noise {pose_noise:g} m, yaw_noise {yaw_noise:g} rad, "
                         f"friction_scale {friction_scale:g}, seed {seed} give no valid world: "
                         f"{exc}; choose smaller noise or another seed") from None
    return world, offsets


_Spec = ParameterSpec
PARAMETERS: tuple[ParameterSpec, ...] = (
    _Spec("scene", "default", "Scene simulated: a shipped scene name (config/scenes) or a scene "
          "YAML path; the planner node's `scene`. Its goal judges the outcome until a goal "
          "arrives on goal_topic.", read_only=True),
    _Spec("start_configuration", (), "Initial arm configuration (rad, planning-joint order), "
          "read at start-up; [] = the scene's."),
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
    _Spec("max_substep", MAX_SUBSTEP, "Largest motion (m) of any point of the arm's contact "
          "shapes within one physics substep. Finer than the planner's 4 mm so that the "
          "simulated world is converged: its result no longer depends on the step size or on "
          "the rate.", 0.0001, 0.05, read_only=True),
    _Spec("start_tolerance", 0.01, "Largest distance (rad, per joint) between a trajectory's "
          "point at time 0 and the current position; farther is rejected. 0 = no check.",
          0.0, 10.0),
    _Spec("frame_id", "", "Frame of the published object poses and of accepted goals; '' = "
          "the robot base frame.", read_only=True),
    _Spec("object_poses_topic", "planner_node/object_poses", "Topic of the published object "
          "poses (PoseArray, scene object order).", read_only=True),
    _Spec("goal_topic", "planner_node/goal", "Topic of the goal point (PoseStamped) the "
          "outcome is judged against.", read_only=True),
)


def _declare(node: Node, spec: ParameterSpec) -> None:
    if spec.default == ():
        # An empty list has no ROS type (rclpy would guess a byte array): declare the type,
        # then set the empty default (which is why such a parameter cannot be read-only).
        declared = node.declare_parameter(spec.name, Parameter.Type.DOUBLE_ARRAY,
                                          spec.descriptor())
        if declared.type_ is Parameter.Type.NOT_SET:
            node.set_parameters([Parameter(spec.name, Parameter.Type.DOUBLE_ARRAY, [])])
    else:
        node.declare_parameter(spec.name, spec.default, spec.descriptor())


class WorldSim(Node):
    """The `world_sim` node (module docstring). Raises `RearrangementError` when the scene or
    the perturbation parameters give no valid world."""

    def __init__(self, **kwargs: Any):
        super().__init__(NODE_NAME, **kwargs)
        self._lock = threading.Lock()   # held by every callback; `stop` waits for it
        self._stopped = False
        self._execution: OpenLoopExecution | None = None
        try:
            self._setup()
        except BaseException:
            self.destroy_node()
            raise

    def _setup(self) -> None:
        for spec in PARAMETERS:
            try:
                _declare(self, spec)
            except (InvalidParameterValueException, InvalidParameterTypeException) as exc:
                raise InputError(f"parameter {spec.name}", f"{exc}; {spec.description}"
                                 ) from None
        p = {spec.name: self.get_parameter(spec.name).value for spec in PARAMETERS}
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
        self._physics = Physics(self._world, PhysicsOptions(max_substep=p["max_substep"]))
        self._frame = p["frame_id"] or robot.config.base_frame
        self._period = 1.0 / p["rate"]
        self._heights = np.array([self._world.table.height + 0.5 * o.height
                                  for o in self._world.objects])
        self._settings = {"time_scale": None, "max_substep_m": p["max_substep"],
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
        # else wakes it up, which throttled joint_states to ~14 Hz.
        group = ReentrantCallbackGroup()
        self._joint_pub = self.create_publisher(JointState, "joint_states", 10)
        self._objects_pub = self.create_publisher(PoseArray, p["object_poses_topic"],
                                                  qos_profile_sensor_data)
        self._outcome_pub = self.create_publisher(
            String, "~/outcome", QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                                            durability=DurabilityPolicy.TRANSIENT_LOCAL))
        self._command_sub = self.create_subscription(
            JointTrajectory, "joint_trajectory", self._guarded(self._on_command),
            QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE,
                       durability=DurabilityPolicy.VOLATILE), callback_group=group)
        self.create_subscription(PoseStamped, p["goal_topic"], self._guarded(self._on_goal), 10,
                                 callback_group=group)
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
        self._execution = OpenLoopExecution(self._physics, self._state, command, self._period)
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
    """`world_sim`: init, spin, clean up (STYLE 11)."""
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
