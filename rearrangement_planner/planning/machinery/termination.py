"""When a search must stop: the one termination condition every search, propagation and
shortcut asks (after OMPL's `base::PlannerTerminationCondition`).

A `Termination` composes a deadline (`time.monotonic()`), a cancel flag, an iteration bound and
a race's gate (`planning.requests.parallel`: may this tree still win?). The pipeline builds one per
request from its time limit and the user's cancel, and hands parts of it on: `split` gives a
sub-budget that ends no later than its parent (a candidate of robust selection, a transit of
DARRT), `extended` one that runs a given time past it (shortcutting after a search). Every
sub-budget keeps its parent's cancel, so one cancel stops them all.

    stop = Termination.within(60.0, cancel=event)
    planner.plan(start, seed, stop)            # TIMEOUT, CANCELLED or PLANNING_FAILED when it ends
"""

from __future__ import annotations

import ctypes
import dataclasses
import math
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np
from numba import njit

from rearrangement_planner.planning.machinery.outcome import SUPERSEDED, Outcome, StopReason


class CancelFlag(Protocol):
    """What a search needs of a cancel request: `threading.Event` is one."""

    def is_set(self) -> bool: ...


IterationGate = Callable[[int], bool]
"""A race's gate: asked before iteration i, False ends the search (another tree won)."""


@dataclass(frozen=True)
class Termination:
    """A deadline, a cancel flag, an iteration bound and a gate, asked as one."""

    deadline: float = math.inf
    """`time.monotonic()` after which the search ends TIMEOUT."""
    cancel: CancelFlag | None = None
    max_iterations: int | None = None
    """Iterations (of a search; attempts of a shortcut) after which it ends PLANNING_FAILED."""
    gate: IterationGate | None = None
    time_limit: float = math.inf
    """The budget the deadline was set from (for messages)."""

    @classmethod
    def within(cls, seconds: float, cancel: CancelFlag | None = None,
               max_iterations: int | None = None) -> Termination:
        """Ends `seconds` from now, on `cancel`, or after `max_iterations`."""
        return cls(time.monotonic() + seconds, cancel, max_iterations, time_limit=seconds)

    def split(self, seconds: float, max_iterations: int | None = None) -> Termination:
        """A sub-budget: ends `seconds` from now or with this one, whichever is first; the same
        cancel and gate, its own iteration bound."""
        deadline = min(self.deadline, time.monotonic() + seconds)
        return dataclasses.replace(self, deadline=deadline, max_iterations=max_iterations,
                                   time_limit=min(seconds, self.remaining()))

    def extended(self, seconds: float, max_iterations: int | None = None) -> Termination:
        """What follows this budget: ends `seconds` after its deadline or `seconds` from now,
        whichever is first (shortcutting a plan found at any time gets at most `seconds`); the
        same cancel, no gate."""
        deadline = min(self.deadline + seconds, time.monotonic() + seconds)
        return Termination(deadline, self.cancel, max_iterations, time_limit=seconds)

    def gated(self, gate: IterationGate) -> Termination:
        return dataclasses.replace(self, gate=gate)

    def cancelled(self) -> bool:
        return self.cancel is not None and self.cancel.is_set()

    def expired(self) -> bool:
        return time.monotonic() > self.deadline

    def remaining(self) -> float:
        """Seconds left before the deadline (never negative)."""
        return max(self.deadline - time.monotonic(), 0.0)

    def interrupted(self) -> StopReason | None:
        """Between batches of propagation steps: CANCEL or TIMEOUT, else None."""
        if self.cancelled():
            return StopReason.CANCEL
        if self.expired():
            return StopReason.TIMEOUT
        return None

    def check(self, iterations: int) -> tuple[Outcome, str] | None:
        """Before iteration `iterations` + 1 (or an attempt): None to go on, else (outcome,
        message): CANCELLED on the cancel or the gate, TIMEOUT past the deadline,
        PLANNING_FAILED past the iteration bound."""
        if self.cancelled():
            return Outcome.CANCELLED, "cancelled"
        if self.expired():
            limit = "" if math.isinf(self.time_limit) else f"{self.time_limit:g} s / "
            return Outcome.TIMEOUT, f"no plan within {limit}{iterations} iterations"
        if self.max_iterations is not None and iterations >= self.max_iterations:
            return (Outcome.PLANNING_FAILED,
                    f"no plan within max_iterations {self.max_iterations}")
        if self.gate is not None and not self.gate(iterations + 1):
            return Outcome.CANCELLED, SUPERSEDED
        return None


NEVER = Termination()
"""A termination that never ends anything (warm-up, replays)."""


_MONOTONIC = time.CLOCK_MONOTONIC
CLOCK = ctypes.CDLL(None).clock_gettime
"""libc's clock_gettime, for compiled code that must read the deadline's clock itself (a
compiled PC-RRT iteration, `pcrrt_kernel`): passed as an argument, Numba calls it through
its pointer and the caller stays cacheable (a global ctypes function would not be)."""
CLOCK.argtypes = [ctypes.c_int, ctypes.c_void_p]
CLOCK.restype = ctypes.c_int


@njit(cache=True)
def monotonic(clock: Any, buffer: np.ndarray) -> float:
    """`time.monotonic()` in compiled code: `clock` is CLOCK, `buffer` two int64 (a timespec).
    On Linux both read CLOCK_MONOTONIC, so the result compares with `Termination.deadline`."""
    clock(_MONOTONIC, buffer.ctypes.data)
    return buffer[0] + buffer[1] * 1e-9

