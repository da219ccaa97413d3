"""The bookkeeping of one `plan()` call that every planner shares: the seeded generator, the
termination condition (`planning.machinery.termination`), progress reports, the counters, and the
results it ends with (Algorithm 1 of King et al. stops "on success, time limit, iteration limit
or cancel, checked every iteration", docs/design.md "Planners")."""

from __future__ import annotations

import math
import time
from collections import Counter
from collections.abc import Sequence

import numpy as np

from rearrangement_planner.model.state import State
from rearrangement_planner.physics.step import (
    Invalid,
    Physics,
    footprint_reach,
    tips_whichever_way,
)
from rearrangement_planner.planning.machinery.interface import (
    Outcome,
    PlannerOptions,
    PlanResult,
    Progress,
    ProgressCallback,
)
from rearrangement_planner.planning.machinery.propagation import Propagation
from rearrangement_planner.planning.machinery.termination import Termination
from rearrangement_planner.planning.machinery.tree import Tree

NEVER_NEARER = 1e-3
"""m: a goal object that came no nearer its goal point than this never moved towards it."""


def unpushable(physics: Physics) -> str | None:
    """Why the arm cannot push the scene's goal object, or None. With the model's `tipping`
    rule on, the arm pushes an object no lower than its pushing plane (the hand leads every
    push there: `push_posture.height`, or the object's top when it is lower). A goal object that
    tips there whichever way it slides (`tips_whichever_way`: a slim cylinder on a grippy
    table) could only be moved by another object pushed into it. Such plans are rare and miss
    when executed: in the 258 recorded benchmark requests of the two varied scenes where this
    holds, 23 plans were found and 2 reached the goal in MuJoCo, both under rules we do not
    ship (docs/experiments.md, 2026-11-29). So the request is refused at once instead of
    searching its whole budget."""
    scene = physics.scene
    if not physics.options.tipping:
        return None
    goal = scene.objects[scene.goal_index]
    height = min(physics.robot.config.push_posture.height, float(goal.size[2]))
    if not tips_whichever_way(goal, height):
        return None
    return (f"the goal object '{goal.name}' would tip over under any push of the arm: support "
            f"friction {goal.support_friction:g} x push height {height:.3f} m exceeds the "
            f"footprint's reach from its centre ({footprint_reach(goal):.3f} m) in every direction "
            f"(the tipping rule; `tipping` false plans without it)")


