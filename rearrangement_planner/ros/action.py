"""The node's action `~/plan_rearrangement` (rearrangement_interfaces/action/
PlanRearrangement.action), apart from the node's wiring: what a goal changes in a plan request,
the error code of an outcome, and the result message. `ros/node.py` serves the action; the
Trigger service `~/plan` runs the same job without a goal (docs/design.md "The action").
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Callable
from typing import Any

import numpy as np
from builtin_interfaces.msg import Time
from geometry_msgs.msg import PoseArray
from rclpy.action import ActionServer, CancelResponse, GoalResponse
from rclpy.action.server import ServerGoalHandle
from rclpy.callback_groups import CallbackGroup
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from trajectory_msgs.msg import JointTrajectory

from msg_adapters import goal_to_pose_stamped, objects_to_pose_array
from rearrangement_interfaces.action import PlanRearrangement
from rearrangement_interfaces.msg import ErrorCode
from rearrangement_planner.io.plan_record import NODE_NAMESPACE
from rearrangement_planner.model.errors import InputError, cut_text
from rearrangement_planner.model.settings import parse_assignments
from rearrangement_planner.planning.machinery.interface import Outcome, Progress
from rearrangement_planner.planning.requests.pipeline import PlanOutput
from rearrangement_planner.planning.requests.request import request_settings

NO_STATE = "NO_STATE"
"""The node's own outcome (docs/design.md): no joint state / object poses yet, or stale ones."""
EXECUTION_FAILED = "EXECUTION_FAILED"
"""The node's own outcome: a plan was sent, and the arm did not reach its end in time."""
GOAL_NOT_REACHED = "GOAL_NOT_REACHED"
"""The closed loop's outcome (`ros/replan.py`): executed, observed, and the goal missed."""
NO_OBSERVATION = "NO_OBSERVATION"
"""The closed loop's outcome: no usable object poses arrived after an execution."""
DIVERGED = "DIVERGED"
"""`execute`'s outcome when its watch stopped the arm: an object strayed from the plan."""

FEEDBACK_RATE = 4.0
"""Hz of the action's feedback while a goal runs."""
EXECUTION_TOLERANCE = 0.01
"""rad: how close every joint of joint_states must come to a sent trajectory's last point for
the execution to have reached it."""
EXECUTION_MARGIN = 10.0
"""s: how long past a sent trajectory's duration the action waits for the arm to reach its
end, unless parameter execution_timeout says otherwise."""

ERROR_CODES: dict[str, int] = {
    Outcome.SUCCEEDED.value: ErrorCode.SUCCESS,
    Outcome.PLANNING_FAILED.value: ErrorCode.PLANNING_FAILED,
    Outcome.TIMEOUT.value: ErrorCode.TIMED_OUT,
    Outcome.CANCELLED.value: ErrorCode.PREEMPTED,
    Outcome.START_INVALID.value: ErrorCode.START_STATE_INVALID,
    NO_STATE: ErrorCode.START_STATE_INVALID,
    Outcome.GOAL_INVALID.value: ErrorCode.GOAL_INVALID,
    Outcome.INVALID_INPUT.value: ErrorCode.INVALID_INPUT,
    EXECUTION_FAILED: ErrorCode.EXECUTION_FAILED,
    GOAL_NOT_REACHED: ErrorCode.GOAL_NOT_REACHED,
    NO_OBSERVATION: ErrorCode.NO_OBSERVATION,
    Outcome.INTERNAL.value: ErrorCode.INTERNAL,
}
"""The error code of each outcome (a fragile success is FRAGILE_PLAN: `error_code`)."""
ERROR_NAMES: dict[int, str] = {getattr(ErrorCode, name): name for name in dir(ErrorCode)
                               if name.isupper() and isinstance(getattr(ErrorCode, name), int)}
"""The name of each error code value ('SUCCESS', 'TIMED_OUT', ...)."""


def error_code(outcome: str, fragile: bool) -> int:
    """The ErrorCode value of a request's outcome; a solved but fragile plan is FRAGILE_PLAN."""
    if outcome == Outcome.SUCCEEDED.value and fragile:
        return ErrorCode.FRAGILE_PLAN
    return ERROR_CODES.get(outcome, ErrorCode.INTERNAL)


