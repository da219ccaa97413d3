"""The closed loop in MuJoCo (docs/design.md "Closed loop"): execute a plan open loop, observe
where the arm and the objects ended, and, while the goal object is outside its region, nothing
toppled and re-plans remain, move the arm back out of contact (`planning.requests.retreat`), observe
again and plan from what is observed. The CLI (`--check-execution --replan N`) and the
benchmark (`--replan N`) run it; the ROS node runs the same loop against its controller.

    loop = execute_closed_loop(request, replans=2, world=perturbed_scene)
    loop.reached, loop.time_to_goal_s, [a.ended for a in loop.attempts]

The planner plans in `request.scene`, its nominal model; MuJoCo executes in `world` (the
same scene, or a perturbed copy: `Perturbation.apply`). Between two executions the MuJoCo
world is rebuilt at the observed planar poses (the objects have come to rest during the
execution's `hold`; a tilt below toppling is not carried over).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from rearrangement_planner.model.errors import SceneError
from rearrangement_planner.model.perturbation import Perturbation
from rearrangement_planner.model.scene import Scene
from rearrangement_planner.model.state import State
from rearrangement_planner.physics.validation import (
    SEPARATION_LIMIT,
    check_scene,
    separate_objects,
)
from rearrangement_planner.planning.machinery.interface import Outcome
from rearrangement_planner.planning.requests.pipeline import PlanOutput, plan_scene
from rearrangement_planner.planning.requests.request import PlanRequest
from rearrangement_planner.planning.requests.retreat import RETREAT_CLEARANCE, retreat_path
from rearrangement_planner.planning.requests.trajectory import time_parameterize
from rearrangement_planner.world3d.execution import (
    ExecutionReport,
    check_execution,
    perturbed_worlds,
)
from rearrangement_planner.world3d.mujoco_model import ExecutionOptions

# Why an attempt ended (`Attempt.ended`)
REACHED = "reached"              # the goal object is in its region, nothing toppled
TOPPLED = "toppled"              # an object toppled: no re-plan mends that
MISSED = "missed"                # the goal object is outside its region, upright
NOT_SOLVED = "not_solved"        # the plan failed; nothing was executed
NO_RETREAT = "no_retreat"        # no way back out of contact along the executed path
OBSERVED_INVALID = "observed_invalid"  # the observed scene is not a valid planning problem

CLOSING = 2
"""Re-plans past `replans` while each attempt closes in (`execute_closed_loop`), as the node's
parameter replan_closing."""
CLOSING_IN = 0.01
"""m: an attempt that leaves the goal object this much nearer its goal than the one before
closes in."""
FARTHER = 3 * RETREAT_CLEARANCE
"""m: how clear the second retreat leaves the arm after a re-plan was refused its start."""


@dataclass(frozen=True)
class Attempt:
    """One plan and its execution: the first, or a re-plan after a retreat."""

    plan: PlanOutput
    execution: ExecutionReport | None
    """None when the plan failed."""
    retreat_s: float
    """Trajectory time of the retreat executed before this plan was made (0 for the first)."""
    ended: str
    detail: str = ""

    @property
    def trajectory_s(self) -> float:
        """The trajectory time executed (up to where the watch stopped it)."""
        trajectory, report = self.plan.trajectory, self.execution
        if report is not None and report.stopped:
            return report.stopped_at_s
        return trajectory.duration if trajectory is not None else 0.0

    def to_dict(self) -> dict[str, Any]:
        report = self.execution
        return {"plan_outcome": self.plan.result.outcome.value,
                "plan_time_s": self.plan.result.plan_time,
                "robustness": self.plan.robustness,
                "retreat_s": self.retreat_s,
                "trajectory_s": self.trajectory_s,
                "goal_distance_m": report.goal_distance_m if report else None,
                "toppled": list(report.toppled) if report else [],
                "ended": self.ended, "detail": self.detail}


@dataclass(frozen=True)
class ClosedLoop:
    """Every attempt of one request, in order."""

    attempts: tuple[Attempt, ...]

    @property
    def reached(self) -> bool:
        return self.attempts[-1].ended == REACHED

    @property
    def replans(self) -> int:
        return len(self.attempts) - 1

    @property
    def time_to_goal_s(self) -> float:
        """All plan times, retreats and trajectories (trajectory time), reached or not."""
        return sum(a.plan.result.plan_time + a.retreat_s + a.trajectory_s for a in self.attempts)

    def to_dict(self) -> dict[str, Any]:
        """The CLI's JSON: `executions` (one entry per attempt) and the final `verdict`."""
        return {"executions": [a.to_dict() for a in self.attempts],
                "verdict": self.attempts[-1].ended, "replans": self.replans,
                "time_to_goal_s": self.time_to_goal_s}