class Search:
    """One plan call: `check()` before every iteration; `success` / `failure` end it."""

    tree: Tree

    def __init__(self, options: PlannerOptions, seed: int, stop: Termination | None,
                 progress: ProgressCallback | None):
        self.options, self.seed, self.progress = options, seed, progress
        self.t0 = self.last_report = time.monotonic()
        self.termination = stop if stop is not None else options.termination()
        self.rng = np.random.default_rng(seed)
        self.iterations = self.steps = 0
        self.best = math.inf
        """The smallest goal distance (m) reached so far."""
        self.start_distance = math.inf
        """The goal object's distance (m) from its goal point at the start."""
        self.refused: Counter[str] = Counter()
        """The propagations the model cut short, by why (an `Invalid` value, "of the goal
        object" added to a rule that named it): what an unsolved search reports."""
        self.goal_index = -1

    def check(self) -> PlanResult | None:
        """Before each iteration: the termination condition, then a progress report; a result
        ends the plan."""
        ended = self.termination.check(self.iterations)
        if ended is not None:
            return self.failure(*ended)
        now = time.monotonic()
        if self.progress is not None and now - self.last_report >= self.options.progress_period:
            self.progress(Progress(self.iterations, self.tree.n, self.best, now - self.t0,
                                   self.goal_positions))
            self.last_report = now
        return None

    def goal_positions(self) -> np.ndarray:
        """The goal object's (x, y) at every node of the tree so far (`Progress`)."""
        return self.tree.objects[:self.tree.n, self.goal_index, :2].copy()

    def check_start(self, physics: Physics, start: State, pushes: bool = True
                    ) -> PlanResult | None:
        """The checks every plan begins with; a result ends the plan: GOAL_INVALID when the
        goal margin leaves no region to reach, START_INVALID for an invalid start state,
        SUCCEEDED when the start is already in the goal, and, for a planner that `pushes` the
        goal object, GOAL_INVALID when the model's tipping rule leaves the arm no push that
        moves it (`unpushable`). Sets `best`."""
        scene, seed = physics.scene, self.seed
        radius = self.options.goal_radius(scene)
        if radius <= 0.0:
            return PlanResult(Outcome.GOAL_INVALID, f"goal_margin {self.options.goal_margin:g} "
                                                    f"m leaves nothing of the goal region "
                                                    f"(radius {scene.goal.radius:g} m)", seed)
        problem = physics.check_state(start)
        if problem is not None:
            return PlanResult(Outcome.START_INVALID, f"start state invalid: {problem[1]}", seed)
        self.goal_index = scene.goal_index
        self.best = self.start_distance = scene.goal.distance(
            start.objects[scene.goal_index, :2])
        if self.best <= radius:
            return PlanResult(Outcome.SUCCEEDED, "start already in the goal region", seed,
                              (start,), plan_time=self.elapsed(), best_goal_distance=self.best)
        why = unpushable(physics) if pushes else None
        if why is not None:
            return PlanResult(Outcome.GOAL_INVALID, why, seed, best_goal_distance=self.best)
        return None

    def propagated(self, result: Propagation) -> None:
        """Count a propagation's steps and, when the model cut it short, why."""
        self.steps += result.count
        if isinstance(result.stopped, Invalid):
            whose = " of the goal object" if result.subject == self.goal_index >= 0 else ""
            self.refused[result.stopped.value + whose] += 1

    def count(self, steps: int, refused: np.ndarray) -> None:
        """`propagated` of many propagations at once: their steps, and refused[code, whose]
        the ones `Physics.reason(code)` cut short (whose 1: the rule named the goal object),
        which it zeroes."""
        self.steps += steps
        for code, whose in zip(*refused.nonzero(), strict=True):
            suffix = " of the goal object" if whose else ""
            self.refused[Physics.reason(int(code)).value + suffix] += int(refused[code, whose])
        refused[:] = 0

    def why_unsolved(self) -> str:
        """What a search that ends without a plan saw, for its message: how near the goal
        object came to its goal point, and the commonest reasons the model cut its
        propagations short (a goal object that never moves while most are cut for
        `object_would_tip` tips under every push the arm can make, as a slim cylinder does)."""
        parts = []
        if math.isfinite(self.start_distance):
            if self.best >= self.start_distance - NEVER_NEARER:
                parts.append(f"the goal object never came nearer its goal point than its start, "
                             f"{self.start_distance:.2f} m away")
            else:
                parts.append(f"the goal object came within {self.best:.2f} m of its goal point "
                             f"(from {self.start_distance:.2f} m)")
        total = sum(self.refused.values())
        if total:
            shares = ", ".join(f"{reason} {count / total:.0%}"
                               for reason, count in self.refused.most_common(3))
            parts.append(f"of the {total} propagations the model cut short: {shares}")
        return "".join(f"; {part}" for part in parts)

    def elapsed(self) -> float:
        return time.monotonic() - self.t0

    def success(self, states: Sequence[State], distance: float) -> PlanResult:
        return PlanResult(Outcome.SUCCEEDED, f"goal reached after {self.iterations} iterations",
                          self.seed, tuple(states), self.iterations, self.tree.n, self.steps,
                          self.elapsed(), distance)

    def failure(self, outcome: Outcome, message: str) -> PlanResult:
        """The search ended without a plan; one that ran out of budget says what it saw."""
        if outcome in (Outcome.TIMEOUT, Outcome.PLANNING_FAILED):
            message += self.why_unsolved()
        return PlanResult(outcome, message, self.seed, (), self.iterations, self.tree.n,
                          self.steps, self.elapsed(), self.best)
