"""`planner_node`: the ROS 2 node of DESIGN §4, a thin layer around `pipeline.plan_scene`.

Data flow:
- Input topics (`joint_states`, `~/object_poses`, `~/goal`) are converted at the edge by
  msg_adapters and kept as the last good value with its receive time. A bad message is logged
  and reported on `~/status` (field and problem); the last good value stays.
- A plan request (`~/plan`, or `~/goal` with `plan_on_goal`) becomes a `_Job` for the ONE worker
  thread; a request while a job exists is refused at once. The worker reads the parameters,
  snapshots the inputs, builds the planning scene (the configured scene with the received start
  state and goal, checked by `check_scene`), runs `plan_scene`, then publishes the trajectory,
  records the plan to MCAP, publishes markers and the final status, and answers the request.
- A MultiThreadedExecutor with three callback groups keeps the inputs, `~/cancel`, `~/execute`
  and the 4 Hz status timer live while the worker plans: `inputs` (subscriptions), `plan`
  (reentrant, so that a second request is refused instead of queued) and `control`.

Only the worker thread touches the robot model (Pinocchio data is not thread-safe); the other
threads share plain values under `self._lock`.
"""

from __future__ import annotations

import dataclasses
import math
import queue
import threading
import time
import traceback
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import rclpy
from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import PoseArray, PoseStamped
from rclpy.callback_groups import MutuallyExclusiveCallbackGroup, ReentrantCallbackGroup
from rclpy.executors import ExternalShutdownException, MultiThreadedExecutor
from rclpy.logging import get_logger
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import (
    DurabilityPolicy,
    QoSProfile,
    ReliabilityPolicy,
    qos_profile_sensor_data,
)
from sensor_msgs.msg import JointState
from std_srvs.srv import Trigger
from trajectory_msgs.msg import JointTrajectory
from visualization_msgs.msg import MarkerArray

from msg_adapters import (
    joint_state_to_configuration,
    plan_markers,
    pose_array_to_objects,
    pose_stamped_to_goal,
    status_to_diagnostics,
    trajectory_to_msg,
)
from rearrangement_planner.io.plan_record import record_plan
from rearrangement_planner.io.recording import RecordingError
from rearrangement_planner.model.errors import InputError, RearrangementError, SceneError
from rearrangement_planner.model.robot import RobotModel
from rearrangement_planner.model.scene import Goal, Scene
from rearrangement_planner.physics.step import Physics
from rearrangement_planner.physics.validation import check_scene, load_scene
from rearrangement_planner.planning.interface import Outcome, PlannerOptions, PlanResult, Progress
from rearrangement_planner.planning.pipeline import PipelineOptions, PlanOutput, plan_scene
from rearrangement_planner.planning.registry import options_from, planner_spec
from rearrangement_planner.planning.status import PlannerStatus
from rearrangement_planner.planning.trajectory import TimingOptions
from rearrangement_planner.ros.parameters import PARAMETERS

NODE_NAME = "planner_node"
NO_STATE = "NO_STATE"
"""The node's own outcome (DESIGN §4): no joint state / object poses yet, or stale ones."""
EXECUTOR_THREADS = 6
STATUS_RATE = 4.0
"""Hz of the `~/status` progress messages while planning (DESIGN §4 asks for >= 2 Hz)."""
CANCEL_WAIT = 1.0
"""Seconds `~/cancel` waits for the planner to stop before answering."""
INPUT_ERROR_REPEAT = 1.0
"""Seconds before the same input error is published on `~/status` again (flood guard)."""


@dataclass(frozen=True)
class PlanSettings:
    """The planner settings of one plan, checked, from the parameter values."""

    planner: str
    options: PlannerOptions
    timing: TimingOptions
    seed: int
    shortcut_time: float
    shortcut_attempts: int | None


def plan_settings(params: dict[str, Any]) -> PlanSettings:
    """Check and assemble the planner settings; InputError names the parameter at fault
    (the ranges are already enforced by the parameter descriptors)."""
    try:
        planner_spec(params["planner"])
    except ValueError as exc:
        raise InputError("parameter planner", str(exc)) from None
    try:
        options = options_from(params["planner"], params)
        pipeline = PipelineOptions(**{s.name: params[s.name] for s in PipelineOptions.describe()})
    except ValueError as exc:
        raise InputError(f"parameter {str(exc).split()[0]}", str(exc)) from None
    return PlanSettings(params["planner"], options, pipeline.timing, int(params["seed"]),
                        pipeline.shortcut_time, pipeline.shortcut_attempts or None)


