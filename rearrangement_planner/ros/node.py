"""`planner_node` (node `rearrangement_planner`): the ROS 2 node of docs/design.md, a thin layer
around `pipeline.plan_scene`.

Data flow:
- Input topics (`joint_states`, `~/object_poses`, `~/goal`) are converted at the edge by
  msg_adapters and kept as the last good value with its receive time. A bad message is logged
  and reported on `~/status` (field and problem); the last good value stays.
- A plan request (`~/plan`, or `~/goal` with `plan_on_goal`) becomes a `Job` for the ONE worker
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
from rearrangement_planner.model.errors import RearrangementError
from rearrangement_planner.model.resources import NODE_NAME
from rearrangement_planner.planning.interface import Outcome, Progress
from rearrangement_planner.planning.warmup import warm_up
from rearrangement_planner.ros.parameters import PARAMETERS, declare_parameters, read_parameters
from rearrangement_planner.ros.plan_request import (
    FINAL_STATES,
    Input,
    Job,
    configured_scene,
    object_ids,
    planning_status,
    record,
    result_markers,
    run_plan,
    summary_line,
)
from rearrangement_planner.ros.status import PlannerStatus

EXECUTOR_THREADS = 6
STATUS_RATE = 4.0
"""Hz of the `~/status` progress messages while planning (docs/design.md asks for >= 2 Hz)."""
CANCEL_WAIT = 1.0
"""Seconds `~/cancel` waits for the planner to stop before answering."""
INPUT_ERROR_REPEAT = 1.0
"""Seconds before the same input error is published on `~/status` again (flood guard)."""


# --------------------------------------------------------------------------------------------
# The node
# --------------------------------------------------------------------------------------------


def _warm_up(node: Node) -> None:
    """Compile the fast core at node start (or load it from the disk cache), not in the first
    plan."""
    seconds = warm_up()
    if seconds > 0.0:
        node.get_logger().info(f"physics core compiled or loaded in {seconds:.1f} s")


class PlannerNode(Node):
    """The planner node of docs/design.md (`rearrangement_planner`). Raises `RearrangementError`
    when the scene or robot (read-only parameters) cannot be loaded."""

    def __init__(self, **kwargs: Any):
        super().__init__(NODE_NAME, **kwargs)
        declare_parameters(self, PARAMETERS)
        self._scene = configured_scene(self.get_parameter("scene").value,
                                       self.get_parameter("robot_description").value)
        self._robot = self._scene.robot
        self._lock = threading.Lock()
        self._joint: Input | None = None
        self._objects: Input | None = None
        self._goal: Input | None = None
        self._job: Job | None = None
        self._progress: Progress | None = None
        self._status = PlannerStatus("idle", f"ready: scene {self._scene.source}")
        self._input_error = ("", 0.0)
        self._last_trajectory: tuple[str, JointTrajectory] | None = None
        self._counter = 0
        self._stopping = False
        self._queue: queue.SimpleQueue[Job | None] = queue.SimpleQueue()

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
        _warm_up(self)
        self.get_logger().info(
            f"ready: scene {self._scene.source} ({len(self._scene.objects)} objects, goal "
            f"'{self._scene.goal.object}'), robot {self._robot.name}, planning frame "
            f"'{self._planning_frame()}'; call {self.resolve_service_name('~/plan')}")

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

    def _planning_frame(self) -> str:
        return self.get_parameter("planning_frame").value or self._robot.config.base_frame

    def _publish_status(self, status: PlannerStatus) -> None:
        self._status_pub.publish(status_to_diagnostics(status, self._stamp()))

    def _planning_status(self, job: Job, message: str) -> PlannerStatus:
        return planning_status(job, self._progress, message)

    def last_inputs(self) -> dict[str, Any]:
        """The last accepted message of each input ('joint_states', 'object_poses', 'goal';
        None before the first): what the next plan starts from."""
        with self._lock:
            latest = {"joint_states": self._joint, "object_poses": self._objects,
                      "goal": self._goal}
        return {k: (v.msg if v is not None else None) for k, v in latest.items()}

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
            self._joint = Input(q, msg, received)

    def _on_object_poses(self, msg: PoseArray) -> None:
        received = time.monotonic()
        try:
            ids = object_ids(list(self.get_parameter("object_ids").value), self._scene)
            poses = pose_array_to_objects(msg, ids, self._planning_frame(),
                                          self.get_parameter("max_object_tilt").value)
            objects = np.empty_like(poses)
            for pose, name in zip(poses, ids, strict=True):
                objects[self._scene.object_index(name)] = pose
        except Exception as exc:  # noqa: BLE001
            self._report(f"rejected object_poses: {_describe(exc)}")
            return
        with self._lock:
            self._objects = Input(objects, msg, received)

    def _on_goal(self, msg: PoseStamped) -> None:
        received = time.monotonic()
        try:
            xy = pose_stamped_to_goal(msg, self._planning_frame())
        except Exception as exc:  # noqa: BLE001
            self._report(f"rejected goal: {_describe(exc)}")
            return
        with self._lock:
            self._goal = Input(xy, msg, received)
        if self.get_parameter("plan_on_goal").value:
            job = self._submit("~/goal")
            if isinstance(job, str):
                self._report(f"goal received, not planning: {job}")

    # -- requests -------------------------------------------------------------------------------

    def _submit(self, source: str) -> Job | str:
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
            job = Job(f"{time.strftime('%Y%m%d-%H%M%S')}-{self._counter:03d}", source)
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

    def _run(self, job: Job) -> None:
        """Plan, then publish the trajectory, record, publish markers and the final status."""
        job.started = time.monotonic()
        with self._lock:
            self._publish_status(self._planning_status(
                job, f"plan {job.plan_id} started ({job.source})"))
        params = read_parameters(self, PARAMETERS)
        frame = params["planning_frame"] or self._robot.config.base_frame
        with self._lock:
            latest = {"joint_states": self._joint, "object_poses": self._objects,
                      "goal": self._goal}
        topics = {"joint_states": self._joint_sub.topic_name,
                  "object_poses": self._objects_sub.topic_name}
        outcome, message, scene, output, inputs = run_plan(
            job, params, self._scene, latest, topics, self._on_progress, self.get_logger())
        job.planned.set()

        if output is not None and output.trajectory is not None:
            msg = trajectory_to_msg(output.trajectory)
            self._trajectory_pub.publish(msg)
            with self._lock:
                self._last_trajectory = (job.plan_id, msg)
            if params["auto_execute"] and (not output.fragile or params["execute_fragile"]):
                self._command_pub.publish(msg)
        recording, failure = record(job, output, params, frame, inputs, self.get_logger())
        if failure is not None:
            self._report(failure)
        self._markers_pub.publish(result_markers(scene, output, frame, self._stamp()))

        r = output.result if output is not None else None    # None: NO_STATE, nothing ran
        summary = summary_line(job.plan_id, outcome, message, output, recording,
                               params["rollouts"])
        final = PlannerStatus(FINAL_STATES.get(outcome, "failed"), summary, outcome,
                              job.plan_id, r.iterations if r else 0, r.tree_size if r else 0,
                              r.best_goal_distance if r else math.inf,
                              time.monotonic() - job.started, bool(output and output.fragile))
        with self._lock:
            self._job = None
            self._status = final
            self._publish_status(final)
        job.outcome, job.summary = outcome, summary
        line = f"{summary} (done {time.monotonic() - job.submitted:.2f} s after the request)"
        if outcome == Outcome.SUCCEEDED.value and not final.fragile:
            self.get_logger().info(line)
        else:
            self.get_logger().warning(line)

    def _on_progress(self, progress: Progress) -> None:
        with self._lock:
            self._progress = progress



def _describe(exc: Exception) -> str:
    if isinstance(exc, RearrangementError):
        return str(exc)
    return f"internal error {type(exc).__name__}: {exc}"


def main(args: list[str] | None = None) -> int:
    """`planner_node`: init, spin on a MultiThreadedExecutor, clean up."""
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