def goal_parameters(goal: PlanRearrangement.Goal, params: dict[str, Any]) -> dict[str, Any]:
    """The node's parameters as `goal` changes them for one request: goal object and radius,
    planner, time limit, seed and the NAME=VALUE settings. InputError names the goal field at
    fault (`goal.settings[1]`); ranges are checked when the request is built."""
    changed = dict(params)
    if goal.goal_object:
        changed["goal_object"] = goal.goal_object
    if not math.isfinite(goal.goal_radius) or goal.goal_radius < 0.0:
        raise InputError("goal.goal_radius", f"is {goal.goal_radius}; give a radius > 0 (m), or "
                                             f"0 for the node's")
    if goal.goal_radius > 0.0:
        changed["goal_radius"] = goal.goal_radius
    if goal.planner:               # an unknown one is named when the request is built
        changed["planner"] = goal.planner
    if not math.isfinite(goal.time_limit) or goal.time_limit < 0.0:
        raise InputError("goal.time_limit", f"is {goal.time_limit}; give a budget > 0 (s), or 0 "
                                            f"for the node's")
    if goal.time_limit > 0.0:
        changed["time_limit"] = goal.time_limit
    if goal.seed >= 0:
        changed["seed"] = int(goal.seed)
    specs = request_settings()
    for i, item in enumerate(goal.settings):
        try:
            changed.update(parse_assignments(specs, [item]))
        except ValueError as exc:
            raise InputError(f"goal.settings[{i}]", str(exc)) from None
    if goal.replan_attempts > 20:
        raise InputError("goal.replan_attempts", f"is {goal.replan_attempts}; give 0 to 20, or "
                                                 f"a negative number for the node's")
    if goal.replan_attempts >= 0:
        changed["replan_attempts"] = int(goal.replan_attempts)
    return changed


def goal_origins(goal: PlanRearrangement.Goal) -> dict[str, str]:
    """The goal field each setting a goal changes comes from (what an error names)."""
    origins = {name: f"goal.{name}" for name, given in (
        ("planner", bool(goal.planner)), ("time_limit", goal.time_limit > 0),
        ("seed", goal.seed >= 0), ("goal_radius", goal.goal_radius > 0)) if given}
    for i, item in enumerate(goal.settings):
        origins[item.partition("=")[0].strip()] = f"goal.settings[{i}]"
    return origins


def goal_point_pose(goal: PlanRearrangement.Goal, frame: str) -> Any:
    """The goal's goal point as the PoseStamped the node would have received on ~/goal, or None
    when the goal does not set one. InputError when it is not finite."""
    if not goal.use_goal_point:
        return None
    p = goal.goal_point
    if not all(math.isfinite(v) for v in (p.x, p.y, p.z)):
        raise InputError("goal.goal_point", f"is ({p.x}, {p.y}, {p.z}); give finite numbers (m)")
    return goal_to_pose_stamped((p.x, p.y), frame, p.z)


def predicted_object_poses(output: PlanOutput | None, frame: str,
                           stamp: Time) -> list[PoseArray]:
    """The objects' predicted poses at each trajectory point, in scene order."""
    if output is None or output.trajectory is None:
        return []
    scene = output.scene
    heights = np.array([scene.table.height + 0.5 * o.height for o in scene.objects])
    return [objects_to_pose_array(s.objects, frame, heights, stamp)
            for s in output.trajectory_states]


ACTION_TYPE = "rearrangement_interfaces/action/PlanRearrangement"