# --------------------------------------------------------------------------------------------
# Jobs and inputs
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class _Input:
    """The last good message of one input topic, converted, with its receive time."""

    value: np.ndarray
    msg: Any
    received: float
    """time.monotonic() at reception (the staleness clock, DESIGN §4 `state_timeout`)."""


class _Job:
    """One plan request, from submission to its answer."""

    def __init__(self, plan_id: str, source: str):
        self.plan_id = plan_id
        self.source = source
        self.submitted = time.monotonic()
        self.submitted_ns = time.time_ns()
        self.cancel = threading.Event()
        self.planned = threading.Event()   # planning has stopped (the answer may still follow)
        self.done = threading.Event()      # everything published, recorded and answered
        self.started: float | None = None
        self.outcome = ""
        self.summary = ""


class _Rejected(Exception):
    """A plan that ends before the planner runs (NO_STATE, invalid start or goal ...)."""

    def __init__(self, outcome: str, message: str):
        super().__init__(message)
        self.outcome = outcome
        self.message = message


_FINAL_STATES = {Outcome.SUCCEEDED.value: "succeeded", Outcome.CANCELLED.value: "cancelled"}


# --------------------------------------------------------------------------------------------
# The node
# --------------------------------------------------------------------------------------------


class PlannerNode(Node):
    """The `planner_node` of DESIGN §4. Raises `RearrangementError` when the scene or robot
    (read-only parameters) cannot be loaded."""

    def __init__(self, **kwargs: Any):
        super().__init__(NODE_NAME, **kwargs)
        for spec in PARAMETERS:
            if spec.default == ():
                # An empty list has no ROS type (rclpy would guess a byte array, and rcl's YAML
                # parser drops `[]`): declare the type, then set the empty default.
                declared = self.declare_parameter(spec.name, Parameter.Type.STRING_ARRAY,
                                                  spec.descriptor())
                if declared.type_ is Parameter.Type.NOT_SET:
                    self.set_parameters([Parameter(spec.name, Parameter.Type.STRING_ARRAY, [])])
            else:
                self.declare_parameter(spec.name, spec.default, spec.descriptor())
        self._scene = self._load_scene()
        self._robot = self._scene.robot
        self._lock = threading.Lock()
        self._joint: _Input | None = None
        self._objects: _Input | None = None
        self._goal: _Input | None = None
        self._job: _Job | None = None
        self._progress: Progress | None = None
        self._status = PlannerStatus("idle", f"ready: scene {self._scene.source}")
        self._input_error = ("", 0.0)
        self._last_trajectory: tuple[str, JointTrajectory] | None = None
        self._counter = 0
        self._stopping = False
        self._queue: queue.SimpleQueue[_Job | None] = queue.SimpleQueue()

        inputs = MutuallyExclusiveCallbackGroup()
        plan = ReentrantCallbackGroup()
        control = MutuallyExclusiveCallbackGroup()
        latched = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                             durability=DurabilityPolicy.TRANSIENT_LOCAL)
        self._trajectory_pub = self.create_publisher(JointTrajectory, "~/trajectory", latched)
        self._command_pub = self.create_publisher(
            JointTrajectory, "joint_trajectory",
            QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                       durability=DurabilityPolicy.VOLATILE))
        self._markers_pub = self.create_publisher(MarkerArray, "~/markers", latched)
        self._status_pub = self.create_publisher(DiagnosticArray, "~/status", 10)
        self._joint_sub = self.create_subscription(
            JointState, "joint_states", self._on_joint_state, qos_profile_sensor_data,
            callback_group=inputs)
        self._objects_sub = self.create_subscription(
            PoseArray, "~/object_poses", self._on_object_poses, qos_profile_sensor_data,
            callback_group=inputs)
        self._goal_sub = self.create_subscription(
            PoseStamped, "~/goal", self._on_goal, 10, callback_group=inputs)
        self.create_service(Trigger, "~/plan", self._on_plan, callback_group=plan)
        self.create_service(Trigger, "~/cancel", self._on_cancel, callback_group=control)
        self.create_service(Trigger, "~/execute", self._on_execute, callback_group=control)
        self.create_timer(1.0 / STATUS_RATE, self._on_status_timer, callback_group=control)

        self._worker = threading.Thread(target=self._work, name="planner_worker", daemon=True)
        self._worker.start()
        self._markers_pub.publish(plan_markers(self._scene, None, None, self._planning_frame(),
                                               self._stamp()))
        self._publish_status(self._status)
        self.get_logger().info(
            f"ready: scene {self._scene.source} ({len(self._scene.objects)} objects, goal "
            f"'{self._scene.goal.object}'), robot {self._robot.name}, planning frame "
            f"'{self._planning_frame()}'; call {self.resolve_service_name('~/plan')}")

    def _load_scene(self) -> Scene:
        scene = load_scene(self.get_parameter("scene").value)
        urdf = self.get_parameter("robot_description").value
        if urdf:
            scene = load_scene(scene.source, robot=RobotModel(scene.robot.config, urdf_xml=urdf))
        return scene

    def stop(self) -> None:
        """Cancel a running plan and stop the worker; a waiting ~/plan call then returns."""
        with self._lock:
            self._stopping = True
            if self._job is not None:
                self._job.cancel.set()
        if self._worker.is_alive():
            self._queue.put(None)
            self._worker.join(timeout=10.0)

    def destroy_node(self) -> None:
        self.stop()
        super().destroy_node()

    # -- small helpers --------------------------------------------------------------------------

    def _stamp(self) -> Time:
        return self.get_clock().now().to_msg()

    def _read_parameters(self) -> dict[str, Any]:
        values: dict[str, Any] = {}
        for spec in PARAMETERS:
            value = self.get_parameter(spec.name).value
            values[spec.name] = list(value) if isinstance(spec.default, tuple) else value
        return values

    def _planning_frame(self) -> str:
        return self.get_parameter("planning_frame").value or self._robot.config.base_frame

    def _publish_status(self, status: PlannerStatus) -> None:
        self._status_pub.publish(status_to_diagnostics(status, self._stamp()))

    def _planning_status(self, job: _Job, message: str) -> PlannerStatus:
        p, now = self._progress, time.monotonic()
        elapsed = now - job.started if job.started is not None else 0.0
        if p is None:
            return PlannerStatus("planning", message, plan_id=job.plan_id, elapsed=elapsed)
        return PlannerStatus("planning", message, plan_id=job.plan_id, iterations=p.iterations,
                             tree_size=p.tree_size, best_goal_distance=p.best_goal_distance,
                             elapsed=elapsed)

    def _report(self, message: str) -> None:
        """Log a problem and put it on ~/status (state unchanged); the same message at most
        once per INPUT_ERROR_REPEAT s."""
        now = time.monotonic()
        with self._lock:
            last, when = self._input_error
            if message == last and now - when < INPUT_ERROR_REPEAT:
                return
            self._input_error = (message, now)
            job = self._job
            status = (self._planning_status(job, message) if job is not None
                      else dataclasses.replace(self._status, message=message))
            self._publish_status(status)
        self.get_logger().warning(message)

    # -- inputs ---------------------------------------------------------------------------------

    def _on_joint_state(self, msg: JointState) -> None:
        received = time.monotonic()
        try:
            q = joint_state_to_configuration(msg, self._robot.joint_names)
        except Exception as exc:  # noqa: BLE001 - bad input never stops the node
            self._report(f"rejected joint_states: {_describe(exc)}")
            return
        with self._lock:
            self._joint = _Input(q, msg, received)

    def _on_object_poses(self, msg: PoseArray) -> None:
        received = time.monotonic()
        try:
            ids = self._object_ids()
            poses = pose_array_to_objects(msg, ids, self._planning_frame(),
                                          self.get_parameter("max_object_tilt").value)
            objects = np.empty_like(poses)
            for pose, name in zip(poses, ids, strict=True):
                objects[self._scene.object_index(name)] = pose
        except Exception as exc:  # noqa: BLE001
            self._report(f"rejected object_poses: {_describe(exc)}")
            return
        with self._lock:
            self._objects = _Input(objects, msg, received)

    def _object_ids(self) -> list[str]:
        ids = list(self.get_parameter("object_ids").value)
        names = list(self._scene.object_names)
        if not ids:
            return names
        unknown = [i for i in ids if i not in names]
        missing = [n for n in names if n not in ids]
        if unknown or missing or len(set(ids)) != len(ids):
            raise InputError("parameter object_ids",
                             f"is {ids}; list every scene object once ({', '.join(names)})")
        return ids

    def _on_goal(self, msg: PoseStamped) -> None:
        received = time.monotonic()
        try:
            xy = pose_stamped_to_goal(msg, self._planning_frame())
        except Exception as exc:  # noqa: BLE001
            self._report(f"rejected goal: {_describe(exc)}")
            return
        with self._lock:
            self._goal = _Input(xy, msg, received)
        if self.get_parameter("plan_on_goal").value:
            job = self._submit("~/goal")
            if isinstance(job, str):
                self._report(f"goal received, not planning: {job}")

    # -- requests -------------------------------------------------------------------------------

    def _submit(self, source: str) -> _Job | str:
        """A new job for the worker, or why not (busy)."""
        with self._lock:
            if self._stopping:
                return "refused: the node is shutting down"
            if self._job is not None:
                running = self._job
                return (f"refused: busy with plan {running.plan_id} (requested "
                        f"{time.monotonic() - running.submitted:.1f} s ago); wait for it or "
                        f"call {self.resolve_service_name('~/cancel')}")
            self._counter += 1
            job = _Job(f"{time.strftime('%Y%m%d-%H%M%S')}-{self._counter:03d}", source)
            self._job = job
            self._progress = None
        self._queue.put(job)
        return job

    def _on_plan(self, request: Trigger.Request, response: Trigger.Response
                 ) -> Trigger.Response:
        job = self._submit("~/plan")
        if isinstance(job, str):
            response.success, response.message = False, job
            return response
        job.done.wait()
        response.success = job.outcome == Outcome.SUCCEEDED.value
        response.message = job.summary
        return response

    def _on_cancel(self, request: Trigger.Request, response: Trigger.Response
                   ) -> Trigger.Response:
        with self._lock:
            job = self._job
        if job is None or job.planned.is_set():
            response.success = False
            response.message = ("no plan is running" if job is None else
                                f"plan {job.plan_id} has already stopped planning")
            return response
        t0 = time.monotonic()
        job.cancel.set()
        stopped = job.planned.wait(CANCEL_WAIT)
        waited = time.monotonic() - t0
        response.success = stopped
        response.message = (f"plan {job.plan_id}: planning stopped {waited * 1e3:.0f} ms after "
                            f"the cancel" if stopped else
                            f"plan {job.plan_id}: cancel requested, planning has not stopped "
                            f"after {waited:.1f} s")
        self.get_logger().info(response.message)
        return response

    def _on_execute(self, request: Trigger.Request, response: Trigger.Response
                    ) -> Trigger.Response:
        with self._lock:
            last = self._last_trajectory
        if last is None:
            response.success = False
            response.message = "no successful plan to execute yet; call ~/plan first"
            return response
        plan_id, msg = last
        self._command_pub.publish(msg)
        duration = msg.points[-1].time_from_start
        response.success = True
        response.message = (f"plan {plan_id} sent to {self._command_pub.topic_name} "
                            f"({len(msg.points)} points, "
                            f"{duration.sec + duration.nanosec * 1e-9:.1f} s)")
        self.get_logger().info(response.message)
        return response

    def _on_status_timer(self) -> None:
        with self._lock:
            job = self._job
            if job is not None and job.started is not None:
                self._publish_status(self._planning_status(job, f"plan {job.plan_id}"))

    # -- the worker -----------------------------------------------------------------------------

    def _work(self) -> None:
        while True:
            job = self._queue.get()
            if job is None:
                return
            try:
                self._run(job)
            except Exception as exc:  # noqa: BLE001 - last resort: the worker must survive
                self.get_logger().error(f"plan {job.plan_id}: {traceback.format_exc()}")
                job.outcome = Outcome.INTERNAL.value
                job.summary = (f"plan {job.plan_id}: INTERNAL in 0.00 s, 0 iterations, mcap "
                               f"not recorded: internal error; {type(exc).__name__}: {exc} "
                               f"(traceback in the node log)")
                final = PlannerStatus("failed", job.summary, job.outcome, job.plan_id)
                with self._lock:
                    self._job = None
                    self._status = final
                    self._publish_status(final)
            finally:
                job.planned.set()
                job.done.set()

    def _run(self, job: _Job) -> None:
        """Plan, then publish the trajectory, record, publish markers and the final status."""
        job.started = time.monotonic()
        with self._lock:
            self._publish_status(self._planning_status(
                job, f"plan {job.plan_id} started ({job.source})"))
        params = self._read_parameters()
        frame = params["planning_frame"] or self._robot.config.base_frame
        outcome, message, scene, output, inputs = self._plan(job, params)
        job.planned.set()

        if output is not None and output.trajectory is not None:
            msg = trajectory_to_msg(output.trajectory)
            self._trajectory_pub.publish(msg)
            with self._lock:
                self._last_trajectory = (job.plan_id, msg)
            if params["auto_execute"]:
                self._command_pub.publish(msg)
        recording = self._record(job, output, params, frame, inputs)
        self._markers_pub.publish(self._markers(scene, output, frame))

        r = output.result if output is not None else None    # None: NO_STATE, nothing ran
        plan_time, iterations = (r.plan_time, r.iterations) if r else (0.0, 0)
        summary = (f"plan {job.plan_id}: {outcome} in {plan_time:.2f} s, {iterations} "
                   f"iterations, mcap {recording}")
        if outcome != Outcome.SUCCEEDED.value:
            summary += f"; {message}"
        final = PlannerStatus(_FINAL_STATES.get(outcome, "failed"), summary, outcome,
                              job.plan_id, iterations, r.tree_size if r else 0,
                              r.best_goal_distance if r else math.inf,
                              time.monotonic() - job.started)
        with self._lock:
            self._job = None
            self._status = final
            self._publish_status(final)
        job.outcome, job.summary = outcome, summary
        line = f"{summary} (done {time.monotonic() - job.submitted:.2f} s after the request)"
        if outcome == Outcome.SUCCEEDED.value:
            self.get_logger().info(line)
        else:
            self.get_logger().warning(line)

    def _plan(self, job: _Job, params: dict[str, Any]
              ) -> tuple[str, str, Scene, PlanOutput | None, dict[str, _Input | None]]:
        """Outcome, message, planning scene, plan output (None for NO_STATE) and the inputs
        used. Every failure becomes an outcome; nothing raises."""
        inputs: dict[str, _Input | None] = {}
        scene, output = self._scene, None
        try:
            settings = plan_settings(params)
            inputs = self._snapshot(params["state_timeout"])
            scene, physics = self._planning_scene(inputs, params)
            output = plan_scene(scene, settings.planner, settings.options, seed=settings.seed,
                                physics=physics,
                                cancel=job.cancel, progress=self._on_progress,
                                shortcut_time=settings.shortcut_time, timing=settings.timing,
                                shortcut_attempts=settings.shortcut_attempts)
            return output.result.outcome.value, output.result.message, scene, output, inputs
        except InputError as exc:
            outcome, message = Outcome.INVALID_INPUT.value, str(exc)
        except _Rejected as exc:
            outcome, message = exc.outcome, exc.message
        except Exception as exc:  # noqa: BLE001 - INTERNAL, reported, the node keeps serving
            self.get_logger().error(f"plan {job.plan_id}: {traceback.format_exc()}")
            outcome = Outcome.INTERNAL.value
            message = f"internal error {type(exc).__name__}: {exc} (traceback in the node log)"
        if outcome != NO_STATE:   # a failure the recording can describe
            output = PlanOutput(scene, params["planner"],
                                PlanResult(Outcome(outcome), message, int(params["seed"])))
        return outcome, message, scene, output, inputs

    def _on_progress(self, progress: Progress) -> None:
        with self._lock:
            self._progress = progress

    def _snapshot(self, state_timeout: float) -> dict[str, _Input | None]:
        """The inputs to plan from; NO_STATE when the joint state or object poses are missing
        or older than `state_timeout` s."""
        with self._lock:
            inputs = {"joint_states": self._joint, "object_poses": self._objects,
                      "goal": self._goal}
        now = time.monotonic()
        for key, what, topic in (("joint_states", "joint state", self._joint_sub.topic_name),
                                 ("object_poses", "object poses", self._objects_sub.topic_name)):
            value = inputs[key]
            if value is None:
                raise _Rejected(NO_STATE, f"no {what} received on {topic} yet")
            age = now - value.received
            if state_timeout > 0 and age > state_timeout:
                raise _Rejected(NO_STATE, f"the last {what} on {topic} is {age:.1f} s old "
                                          f"(state_timeout {state_timeout:g} s)")
        return inputs

    def _planning_scene(self, inputs: dict[str, _Input | None],
                        params: dict[str, Any]) -> tuple[Scene, Physics]:
        """The configured scene with the received start state and goal, checked, and the one
        physics the plan runs in (the scene is not re-parsed: only the state and goal change)."""
        joints, objects, received = (inputs["joint_states"], inputs["object_poses"],
                                     inputs["goal"])
        assert joints is not None and objects is not None    # `_snapshot` raised otherwise
        configured = self._scene.goal
        goal = Goal(params["goal_object"] or configured.object,
                    received.value if received is not None else configured.position,
                    params["goal_radius"] if params["goal_radius"] > 0 else configured.radius)
        scene = dataclasses.replace(self._scene.with_start(joints.value, objects.value),
                                    goal=goal)
        try:
            physics = Physics(scene)
            check_scene(scene, physics.world)
        except SceneError as exc:
            raise _Rejected(*_classify(exc, received is not None)) from None
        return scene, physics

    def _record(self, job: _Job, output: PlanOutput | None, params: dict[str, Any], frame: str,
                inputs: dict[str, _Input | None]) -> str:
        """Record the plan; the path written or 'not recorded: <reason>' (a recording failure
        is reported on ~/status and never loses the plan)."""
        if not params["record"]:
            return "not recorded: parameter record is false"
        if output is None:
            return "not recorded: no planning state"

        def msg(key: str) -> Any:
            value = inputs.get(key)
            return value.msg if value is not None else None

        path = Path(params["record_dir"]).expanduser() / f"{job.plan_id}.mcap"
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
            written = record_plan(path, output, plan_id=job.plan_id, parameters=params,
                                  planning_frame=frame, joint_state=msg("joint_states"),
                                  object_poses=msg("object_poses"), goal=msg("goal"),
                                  start_time_ns=job.submitted_ns)
        except (RecordingError, OSError) as exc:
            reason = str(exc)
        except Exception as exc:  # noqa: BLE001 - a recording bug must not lose the plan
            self.get_logger().error(f"plan {job.plan_id}: {traceback.format_exc()}")
            reason = f"internal error {type(exc).__name__}: {exc}"
        else:
            return str(written)
        self._report(f"plan {job.plan_id}: recording to {path} failed: {reason}")
        return f"not recorded: {reason}"

    def _markers(self, scene: Scene, output: PlanOutput | None, frame: str) -> MarkerArray:
        if output is None or output.trajectory is None:
            return plan_markers(scene, None, None, frame, self._stamp())
        robot = scene.robot
        object_paths = np.array([s.objects for s in output.trajectory_states])
        ee_path = np.array([robot.tool_pose(q)[:3, 3] for q in output.trajectory.positions])
        return plan_markers(scene, object_paths, ee_path, frame, self._stamp())


