"""The node's closed loop (docs/design.md "Closed loop"): after an action goal's plan has been
executed, observe the object poses, and while the goal object is outside its region and
re-plans remain, move the arm back out of contact (`planning.requests.retreat`), plan again from the
observed joint state and object poses, and execute. The same loop in MuJoCo is
`execution.closed_loop` (the CLI's and the benchmark's).

What counts as observed: the first `~/object_poses` message received OBSERVE_SETTLE s after the
arm reached the plan's end (the objects have come to rest). A toppled object is not a pose the
node accepts (parameter max_object_tilt): its message is rejected, so no observation arrives,
and the loop ends NO_OBSERVATION with the rejection's reason. A pose that stops arriving (an
object the arm hides, a perception that stalls) is never taken for a pose that moved: the
loop waits up to OBSERVE_TIMEOUT s and then ends, and never re-plans from stale poses.

Watching during execution (`DivergenceWatch`, parameters divergence_bound and
max_object_tilt): the plan predicts every object's pose at every trajectory point. While a
trajectory runs, the arm's joint state says which point it has reached (the nearest one from
the last matched on, so time scaling and controller lag do not matter), and fresh object poses
(received within FRESH s) are compared with that point's prediction; an object farther than
the bound stops the arm (empty JointTrajectory) and the loop observes and re-plans from there.
Stale poses are not compared: an object the arm hides is not an object that strayed. An object
seen tilted past max_object_tilt has begun to tip: that stops the arm too, before it falls,
whatever divergence_bound says.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from msg_adapters import trajectory_to_msg
from rearrangement_planner.execution.closed_loop import FARTHER, replans_left
from rearrangement_planner.model.errors import ObjectTilted
from rearrangement_planner.model.scene import Scene
from rearrangement_planner.model.state import State
from rearrangement_planner.planning.machinery.interface import Outcome
from rearrangement_planner.planning.requests.pipeline import PlanOutput
from rearrangement_planner.planning.requests.retreat import RETREAT_CLEARANCE, retreat_path
from rearrangement_planner.planning.requests.trajectory import time_parameterize
from rearrangement_planner.ros.action import DIVERGED, GOAL_NOT_REACHED, NO_OBSERVATION

OBSERVE_SETTLE = 0.5
"""s after the arm reached a plan's end before object poses count as observed."""
OBSERVE_TIMEOUT = 5.0
"""s the loop waits for those poses after OBSERVE_SETTLE."""
FRESH = 0.5
"""s: object poses older than this are not compared with the prediction."""



class DivergenceWatch:
    """`action.execute`'s watch for one plan (module doc): `watch(q)` is None while no object
    has been seen tilted since the watch began (`tilted()`: (time.monotonic(), ObjectTilted) of
    the last object pose message rejected for a tilt, or None) and every object stays within
    `bound` m of a pose the plan predicts for it around the arm's progress (bound 0: not
    compared), else the sentence that says which began to tip or strayed. "Around": at any
    trajectory point the arm has passed since FRESH s before the object poses were received
    (the poses and the joint state arrive on different topics, each with its own delay).
    `shown(q, observed objects or None, predicted objects)` sees every step (the live view)."""

    def __init__(self, output: PlanOutput, bound: float,
                 objects: Callable[[], Any],
                 tilted: Callable[[], tuple[float, ObjectTilted] | None] = lambda: None,
                 shown: Callable[[np.ndarray, np.ndarray | None, np.ndarray], None]
                 | None = None):
        assert output.trajectory is not None
        self.path = output.trajectory.positions
        self.predicted = np.array([s.objects for s in output.trajectory_states])
        self.names = output.scene.object_names
        self.bound, self.objects, self.tilted, self.shown = bound, objects, tilted, shown
        self.began = time.monotonic()
        self.passed: list[tuple[float, int]] = [(-math.inf, 0)]
        """(time.monotonic(), point) of every match."""

    def __call__(self, q: np.ndarray) -> str | None:
        point = self.passed[-1][1]
        point += int(np.argmin(np.max(np.abs(self.path[point:] - q), axis=1)))
        self.passed.append((time.monotonic(), point))
        seen = self.objects()           # the newest poses, converted (or refused) now
        if self.shown is not None:      # the live view: the arm, the objects seen, predicted
            self.shown(q, seen.value if seen is not None else None, self.predicted[point])
        tilted = self.tilted()
        if tilted is not None and tilted[0] > self.began:
            tilt = tilted[1]
            return (f"'{tilt.object_id}' began to tip: seen tilted {tilt.tilt:.3f} rad "
                    f"(max_object_tilt {tilt.bound:g} rad) by trajectory point {point} of "
                    f"{len(self.path)}")
        if self.bound <= 0.0 or seen is None or time.monotonic() - seen.received > FRESH:
            return None
        since = max((p for t, p in self.passed if t <= seen.received - FRESH), default=0)
        window = self.predicted[since:point + 1, :, :2]               # (K, M, 2)
        errors = np.min(np.linalg.norm(window - seen.value[None, :, :2], axis=2), axis=0)
        worst = int(np.argmax(errors))
        if errors[worst] <= self.bound:
            return None
        return (f"'{self.names[worst]}' strayed {errors[worst]:.3f} m from its predicted path "
                f"by trajectory point {point} of {len(self.path)} (divergence_bound "
                f"{self.bound:g} m)")