def recorded_action(job: Any, stamp: Time) -> list[tuple]:
    """The goal, the feedback and the result of an action job as recording entries (topic,
    type, message, log time (ns), QoS name), on `<node>/plan_rearrangement/{goal, feedback,
    result}` with the action's Goal, Feedback and Result types."""
    topic = f"{NODE_NAMESPACE}/plan_rearrangement"
    entries = [(f"{topic}/goal", f"{ACTION_TYPE}_Goal", job.goal, job.submitted_ns, "reliable")]
    entries += [(f"{topic}/feedback", f"{ACTION_TYPE}_Feedback", feedback, t, "reliable")
                for t, feedback in list(job.feedback)]
    entries.append((f"{topic}/result", f"{ACTION_TYPE}_Result", job_result(job, stamp),
                    time.time_ns(), "reliable"))
    return entries


REQUEST_DEPTH = 1000
REQUESTS = QoSProfile(depth=REQUEST_DEPTH, reliability=ReliabilityPolicy.RELIABLE,
                      durability=DurabilityPolicy.VOLATILE, history=HistoryPolicy.KEEP_LAST)
"""The action's goal, cancel and result services keep this many requests each: with the
default 10, a burst of 20 goals (or 60 cancels) sent at once lost requests that were then never
answered, accepted or refused."""

RESULT_TIMEOUT = 120
"""s a finished goal and its result are kept for a client to fetch (rclpy's default is 900 s:
each goal, whatever it carried, stayed in memory for a quarter of an hour)."""

RESULT_CHARS = 4000
"""A result's message is cut to this many characters: a message quotes what was wrong with
the goal, and a goal may hold a 100 kB string (the closed loop's longest answers, a line per
attempt, stay within 1,500)."""


def plain_result(code: int, message: str) -> PlanRearrangement.Result:
    result = PlanRearrangement.Result(message=cut_text(message, RESULT_CHARS))
    result.error_code.val = code
    return result


def job_result(job: Any, stamp: Time) -> PlanRearrangement.Result:
    """The action result of a finished job (`plan_request.Job`)."""
    output = job.output
    unsent = bool(output and output.fragile) and not job.executed   # executed: as asked
    result = plain_result(error_code(job.outcome, unsent), job.summary)
    if job.trajectory is not None:
        result.trajectory = job.trajectory
    result.predicted_object_poses = predicted_object_poses(output, job.frame, stamp)
    if output is not None and output.robustness is not None:
        result.robustness = float(output.robustness)
    result.plan_id = job.plan_id
    if output is not None:
        result.plan_time = float(output.result.plan_time)
        result.iterations = int(output.result.iterations)
    result.mcap_path = "" if job.recording.startswith("not recorded") else job.recording
    return result


def job_feedback(job: Any, progress: Progress | None) -> PlanRearrangement.Feedback:
    """The feedback of a running job: its phase, and while it plans, the planner's progress."""
    feedback = PlanRearrangement.Feedback(phase=job.phase, attempt=job.attempt,
                                          elapsed=time.monotonic() - job.submitted,
                                          best_goal_distance=math.inf)
    if progress is not None and job.phase == "planning":
        feedback.iterations = progress.iterations
        feedback.tree_size = progress.tree_size
        feedback.best_goal_distance = float(progress.best_goal_distance)
    return feedback


def execute(job: Any, msg: JointTrajectory, timeout: float, publish: Callable[[Any], None],
            joint_input: Callable[[], Any],
            watch: Callable[[np.ndarray], str | None] | None = None) -> tuple[str, str]:
    """Send `msg` (`publish`) and wait until the joint state (`joint_input()`, an Input
    received after the send) reaches its last point within EXECUTION_TOLERANCE, the job is
    cancelled (the arm is stopped with an empty trajectory, as joint_trajectory_controller
    documents), `watch(q)` names a divergence (the arm is stopped: DIVERGED) or `timeout` s
    pass (0: the duration plus EXECUTION_MARGIN). Outcome, message."""
    end = msg.points[-1]
    duration = end.time_from_start.sec + end.time_from_start.nanosec * 1e-9
    timeout = timeout if timeout > 0.0 else duration + EXECUTION_MARGIN
    target = np.asarray(end.positions, dtype=float)
    sent = time.monotonic()
    publish(msg)
    error = math.inf
    while not job.cancel.wait(0.05):
        joint = joint_input()
        if joint is not None and joint.received > sent:
            error = float(np.max(np.abs(joint.value - target)))
            if error <= EXECUTION_TOLERANCE:
                return (Outcome.SUCCEEDED.value,
                        f"executed: the arm reached the plan's end "
                        f"{time.monotonic() - sent:.1f} s after it was sent")
            strayed = watch(joint.value) if watch is not None else None
            if strayed:
                publish(JointTrajectory(joint_names=list(msg.joint_names)))
                return DIVERGED, f"stopped the arm: {strayed}"
        if time.monotonic() - sent > timeout:
            return (EXECUTION_FAILED,
                    f"execution failed: joint_states did not reach the trajectory's last point "
                    f"within {timeout:.1f} s (largest joint error {error:.3f} rad)")
    publish(JointTrajectory(joint_names=list(msg.joint_names)))
    return Outcome.CANCELLED.value, "cancelled during execution: the arm was stopped"