def _describe(exc: Exception) -> str:
    if isinstance(exc, RearrangementError):
        return str(exc)
    return f"internal error {type(exc).__name__}: {exc}"


def _classify(exc: SceneError, goal_received: bool) -> tuple[str, str]:
    """Outcome and message of a planning scene that does not validate: the start state is the
    joint state and object poses, the goal the received goal and the goal parameters."""
    field = exc.field
    if field.startswith("goal"):
        source = {"goal.object": "parameter goal_object", "goal.radius": "parameter goal_radius",
                  "goal.position": "~/goal" if goal_received else "the scene"}
        where = source.get(field.split("[")[0], "the goal")
        return Outcome.GOAL_INVALID.value, f"goal invalid ({where}): {exc}"
    if field.startswith("start_configuration"):
        return Outcome.START_INVALID.value, f"start invalid (joint_states): {exc}"
    if field.startswith("objects"):
        return Outcome.START_INVALID.value, f"start invalid (object_poses): {exc}"
    return Outcome.INVALID_INPUT.value, str(exc)


def main(args: list[str] | None = None) -> int:
    """`planner_node`: init, spin on a MultiThreadedExecutor, clean up (STYLE 11)."""
    rclpy.init(args=args)
    node = None
    executor = MultiThreadedExecutor(num_threads=EXECUTOR_THREADS)
    try:
        node = PlannerNode()
        executor.add_node(node)
        executor.spin()
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except RearrangementError as exc:
        get_logger(NODE_NAME).fatal(f"cannot start: {exc}")
        return 1
    finally:
        if node is not None:
            node.stop()
        executor.shutdown()
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
