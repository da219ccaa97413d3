"""How a plan ends: its outcome code, and why a propagation stopped early."""

from __future__ import annotations

from enum import Enum

SUPERSEDED = "superseded: another tree of the race found a plan in fewer iterations"
"""The message of a tree that a race (`planning.requests.parallel`) stopped because another won."""


class Outcome(str, Enum):
    """Planning outcome codes (modelled on Nav2's; docs/design.md)."""

    SUCCEEDED = "SUCCEEDED"
    START_INVALID = "START_INVALID"
    GOAL_INVALID = "GOAL_INVALID"
    TIMEOUT = "TIMEOUT"
    """The time limit passed before a plan was found."""
    PLANNING_FAILED = "PLANNING_FAILED"
    """The iteration budget (`max_iterations`) ran out before a plan was found."""
    CANCELLED = "CANCELLED"
    INVALID_INPUT = "INVALID_INPUT"
    INTERNAL = "INTERNAL"


class StopReason(str, Enum):
    """Why a propagation ended before its duration, other than an invalid step (`Invalid`)."""

    GOAL = "goal"
    """The goal object is in the goal region: the plan is found."""
    CANCEL = "cancel"
    """The request was cancelled."""
    TIMEOUT = "timeout"
    """The plan's time limit passed (an action is cut there, so no plan is found late)."""
