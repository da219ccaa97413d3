"""A Python client of the planner node: its action `~/plan_rearrangement` and its `~/execute`
service, on any rclpy node. `make demo` and the bag replay use it; a user's script can too:

    client = PlannerClient(node)                  # node: a spinning rclpy node
    reply = client.plan(PlanRearrangement.Goal(execute=True))
    reply.outcome, reply.trajectory, reply.mcap   # 'SUCCESS', JointTrajectory, Path
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from rearrangement_planner.model.errors import RearrangementError
from rearrangement_planner.model.resources import NODE_NAME


class ClientError(RearrangementError):
    """The node did not answer in time, or refused the goal; the message says which."""


@dataclass(frozen=True)
class PlanReply:
    success: bool
    """A plan came back (error code SUCCESS, or FRAGILE_PLAN with its trajectory)."""
    message: str
    """The node's one-line summary."""
    plan_id: str = ""
    outcome: str = ""
    """The error code's name (SUCCESS, TIMED_OUT, ...; rearrangement_interfaces/ErrorCode)."""
    plan_time: float = 0.0
    iterations: int = 0
    mcap: Path | None = None
    """The plan's recording, None when not recorded."""
    trajectory: Any = None
    """The trajectory_msgs/JointTrajectory of the plan (None unless one came back)."""
    wall_time: float = 0.0
    """Seconds from the request to the answer."""
    result: Any = None
    """The action's whole PlanRearrangement result."""


def action_client(node: Any, action_type: Any, name: str) -> Any:
    """An rclpy ActionClient on `node` whose requests cannot lose their response.

    rclpy's `send_goal_async` (and the cancel and result requests) sends the request, then
    registers its sequence number. An executor spinning in another thread can take the
    response in between. The client then logs "Ignoring unexpected goal response" and the
    future never completes (ros2/rclpy#1123). A clean-clone test run failed this way with
    `node_demo`: the node planned and executed, and the demo waited for an answer it had
    dropped. rclpy fixed it in #1308 (Jazzy backport #1519), which the pinned wheel predates.
    The fix is the same: one lock held while a request is sent and registered, and while the
    executor takes responses. Its services keep as many requests and responses as the server's
    (`action.REQUESTS`), so that a burst is answered whole."""
    from rclpy.action import ActionClient

    class _Client(ActionClient):
        def __init__(self, *args: Any, **kwargs: Any) -> None:
            super().__init__(*args, **kwargs)
            self._sending = threading.Lock()

        def take_data(self) -> Any:
            with self._sending:
                return super().take_data()

        def send_goal_async(self, *args: Any, **kwargs: Any) -> Any:
            with self._sending:
                return super().send_goal_async(*args, **kwargs)

        def _cancel_goal_async(self, goal_handle: Any) -> Any:
            with self._sending:
                return super()._cancel_goal_async(goal_handle)

        def _get_result_async(self, goal_handle: Any) -> Any:
            with self._sending:
                return super()._get_result_async(goal_handle)

    from rearrangement_planner.ros.action import REQUESTS

    return _Client(node, action_type, name, goal_service_qos_profile=REQUESTS,
                   result_service_qos_profile=REQUESTS, cancel_service_qos_profile=REQUESTS)


class PlannerClient:
    """The planner node seen from `node`: its action `~/plan_rearrangement` (`plan`) and its
    `~/execute` service (send the last plan to the controller)."""

    def __init__(self, node, namespace: str = f"/{NODE_NAME}"):
        from std_srvs.srv import Trigger

        from rearrangement_interfaces.action import PlanRearrangement

        self.namespace = namespace.rstrip("/")
        self._action = action_client(node, PlanRearrangement,
                                     f"{self.namespace}/plan_rearrangement")
        self._execute = node.create_client(Trigger, f"{self.namespace}/execute")

    def wait_ready(self, timeout: float = 10.0) -> None:
        if not (self._action.wait_for_server(timeout_sec=timeout)
                and self._execute.wait_for_service(timeout_sec=timeout)):
            raise ClientError(f"the planner node's action {self.namespace}/plan_rearrangement and "
                           f"service {self.namespace}/execute did not come up in {timeout:g} s")

    def plan(self, goal: Any = None, timeout: float = 120.0,
             feedback: Callable[[Any], None] | None = None) -> PlanReply:
        """Send `goal` (default: an empty PlanRearrangement goal, which plans with the node's
        parameters and latest inputs) and wait for its result; `feedback` gets each feedback."""
        from rearrangement_interfaces.action import PlanRearrangement
        from rearrangement_interfaces.msg import ErrorCode
        from rearrangement_planner.ros.action import ERROR_NAMES

        self.wait_ready()
        t0 = time.monotonic()
        sent = self._action.send_goal_async(
            goal if goal is not None else PlanRearrangement.Goal(),
            feedback_callback=(lambda m: feedback(m.feedback)) if feedback else None)
        if not wait_until(sent.done, 10.0):
            raise ClientError(f"{self.namespace}/plan_rearrangement did not take the goal in 10 s")
        handle = sent.result()
        if not handle.accepted:
            raise ClientError(f"{self.namespace}/plan_rearrangement refused the goal (busy; see "
                           f"{self.namespace}/status)")
        answer = handle.get_result_async()
        if not wait_until(answer.done, timeout):
            raise ClientError(f"{self.namespace}/plan_rearrangement did not answer in "
                              f"{timeout:g} s")
        result = answer.result().result
        code = result.error_code.val
        solved = code in (ErrorCode.SUCCESS, ErrorCode.FRAGILE_PLAN) and \
            len(result.trajectory.points) > 0
        return PlanReply(solved, result.message, result.plan_id,
                         ERROR_NAMES.get(code, str(code)), result.plan_time, result.iterations,
                         Path(result.mcap_path) if result.mcap_path else None,
                         result.trajectory if solved else None, time.monotonic() - t0, result)

    def execute(self, timeout: float = 10.0):
        """Call ~/execute; the std_srvs/Trigger response."""
        from std_srvs.srv import Trigger

        future = self._execute.call_async(Trigger.Request())
        if not wait_until(future.done, timeout):
            raise ClientError(f"{self.namespace}/execute did not answer in {timeout:g} s")
        return future.result()


def wait_until(predicate, timeout: float, period: float = 0.01) -> bool:
    """Poll `predicate` every `period` s until it holds or `timeout` s pass; its last value."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if predicate():
            return True
        time.sleep(period)
    return bool(predicate())
