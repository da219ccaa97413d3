"""`planner_node` (node `rearrangement_planner`): the ROS 2 node of docs/design.md, a thin layer
around `pipeline.plan_scene`.

Data flow:
- Input topics (`joint_states`, `~/object_poses`, `~/goal`) are converted at the edge by
  msg_adapters and kept as the last good value with its receive time. A bad message is logged
  and reported on `~/status` (field and problem); the last good value stays.
- A plan request (a goal of the action `~/plan_rearrangement` (`ros/action.py`), a `~/plan`
  call (`ros/services.py`), or `~/goal` with `plan_on_goal`) becomes a `Job` for the ONE worker
  thread; a request while a job exists is refused at once. The worker reads the parameters (a
  goal changes them for its job), snapshots the inputs, builds the planning scene (the
  configured scene with the received start state and goal, checked by `check_scene`), builds
  one request on it, runs `plan_scene`, then publishes the trajectory, executes it when the goal
  asks, records the plan to MCAP, publishes markers and the final status (`ros/outputs.py`),
  and answers the request.
- A MultiThreadedExecutor with three callback groups keeps the inputs, the action's feedback,
  `~/cancel`, `~/execute` and the 4 Hz status timer live while the worker plans: `inputs`
  (subscriptions), `plan` (reentrant, so that a second request is refused instead of queued)
  and `control`.

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

import rclpy
from builtin_interfaces.msg import Time
from geometry_msgs.msg import PoseArray, PoseStamped
from rclpy.callback_groups import MutuallyExclusiveCallbackGroup, ReentrantCallbackGroup
from rclpy.executors import ExternalShutdownException, MultiThreadedExecutor
from rclpy.logging import get_logger
from rclpy.node import Node
from rclpy.qos import (
    qos_profile_sensor_data,
)
from rclpy.signals import SignalHandlerOptions
from sensor_msgs.msg import JointState
from trajectory_msgs.msg import JointTrajectory

from msg_adapters import (
    joint_state_to_configuration,
    plan_markers,
    pose_stamped_to_goal,
    trajectory_to_msg,
)
from rearrangement_planner.model.errors import ObjectTilted, RearrangementError, cut_text
from rearrangement_planner.model.resources import NODE_NAME
from rearrangement_planner.planning.machinery.interface import Outcome, Progress
from rearrangement_planner.planning.requests.parallel import start_workers
from rearrangement_planner.planning.requests.status import PlannerStatus
from rearrangement_planner.planning.requests.warmup import warm_up
from rearrangement_planner.ros.action import (
    DIVERGED,
    PlanActionServer,
    execute,
    recorded_action,
)
from rearrangement_planner.ros.latest import Latest, LazyInput
from rearrangement_planner.ros.live_view import NodeLive
from rearrangement_planner.ros.outputs import Outputs
from rearrangement_planner.ros.parameters import PARAMETERS, declare_parameters, read_parameters
from rearrangement_planner.ros.plan_request import (
    FINAL_STATES,
    Input,
    Job,
    configured_scene,
    final_summary,
    objects_from_msg,
    planning_status,
    record,
    result_markers,
    run_plan,
)
from rearrangement_planner.ros.replan import LoopIO, close_the_loop, goal_watch
from rearrangement_planner.ros.services import TriggerServices

EXECUTOR_THREADS = 6
STATUS_RATE = 4.0
"""Hz of the `~/status` progress messages while planning (docs/design.md asks for >= 2 Hz)."""
INPUT_ERROR_REPEAT = 1.0
"""Seconds before a rejection of the same input topic (or the same problem) is published on
`~/status` and logged again (flood guard: a stream of varied bad messages is one line a
second)."""
REPORT_CHARS = 400
"""Longest problem report; a rejection names the field and the problem, it does not echo an
input of any size."""


# --------------------------------------------------------------------------------------------
# The node
# --------------------------------------------------------------------------------------------


def _warm_up(node: Node) -> None:
    """Compile the fast core at node start (or load it from the disk cache), not in the first
    plan; the race's tree workers start beside it (`start_workers`) and load theirs while the
    node serves, so that the first plan's warm-up (`warm_up_race`) finds them ready."""
    start_workers(int(node.get_parameter("trees").value))
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
        self._objects_rejected: tuple[float, str] | None = None
        self._objects_tilted: tuple[float, ObjectTilted] | None = None
        self._goal: Input | None = None
        self._job: Job | None = None
        self._progress: Progress | None = None
        self._status = PlannerStatus("idle", f"ready: scene {self._scene.source}")
        self._input_error: dict[str, float] = {}
        self._last_trajectory: tuple[str, JointTrajectory] | None = None
        self._counter = 0
        self._stopping = False
        self._queue: queue.SimpleQueue[Job | None] = queue.SimpleQueue()

        inputs = MutuallyExclusiveCallbackGroup()
        plan = ReentrantCallbackGroup()
        control = MutuallyExclusiveCallbackGroup()
        self._out = Outputs(self)
        self._joints = LazyInput(
            Latest(self.context, f"{NODE_NAME}_joint_states", JointState,
                   self.resolve_topic_name("joint_states"), qos_profile_sensor_data),
            lambda msg: joint_state_to_configuration(msg, self._robot.joint_names),
            lambda exc, _: self.report(f"rejected joint_states: {_describe(exc)}",
                                       "joint_states"))
        self._objects = LazyInput(
            Latest(self.context, f"{NODE_NAME}_object_poses", PoseArray,
                   self.resolve_topic_name("~/object_poses"), qos_profile_sensor_data),
            self._object_poses, self._objects_refused)
        self._goal_sub = self.create_subscription(
            PoseStamped, "~/goal", self._on_goal, 10, callback_group=inputs)
        self._plan_action = PlanActionServer(self, plan)
        self._triggers = TriggerServices(self, plan, control)
        self.create_timer(1.0 / STATUS_RATE, self._on_status_timer, callback_group=control)

        self._worker = threading.Thread(target=self._work, name="planner_worker", daemon=True)
        self._worker.start()
        self._out.publish(self._out.markers, plan_markers(
            self._scene, None, None, self._planning_frame(), self._stamp()))
        self._publish_status(self._status)
        self.live = NodeLive.open(self.get_parameter("live_view_port").value, self._scene,
                                  self.get_logger())
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
        self.live.close()
        self._plan_action.destroy()
        self._joints.latest.destroy()
        self._objects.latest.destroy()
        super().destroy_node()

    # -- small helpers --------------------------------------------------------------------------

    def _stamp(self) -> Time:
        return self.get_clock().now().to_msg()

    def _planning_frame(self) -> str:
        return self.get_parameter("planning_frame").value or self._robot.config.base_frame

    def _publish_status(self, status: PlannerStatus) -> None:
        self._out.status(status)

    def _planning_status(self, job: Job, message: str) -> PlannerStatus:
        return planning_status(job, self._progress, message)

    def last_inputs(self) -> dict[str, Any]:
        """The last accepted message of each input ('joint_states', 'object_poses', 'goal';
        None before the first): what the next plan starts from."""
        latest = self._latest()
        return {k: (v.msg if v is not None else None) for k, v in latest.items()}

    def report(self, message: str, source: str = "") -> None:
        """Log a problem and put it on ~/status (state unchanged), cut to REPORT_CHARS; at most
        once per INPUT_ERROR_REPEAT s per `source` (an input topic), or per message text."""
        now, key, message = time.monotonic(), source or message, _cut(message)
        with self._lock:
            if now - self._input_error.get(key, -math.inf) < INPUT_ERROR_REPEAT:
                return
            self._input_error[key] = now
            job = self._job
            status = (self._planning_status(job, message) if job is not None
                      else dataclasses.replace(self._status, message=message))
            self._publish_status(status)
        self.get_logger().warning(message)

    # -- inputs ---------------------------------------------------------------------------------

    def _object_poses(self, msg: PoseArray) -> Any:
        params = {name: self.get_parameter(name).value
                  for name in ("object_ids", "planning_frame", "max_object_tilt")}
        return objects_from_msg(msg, params, self._scene)

    def _objects_refused(self, exc: Exception, received: float) -> None:
        self.report(f"rejected object_poses: {_describe(exc)}", "object_poses")
        with self._lock:
            self._objects_rejected = (received, _describe(exc))
            if isinstance(exc, ObjectTilted):
                self._objects_tilted = (received, exc)

    def _on_goal(self, msg: PoseStamped) -> None:
        received = time.monotonic()
        try:
            xy = pose_stamped_to_goal(msg, self._planning_frame())
        except Exception as exc:  # noqa: BLE001
            self.report(f"rejected goal: {_describe(exc)}", "goal")
            return
        with self._lock:
            self._goal = Input(xy, msg, received)
        if self.get_parameter("plan_on_goal").value:
            job = self.submit("~/goal")
            if isinstance(job, str):
                self.report(f"goal received, not planning: {job}")

    # -- requests -------------------------------------------------------------------------------

    def submit(self, source: str, goal: Any = None, queued: bool = True) -> Job | str:
        """A new job for the worker, or why not (busy); `goal`: the action goal it serves;
        not `queued`: reserved (the node is busy with it) until `enqueue`."""
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
            job.goal = goal
            self._job = job
            self._progress = None
        if queued:
            self._queue.put(job)
        return job

    def _on_status_timer(self) -> None:
        """The progress while planning; and at this rate, the newest inputs converted, so that
        one that is unusable is reported (`report`) while the node waits."""
        self._latest()
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
        """Plan, publish the trajectory, execute when the goal asks, record, publish markers
        and the final status."""
        job.started = time.monotonic()
        job.phase = "planning"
        with self._lock:
            self._publish_status(self._planning_status(
                job, f"plan {job.plan_id} started ({job.source})"))
        job.params = read_parameters(self, PARAMETERS)
        job.frame = frame = job.params["planning_frame"] or self._robot.config.base_frame
        node_params = job.params
        outcome, message, scene, output, inputs = self._plan(job, node_params)
        params = job.params      # with the goal's changes
        job.output = output
        job.planned.set()
        self.live.answer(scene, output)

        fragile = bool(output and output.fragile)
        sendable = not fragile or params["execute_fragile"]
        executed = False
        if output is not None and output.trajectory is not None:
            msg = trajectory_to_msg(output.trajectory)
            job.trajectory = msg
            self._out.publish(self._out.trajectory, msg)
            with self._lock:
                self._last_trajectory = (job.plan_id, msg)
            if job.goal is not None and job.goal.execute and sendable:
                outcome, message, scene, output, inputs = _execute_goal(
                    self, job, msg, (scene, output, inputs), node_params)
                executed = job.executed = True
            elif job.goal is None and params["auto_execute"] and sendable:
                self._out.publish(self._out.command, msg)
        job.phase = "recording"

        def action_records(path: str) -> list[tuple]:
            """The goal, feedback and result, as the answer will be when `path` is written."""
            job.outcome, job.recording = outcome, path
            job.summary = final_summary(job, outcome, message, path, executed, sendable)
            return recorded_action(job, self._stamp())

        recording, failure = record(job, output, params, frame, inputs, self.get_logger(),
                                    action_records if job.goal is not None else None)
        job.recording = recording
        if failure is not None:
            self.report(failure)
        self._out.publish(self._out.markers, result_markers(scene, output, frame, self._stamp()))

        r = output.result if output is not None else None    # None: NO_STATE, nothing ran
        summary = final_summary(job, outcome, message, recording, executed, sendable)
        final = PlannerStatus(FINAL_STATES.get(outcome, "failed"), summary, outcome,
                              job.plan_id, r.iterations if r else 0, r.tree_size if r else 0,
                              r.best_goal_distance if r else math.inf,
                              time.monotonic() - job.started, fragile)
        with self._lock:
            self._job = None
            self._status = final
            self._publish_status(final)
        job.outcome, job.summary = outcome, summary
        self.live.log(summary)
        line = f"{summary} (done {time.monotonic() - job.submitted:.2f} s after the request)"
        if outcome == Outcome.SUCCEEDED.value and not final.fragile:
            self.get_logger().info(line)
        else:
            self.get_logger().warning(line)

    def enqueue(self, job: Job) -> None:
        """Hand a job reserved by `submit(..., queued=False)` to the worker."""
        self._queue.put(job)

    def running(self) -> tuple[Job | None, Progress | None]:
        """The job that runs now (None when idle) and its planner's last progress."""
        with self._lock:
            return self._job, self._progress

    def last_trajectory(self) -> tuple[str, JointTrajectory] | None:
        """The plan id and trajectory of the last solved plan (None before the first)."""
        with self._lock:
            return self._last_trajectory

    def send(self, msg: JointTrajectory) -> None:
        """Send `msg` to the arm's controller (joint_trajectory)."""
        self._out.publish(self._out.command, msg)

    def _latest(self) -> dict[str, Input | None]:
        """The last good input of each topic, the joint state and object poses converted from
        their newest messages now (`latest.LazyInput`: nothing runs per message)."""
        joints, objects = self._joints.get(), self._objects.get()
        with self._lock:
            return {"joint_states": joints, "object_poses": objects, "goal": self._goal}

    def _plan(self, job: Job, params: dict[str, Any]) -> tuple:
        """`run_plan` from the latest inputs with the node's `params`."""
        topics = {"joint_states": self._joints.latest.topic_name,
                  "object_poses": self._objects.latest.topic_name}
        return run_plan(job, params, self._scene, self._latest(), topics, self._on_progress,
                        self.get_logger())

    def _on_progress(self, progress: Progress) -> None:
        with self._lock:
            self._progress = progress
        self.live.search(progress)