def goal_watch(output: PlanOutput | None, attempts: int, bound: float,
               objects: Callable[[], Any],
               tilted: Callable[[], tuple[float, ObjectTilted] | None],
               shown: Callable[[np.ndarray, np.ndarray | None, np.ndarray], None] | None
               ) -> DivergenceWatch | None:
    """The watch over one execution of an action goal's plan `output`: with re-plans
    (`attempts` > 0), one that stops the arm on an object that tips or strays `bound` m; without,
    only the live view's (`shown`; None: no watch), which never stops the arm, since whether
    someone watches must not change what the arm does."""
    if output is None:
        return None
    if attempts > 0:
        return DivergenceWatch(output, bound, objects, tilted, shown)
    if shown is not None:
        return DivergenceWatch(output, 0.0, objects, shown=shown)
    return None


@dataclass
class Attempt:
    """One executed plan of the loop and what was observed after it."""

    plan_id: str
    observed: str = ""


@dataclass
class LoopIO:
    """What the loop needs of the node: the latest inputs (`Input` by key, as the node keeps
    them), the last rejection of an object pose message ((time.monotonic(), text) or None),
    `send_and_wait(msg, output) -> (outcome, message)` (`action.execute`, watching `output`
    unless None), `plan(attempt) -> (outcome, message, scene, output, inputs)`
    (`plan_request.run_plan` from the latest inputs) and `record(output, inputs, plan_id)`."""

    latest: Callable[[], dict[str, Any]]
    rejected: Callable[[], tuple[float, str] | None]
    send_and_wait: Callable[[Any, PlanOutput | None], tuple[str, str]]
    plan: Callable[[int], tuple[str, str, Scene, PlanOutput | None, dict[str, Any]]]
    record: Callable[[PlanOutput | None, dict[str, Any], str], None]