class PlanActionServer:
    """`~/plan_rearrangement` on `node` (a `PlannerNode`): each goal becomes a job of the node's
    one worker, like a `~/plan` call. One goal at a time: a goal that arrives while a plan runs
    (a goal's or a `~/plan` call's) is refused, never queued and never preempting; the reason
    goes to ~/status and the log. Cancel stops the planner, or stops the arm mid-execution."""

    def __init__(self, node: Any, group: CallbackGroup):
        self._node = node
        self._lock = threading.Lock()
        self._reserved: Any = None
        self.answering = 0
        """Goals whose execute callback has not returned (their result not yet given)."""
        self._server = ActionServer(node, PlanRearrangement, "~/plan_rearrangement",
                                    self._on_execute, goal_callback=self._on_goal,
                                    cancel_callback=self._on_cancel, callback_group=group,
                                    goal_service_qos_profile=REQUESTS,
                                    result_service_qos_profile=REQUESTS,
                                    cancel_service_qos_profile=REQUESTS,
                                    result_timeout=RESULT_TIMEOUT)

    def destroy(self) -> None:
        self._server.destroy()

    def _on_goal(self, goal: PlanRearrangement.Goal) -> GoalResponse:
        """Accept a goal when no plan runs (its job is reserved at once), else refuse it."""
        job = self._node.submit("~/plan_rearrangement", goal=goal, queued=False)
        if isinstance(job, str):
            self._node.report(f"~/plan_rearrangement goal {job}")
            return GoalResponse.REJECT
        with self._lock:
            self._reserved = job
        return GoalResponse.ACCEPT

    def _on_cancel(self, handle: ServerGoalHandle) -> CancelResponse:
        job, _ = self._node.running()
        if job is not None and job.goal is handle.request:
            job.cancel.set()
        return CancelResponse.ACCEPT

    def _on_execute(self, handle: ServerGoalHandle) -> PlanRearrangement.Result:
        """Run the reserved job, with feedback at FEEDBACK_RATE, and answer its result."""
        with self._lock:
            self.answering += 1
        try:
            return self._answer(handle)
        finally:
            with self._lock:
                self.answering -= 1

    def _answer(self, handle: ServerGoalHandle) -> PlanRearrangement.Result:
        with self._lock:
            job, self._reserved = self._reserved, None
        if job is None or job.goal is not handle.request:      # cannot happen: one at a time
            handle.abort()
            return plain_result(ErrorCode.INTERNAL, "the accepted goal's job is gone")
        self._node.enqueue(job)
        while True:                      # at least one feedback, however quick the plan
            if handle.is_cancel_requested:
                job.cancel.set()
            running, progress = self._node.running()
            if handle.is_active:
                feedback = job_feedback(job, progress if running is job else None)
                handle.publish_feedback(feedback)
                job.feedback.append((time.time_ns(), feedback))
            if job.done.wait(1.0 / FEEDBACK_RATE):
                break
        result = job_result(job, self._node.get_clock().now().to_msg())
        if result.error_code.val == ErrorCode.SUCCESS:
            handle.succeed()
        elif result.error_code.val == ErrorCode.PREEMPTED and handle.is_cancel_requested:
            handle.canceled()
        else:
            handle.abort()
        return result