def _execute_goal(node: PlannerNode, job: Job, msg: JointTrajectory, planned: tuple,
                  params: dict[str, Any]) -> tuple:
    """Execute an action goal's plan `msg` and wait for the arm (`action.execute`); with
    replan_attempts, close the loop (`ros/replan.py`; re-plans read the node's `params`).
    Returns (outcome, message, scene, output, inputs) of the last attempt."""
    scene, output, inputs = planned
    job.phase = "executing"
    attempts, bound = job.params["replan_attempts"], job.params["divergence_bound"]

    # One attribute read each (atomic): the last object pose message rejected, and the last
    # rejected because an object was seen tilted (when, and which).
    def rejected() -> tuple[float, str] | None:
        return node._objects_rejected

    def tilted() -> tuple[float, ObjectTilted] | None:
        return node._objects_tilted

    def send(command: JointTrajectory, watched: Any) -> tuple[str, str]:
        watch = goal_watch(watched, attempts, bound, lambda: node._latest()["object_poses"],
                           tilted, node.live.executing if node.live.view else None)
        return execute(job, command, job.params["execution_timeout"], node.send,
                       node._joints.get, watch)

    outcome, message = send(msg, output)
    if outcome not in (Outcome.SUCCEEDED.value, DIVERGED) or attempts == 0:
        return outcome, message, scene, output, inputs

    def record_attempt(attempt: Any, used: dict, plan_id: str) -> None:
        _, failure = record(job, attempt, job.params, job.frame, used, node.get_logger(),
                            plan_id=plan_id)
        if failure is not None:
            node.report(failure)

    io = LoopIO(node._latest, rejected, send, lambda _: node._plan(job, params),
                record_attempt)
    last = close_the_loop(job, io, scene, output, inputs, attempts, time.monotonic(),
                          message if outcome == DIVERGED else "",
                          job.params["replan_closing"])
    job.output = last[3]
    return last


