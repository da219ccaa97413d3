"""A topic's newest message, taken when the node needs it rather than as it arrives.

An arm's joint_state_broadcaster publishes at up to 1 kHz. Taken by an executor, each message
costs the node a wake-up of rclpy's executor loop, about a millisecond of Python (a wait set
rebuilt over every entity of the node): three quarters of a core while the node only waits for
a goal, taken from the planner that runs in the same process (docs/benchmark.md, "The node at a
robot's rates"). Here the subscription lives on a node of its own that no executor spins: the
middleware keeps the last `depth` messages (the QoS), and nothing in Python runs until a plan,
the watch or the execution's wait asks for the newest (`take`), at most a few tens of times a
second.

    joints = LazyInput(Latest(context, "rearrangement_planner_joint_states", JointState,
                              node.resolve_topic_name("joint_states"), qos_profile_sensor_data),
                       convert, rejected)
    joints.get()          # the last good Input (value, message, received), or None
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from typing import Any

import rclpy
from rclpy.context import Context
from rclpy.qos import QoSProfile

from rearrangement_planner.ros.plan_request import Input


class Latest:
    """The newest message of one topic (module doc)."""

    def __init__(self, context: Context, name: str, msg_type: Any, topic: str,
                 qos: QoSProfile):
        self._node = rclpy.create_node(name, context=context, enable_rosout=False,
                                       start_parameter_services=False)
        self._sub = self._node.create_subscription(msg_type, topic, _never_called, qos)
        self._lock = threading.Lock()
        self._newest: tuple[Any, float] | None = None

    @property
    def topic_name(self) -> str:
        return self._sub.topic_name

    def take(self) -> tuple[Any, float] | None:
        """(the newest message, its reception time on time.monotonic()'s clock), None before
        the first: every message the middleware holds is taken, the last kept."""
        with self._lock, self._sub.handle:
            while True:
                taken = self._sub.handle.take_message(self._sub.msg_type, False)
                if taken is None:
                    return self._newest
                message, info = taken
                self._newest = (message, _monotonic(info.get("received_timestamp", 0)))

    def destroy(self) -> None:
        self._node.destroy_node()


def _never_called(message: Any) -> None:
    """The subscription's callback: no executor spins its node, so nothing calls it."""


def _monotonic(received_ns: int) -> float:
    """A reception time (ns on the system clock, as the middleware stamps it) on
    time.monotonic()'s clock; now when the middleware gave none."""
    now = time.monotonic()
    if received_ns <= 0:
        return now
    return now - max(0.0, time.time() - received_ns * 1e-9)


class LazyInput:
    """The last good input of one topic (`plan_request.Input`), converted from the newest
    message when asked (`get`): `convert(message)` gives the value or raises, and a message
    that does not convert goes to `rejected(exception, received)` while the last good input
    stays the input."""

    def __init__(self, latest: Latest, convert: Callable[[Any], Any],
                 rejected: Callable[[Exception, float], None]):
        self.latest, self._convert, self._rejected = latest, convert, rejected
        self._lock = threading.Lock()
        self._input: Input | None = None
        self._seen: Any = None
        """The message converted (or refused) last: the next `get` converts only a newer."""

    def get(self) -> Input | None:
        taken = self.latest.take()
        with self._lock:
            if taken is None or taken[0] is self._seen:
                return self._input
            message, received = taken
            self._seen = message
            try:
                value = self._convert(message)
            except Exception as exc:  # noqa: BLE001 - bad input never stops the node
                self._rejected(exc, received)
                return self._input
            self._input = Input(value, message, received)
            return self._input
