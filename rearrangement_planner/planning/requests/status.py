"""What the planner is doing right now (docs/design.md, the `~/status` topic), as a plain value.

The node fills a `PlannerStatus` from the planner's progress callback and its result; the
msg_adapters turn it into a `diagnostic_msgs/DiagnosticArray` and back. Nothing here knows ROS.
"""

from __future__ import annotations

import math
import operator
from dataclasses import dataclass

STATES = ("idle", "planning", "succeeded", "failed", "cancelled")
"""The planner's states, in the order a plan passes through them (the last three end a plan)."""


@dataclass(frozen=True)
class PlannerStatus:
    """A snapshot of the planner, published at >= 2 Hz while planning (docs/design.md)."""

    state: str
    """One of `STATES`: 'idle' | 'planning' | 'succeeded' | 'failed' | 'cancelled'."""
    message: str = ""
    """One human-readable line, e.g. the planner's result message or why a request was refused."""
    outcome: str = ""
    """The outcome code of the last plan (SUCCEEDED, TIMEOUT, NO_STATE, ...; docs/design.md),
    or '' while none has ended."""
    plan_id: str = ""
    """Identifier of the current or last plan ('' before the first)."""
    iterations: int = 0
    """Planner iterations so far (Algorithm 1 of King et al.)."""
    tree_size: int = 0
    """Nodes in the search tree so far."""
    best_goal_distance: float = math.inf
    """Smallest distance (m) of the goal object's centre from the goal point over the tree;
    inf before any state has been evaluated."""
    elapsed: float = 0.0
    """Wall-clock time (s) since the plan started."""
    fragile: bool = False
    """The last plan succeeded but is fragile: its robustness is below fragile_below
    (`PlanOutput.fragile`)."""

    def __post_init__(self) -> None:
        if self.state not in STATES:
            raise ValueError(f"state {self.state!r} is not a planner state; use one of "
                             f"{', '.join(STATES)}")
        if not isinstance(self.fragile, bool):
            raise ValueError(f"fragile must be a bool, got {self.fragile!r}")
        for name in ("message", "outcome", "plan_id"):
            if not isinstance(getattr(self, name), str):
                raise ValueError(f"{name} must be a str, got {getattr(self, name)!r}")
        for name in ("iterations", "tree_size"):
            value = operator.index(getattr(self, name))  # ints incl. numpy ints, never floats
            if value < 0:
                raise ValueError(f"{name} must be >= 0, got {value}")
            object.__setattr__(self, name, int(value))
        for name in ("best_goal_distance", "elapsed"):
            number = float(getattr(self, name))
            if not number >= 0.0:  # also rejects NaN
                raise ValueError(f"{name} must be >= 0, got {number}")
            object.__setattr__(self, name, number)

    @property
    def finished(self) -> bool:
        """Whether the state ends a plan (succeeded, failed or cancelled)."""
        return self.state in ("succeeded", "failed", "cancelled")