def execute_closed_loop(request: PlanRequest, replans: int, world: Scene | None = None,
                        options: ExecutionOptions | None = None,
                        first: PlanOutput | None = None,
                        plan: Callable[[PlanRequest], PlanOutput] = plan_scene,
                        executed: ExecutionReport | None = None,
                        closing: int = CLOSING) -> ClosedLoop:
    """Plan `request` (or take `first`, its plan), execute it in `world` (default: the
    request's scene) with the servo arm (or take `executed`, that execution of `first`), and
    re-plan from the observed state up to `replans` times, and up to `closing` more while each
    attempt leaves the goal object CLOSING_IN nearer its goal, while the goal is missed with
    nothing toppled (module doc). `options.divergence_bound` > 0 watches each execution of a
    plan (`ExecutionOptions`): a stopped one is observed and re-planned like a miss."""
    options = options or ExecutionOptions(arm="servo")
    world = world if world is not None else request.scene
    output = first if first is not None else plan(request)
    attempts: list[Attempt] = []
    retreat_s = 0.0
    while True:
        if output.trajectory is None:
            attempts.append(Attempt(output, None, retreat_s, NOT_SOLVED, output.result.message))
            break
        report = executed if executed is not None and not attempts else check_execution(
            world, output.trajectory, output.trajectory_states, options)
        ended = (REACHED if report.reached else TOPPLED if report.toppled else MISSED)
        attempts.append(Attempt(output, report, retreat_s, ended,
                                f"stopped: {report.stopped}" if report.stopped else ""))
        distances = [a.execution.goal_distance_m if a.execution is not None else None
                     for a in attempts]
        if ended != MISSED or not replans_left(distances, replans, closing):
            break
        following = _following(request, world, report.final_state(),
                               output.trajectory.positions, options, plan)
        if isinstance(following[0], str):
            attempts[-1] = dataclasses.replace(attempts[-1], ended=following[0],
                                               detail=str(following[1]))
            break
        request, world, output, retreat_s = following    # type: ignore[assignment]
    return ClosedLoop(tuple(attempts))


def replans_left(distances: Sequence[float | None], replans: int, closing: int) -> bool:
    """Another re-plan after the attempts that left the goal object `distances` from its goal
    (one an attempt, the newest last; None: not executed): within `replans`, or within `closing`
    more while the newest left it CLOSING_IN nearer than the one before (this loop's and the
    node's, `ros.replan`)."""
    made = len(distances) - 1
    if made < replans:
        return True
    last = list(distances[-2:])
    nearer = (len(last) == 2 and last[0] is not None and last[1] is not None
              and last[0] - last[1] >= CLOSING_IN)
    return nearer and made < replans + closing


def _following(request: PlanRequest, world: Scene, state: State, path: Any,
               options: ExecutionOptions, plan: Callable[[PlanRequest], PlanOutput]
               ) -> tuple[PlanRequest, Scene, PlanOutput, float] | tuple[str, str]:
    """The next attempt after an execution that left the arm and objects at `state` (its arm
    `path`): the retreat executed in `world`, the request from the observed state and its plan;
    a plan refused its start there gets a second retreat, FARTHER, and one more plan. Or
    (ended, why) when there is no retreat or the observed state is no start."""
    retreat_s = 0.0
    for clearance in (RETREAT_CLEARANCE, FARTHER):
        observed, seconds, problem = _retreat(request.scene, world, state, path,
                                              request.timing, options, clearance)
        if observed is None:
            return NO_RETREAT, problem
        retreat_s += seconds
        try:
            scene = request.scene.with_start(request.scene.robot.clamped(observed.q),
                                             _apart(request.scene, observed))
            check_scene(scene)
        except SceneError as exc:
            return OBSERVED_INVALID, str(exc)
        world, state = world.with_start(observed.q, observed.objects), observed
        following = dataclasses.replace(request, scene=scene, start=None)
        output = plan(following)
        if output.result.outcome is not Outcome.START_INVALID:
            break
    return following, world, output, retreat_s


def perturbed_closed_loops(request: PlanRequest, first: PlanOutput, trials: int, seed: int,
                           replans: int, perturbation: Perturbation | None = None,
                           options: ExecutionOptions | None = None,
                           executed: Sequence[ExecutionReport] = ()) -> tuple[ClosedLoop, ...]:
    """The closed loop of `first` (the plan of `request`) in `trials` MuJoCo worlds perturbed
    as `check_perturbed` draws them from `seed`: the same worlds, so each loop's first attempt
    is that open-loop execution (`executed`: those executions, already made)."""
    worlds = perturbed_worlds(request.scene, trials, seed, perturbation)
    done: list[ExecutionReport | None] = [*executed, *[None] * (trials - len(executed))]
    return tuple(execute_closed_loop(request, replans, world, options, first, executed=report)
                 for world, report in zip(worlds, done, strict=True))


def _apart(scene: Scene, observed: State) -> np.ndarray:
    """The observed object poses with touching objects moved apart (`separate_objects`)."""
    apart = separate_objects(scene, observed.objects)
    if apart is None:
        raise SceneError("objects", f"the observed objects overlap by more than "
                                    f"{SEPARATION_LIMIT:g} m")
    return apart


def _retreat(scene: Scene, world: Scene, observed: State, path: Any, timing: Any,
             options: ExecutionOptions, clearance: float = RETREAT_CLEARANCE
             ) -> tuple[State | None, float, str]:
    """The retreat from `observed` (where an execution left the arm and the objects) until the
    arm stands `clearance` m clear, planned in the model at the observed poses and executed in
    `world`: (the state observed after it, its duration, ""), or (None, 0, why)."""
    moves = retreat_path(scene.with_start(observed.q, observed.objects), observed, path,
                         clearance)
    if moves is None:
        return None, 0.0, "no retreat out of contact is clear of the objects"
    if len(moves) == 1:
        return observed, 0.0, ""
    trajectory = time_parameterize(scene.robot, moves, timing)
    back = check_execution(world.with_start(observed.q, observed.objects), trajectory, None,
                           dataclasses.replace(options, divergence_bound=0.0))
    if back.toppled:
        return None, 0.0, f"the retreat toppled {', '.join(back.toppled)}"
    return back.final_state(), trajectory.duration, ""