def _cut(message: str) -> str:
    return cut_text(message, REPORT_CHARS)


def _describe(exc: Exception) -> str:
    if isinstance(exc, RearrangementError):
        return str(exc)
    return f"internal error {type(exc).__name__}: {exc}"


def main(args: list[str] | None = None) -> int:
    """`planner_node`: init, spin on a MultiThreadedExecutor, clean up."""
    # No rclpy signal handler: Ctrl-C arrives as KeyboardInterrupt while the context is still
    # valid, so a running plan is cancelled and its worker joined before anything is destroyed.
    rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.NO)
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
            _send_last_results(executor, node)
        executor.shutdown()
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()
    return 0


SHUTDOWN_GRACE = 3.0
"""s the node spins on at shutdown so that a goal its stop cancelled gets its result."""


def _send_last_results(executor: MultiThreadedExecutor, node: PlannerNode) -> None:
    """After `node.stop()` (Ctrl-C): spin until every goal's result is given, PREEMPTED for a
    plan it cancelled, as ErrorCode.msg promises, and the responses have gone out."""
    if not node.context.ok():
        return                           # shut down from outside: nothing can be sent
    deadline = time.monotonic() + SHUTDOWN_GRACE
    sent = None
    while time.monotonic() < deadline:
        executor.spin_once(timeout_sec=0.05)
        if node._plan_action.answering == 0:
            sent = sent or time.monotonic()
            if time.monotonic() - sent > 0.3:
                return


if __name__ == "__main__":
    raise SystemExit(main())
