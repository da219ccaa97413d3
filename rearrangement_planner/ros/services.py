"""The node's Trigger services (docs/design.md): `~/plan`, `~/cancel` and `~/execute`, thin
wrappers over the same job as the action `~/plan_rearrangement` (`ros/action.py`): a `~/plan`
call is a job without a goal, planned with the node's parameters and latest inputs."""

from __future__ import annotations

import time
from typing import Any

from rclpy.callback_groups import CallbackGroup
from std_srvs.srv import Trigger

from rearrangement_planner.planning.machinery.interface import Outcome

CANCEL_WAIT = 1.0
"""Seconds `~/cancel` waits for the planner to stop before answering."""


class TriggerServices:
    """`~/plan` (in `plan`, a reentrant group, so that a second call is refused, not queued),
    `~/cancel` and `~/execute` (in `control`) on `node`, a `PlannerNode`."""

    def __init__(self, node: Any, plan: CallbackGroup, control: CallbackGroup):
        self._node = node
        node.create_service(Trigger, "~/plan", self._on_plan, callback_group=plan)
        node.create_service(Trigger, "~/cancel", self._on_cancel, callback_group=control)
        node.create_service(Trigger, "~/execute", self._on_execute, callback_group=control)

    def _on_plan(self, request: Trigger.Request, response: Trigger.Response
                 ) -> Trigger.Response:
        job = self._node.submit("~/plan")
        if isinstance(job, str):
            response.success, response.message = False, job
            return response
        job.done.wait()
        response.success = job.outcome == Outcome.SUCCEEDED.value
        response.message = job.summary
        return response

    def _on_cancel(self, request: Trigger.Request, response: Trigger.Response
                   ) -> Trigger.Response:
        job, _ = self._node.running()
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
        self._node.get_logger().info(response.message)
        return response

    def _on_execute(self, request: Trigger.Request, response: Trigger.Response
                    ) -> Trigger.Response:
        running, _ = self._node.running()
        if running is not None:
            # The arm may be executing that job's plan (or about to): the last plan, whose
            # first point is its start at t = 0, would command it back there mid-motion.
            response.success = False
            response.message = (f"refused: plan {running.plan_id} is running (planning or "
                                f"executing); ~/execute sends the last plan only when the node "
                                f"is idle")
            return response
        last = self._node.last_trajectory()
        if last is None:
            response.success = False
            response.message = "no successful plan to execute yet; call ~/plan first"
            return response
        plan_id, msg = last
        self._node.send(msg)
        duration = msg.points[-1].time_from_start
        response.success = True
        topic = self._node.resolve_topic_name("joint_trajectory")
        response.message = (f"plan {plan_id} sent to {topic} "
                            f"({len(msg.points)} points, "
                            f"{duration.sec + duration.nanosec * 1e-9:.1f} s)")
        self._node.get_logger().info(response.message)
        return response
