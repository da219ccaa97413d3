"""The one termination condition of a search (`planning.machinery.termination`)."""

from __future__ import annotations

import math
import threading
import time

import numpy as np

from rearrangement_planner.planning.machinery.interface import SUPERSEDED, Outcome, StopReason
from rearrangement_planner.planning.machinery.termination import (
    CLOCK,
    NEVER,
    Termination,
    monotonic,
)


def test_the_cancel_comes_first_then_the_clock_then_the_iterations_then_the_gate():
    flag = threading.Event()
    gate_asked: list[int] = []

    def gate(i: int) -> bool:
        gate_asked.append(i)
        return i < 5

    stop = Termination(time.monotonic() + 60.0, flag, 10, gate, 60.0)
    assert stop.check(3) is None and gate_asked == [4]
    assert stop.check(4) == (Outcome.CANCELLED, SUPERSEDED)
    assert stop.check(10)[0] is Outcome.PLANNING_FAILED
    assert "max_iterations 10" in stop.check(10)[1]
    late = Termination(time.monotonic() - 1.0, flag, 10, gate, 1.0)
    assert late.check(10) == (Outcome.TIMEOUT, "no plan within 1 s / 10 iterations")
    assert late.interrupted() is StopReason.TIMEOUT
    flag.set()
    assert late.check(0) == (Outcome.CANCELLED, "cancelled")
    assert late.interrupted() is StopReason.CANCEL


def test_a_split_ends_with_its_parent_and_keeps_its_cancel():
    flag = threading.Event()
    parent = Termination.within(10.0, flag, max_iterations=7)
    short = parent.split(1.0)
    assert short.deadline <= parent.deadline and short.remaining() <= 1.0
    assert short.max_iterations is None        # its own bound
    long = parent.split(100.0)
    assert long.deadline == parent.deadline
    flag.set()
    assert short.cancelled() and long.cancelled()


def test_an_extension_runs_at_most_its_seconds_past_the_parent():
    parent = Termination(time.monotonic() - 5.0, None, 3, lambda i: False, 1.0)
    after = parent.extended(10.0, max_iterations=40)
    assert after.remaining() <= 5.0 + 1e-6          # 10 s past a deadline 5 s ago
    assert after.gate is None and after.max_iterations == 40
    fresh = Termination.within(60.0).extended(2.0)
    assert 1.0 < fresh.remaining() <= 2.0           # at most its seconds from now


def test_never_ends_nothing():
    assert NEVER.check(10**9) is None and NEVER.interrupted() is None
    assert math.isinf(NEVER.remaining())


def test_compiled_code_reads_the_deadlines_clock():
    """`monotonic` (what a compiled PC-RRT iteration compares with the deadline) is
    `time.monotonic()`."""
    buffer = np.zeros(2, dtype=np.int64)
    before = time.monotonic()
    now = monotonic(CLOCK, buffer)
    after = time.monotonic()
    assert before - 1e-6 <= now <= after + 1e-6
