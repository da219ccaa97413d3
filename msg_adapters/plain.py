"""Plain message data (`rearrangement_planner.io.messages`: dicts in the ROS message layouts)
to rclpy message objects, and back for stamps: the one generic conversion the node's
publishers need, so that what is published and what is recorded come from the same builders."""

from __future__ import annotations

import importlib
from collections.abc import Mapping
from functools import cache
from typing import Any, TypeVar

from builtin_interfaces.msg import Time

M = TypeVar("M")


def from_plain(plain: Mapping[str, Any], msg_type: type[M]) -> M:
    """A `msg_type` message with the fields of `plain` (nested messages and sequences of
    messages from nested dicts and lists of dicts; fields not in `plain` keep their defaults).
    Raises KeyError for a field the message does not have."""
    msg = msg_type()
    kinds = msg_type.get_fields_and_field_types()  # type: ignore[attr-defined]
    for name, value in plain.items():
        kind = kinds[name]
        if isinstance(value, Mapping):
            value = from_plain(value, type(getattr(msg, name)))
        elif kind.startswith("sequence<") and "/" in kind:
            item_type = _message_class(kind[len("sequence<"):-1])
            value = [from_plain(item, item_type) for item in value]
        setattr(msg, name, value)
    return msg


def time_to_plain(stamp: Time | None) -> dict[str, int] | None:
    """A builtin_interfaces/Time as plain data (None stays None: "stamp zero")."""
    return None if stamp is None else {"sec": stamp.sec, "nanosec": stamp.nanosec}


@cache
def _message_class(name: str) -> type:
    """The class of a message type named like 'geometry_msgs/Pose'."""
    package, _, message = name.partition("/")
    return getattr(importlib.import_module(f"{package}.msg"), message)