def close_the_loop(job: Any, io: LoopIO, scene: Scene, output: PlanOutput,
                   inputs: dict[str, Any], attempts: int, executed_at: float,
                   stopped: str = "", closing: int = 0) -> tuple[str, str, Scene,
                                                                 PlanOutput | None,
                                                                 dict[str, Any]]:
    """Observe after the executed `output` (executed at time.monotonic() `executed_at`;
    `stopped`: why its watch stopped it) and re-plan up to `attempts` times, and up to
    `closing` more while each attempt leaves the goal object 1 cm nearer its goal than
    the one before (module doc). Returns the last (outcome, message, scene, output, inputs);
    every attempt's line is in `job.attempts`."""
    job.attempts = [Attempt(job.plan_id, stopped + "; " if stopped else "")]
    distances: list[float] = []
    for k in range(1, attempts + closing + 2):
        job.phase = "observing"
        observed, problem = _observe(job, io, executed_at)
        if observed is None:
            return problem[0], problem[1], scene, output, inputs
        distance = scene.goal.distance(observed[scene.goal_index, :2])
        distances.append(distance)
        job.attempts[-1].observed += (f"'{scene.goal.object}' observed {distance:.3f} m from "
                                      f"the goal (radius {scene.goal.radius:g} m)")
        if distance <= scene.goal.radius:
            return (Outcome.SUCCEEDED.value, _lines(job) + f"; goal reached after {k - 1} "
                                                             f"re-plans", scene, output, inputs)
        if not replans_left(distances, attempts, closing):
            break
        io.record(output, inputs, f"{job.plan_id}-attempt{k}")
        ended, why = _retreat(job, io, scene, observed, output)
        if why:
            return ended, _lines(job) + f"; {why}", scene, output, inputs
        job.attempt, job.phase = k + 1, "planning"
        outcome, message, scene, new, inputs = io.plan(k + 1)
        if outcome == Outcome.START_INVALID.value:
            # refused where the retreat left the arm (no approach onto the pushing plane from
            # there, say): back out farther along the way it came, and plan once more
            ended, why = _retreat(job, io, scene, observed, output, FARTHER)
            if not why:
                outcome, message, scene, new, inputs = io.plan(k + 1)
        job.attempts.append(Attempt(f"{job.plan_id}-attempt{k + 1}"))
        if new is None or new.trajectory is None:
            job.attempts[-1].observed = f"re-plan {outcome}: {message}"
            return outcome, _lines(job), scene, new, inputs
        output = new          # executed even when fragile: the loop observes what it does
        job.phase = "executing"
        job.trajectory = trajectory_to_msg(new.trajectory)      # the answer's plan
        outcome, message = io.send_and_wait(job.trajectory, new)
        if outcome == DIVERGED:
            job.attempts[-1].observed = message + "; "
        elif outcome != Outcome.SUCCEEDED.value:
            return outcome, _lines(job) + f"; {message}", scene, output, inputs
        executed_at = time.monotonic()
    return (GOAL_NOT_REACHED, _lines(job) + f"; not reached after {len(distances) - 1} "
                                            f"re-plans", scene, output, inputs)


def _observe(job: Any, io: LoopIO, executed_at: float
             ) -> tuple[np.ndarray | None, tuple[str, str]]:
    """The object poses received OBSERVE_SETTLE s after `executed_at`, or why none came."""
    settled = executed_at + OBSERVE_SETTLE
    deadline = settled + OBSERVE_TIMEOUT
    while not job.cancel.wait(0.02):
        objects = io.latest()["object_poses"]
        if objects is not None and objects.received > settled:
            return objects.value, ("", "")
        if time.monotonic() > deadline:
            rejected = io.rejected()
            why = (f"; the last were rejected: {rejected[1]}"
                   if rejected is not None and rejected[0] > executed_at else "")
            return None, (NO_OBSERVATION, _lines(job) + f"; no object poses arrived within "
                                                        f"{OBSERVE_SETTLE + OBSERVE_TIMEOUT:g}"
                                                        f" s after the execution{why}")
    return None, (Outcome.CANCELLED.value, _lines(job) + "; cancelled while observing")


def _retreat(job: Any, io: LoopIO, scene: Scene, observed: np.ndarray,
             output: PlanOutput, clearance: float = RETREAT_CLEARANCE) -> tuple[str, str]:
    """Back the arm out of contact until it stands `clearance` m clear of every object
    (`planning.requests.retreat`; sent and waited for): ('', '') when it is clear, else the
    outcome and why the loop cannot go on."""
    assert output.trajectory is not None
    executed = output.trajectory.positions
    joints = io.latest()["joint_states"]
    q = joints.value if joints is not None else executed[-1]
    path = retreat_path(scene.with_start(q, observed), State(q, observed), executed, clearance)
    if path is None:
        return GOAL_NOT_REACHED, "no retreat out of contact is clear of the objects"
    if len(path) == 1:
        return "", ""
    job.phase = "retreating"
    outcome, message = io.send_and_wait(
        trajectory_to_msg(time_parameterize(scene.robot, path)), None)
    return ("", "") if outcome == Outcome.SUCCEEDED.value else (outcome, f"retreat: {message}")


def _lines(job: Any) -> str:
    """Every attempt so far: 'attempt 1 (plan ID): observed ...; attempt 2 ...'."""
    return "; ".join(f"attempt {i} ({a.plan_id}): {a.observed or 'not observed'}"
                     for i, a in enumerate(job.attempts, start=1))
