"""The bookkeeping of one `plan()` call that every planner shares: the seeded generator, the
termination condition (`planning.machinery.termination`), progress reports, the counters, and the
results it ends with (Algorithm 1 of King et al. stops "on success, time limit, iteration limit
or cancel, checked every iteration", docs/design.md "Planners")."""

from __future__ import annotations

import math
import time
from collections.abc import Sequence

import numpy as np

from rearrangement_planner.model.state import State
from rearrangement_planner.physics.step import Physics
from rearrangement_planner.planning.machinery.interface import (
    Outcome,
    PlannerOptions,
    PlanResult,
    Progress,
    ProgressCallback,
)
from rearrangement_planner.planning.machinery.termination import Termination
from rearrangement_planner.planning.machinery.tree import Tree


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

    def check(self) -> PlanResult | None:
        """Before each iteration: the termination condition, then a progress report; a result
        ends the plan."""
        ended = self.termination.check(self.iterations)
        if ended is not None:
            return self.failure(*ended)
        now = time.monotonic()
        if self.progress is not None and now - self.last_report >= self.options.progress_period:
            self.progress(Progress(self.iterations, self.tree.n, self.best, now - self.t0))
            self.last_report = now
        return None

    def check_start(self, physics: Physics, start: State) -> PlanResult | None:
        """The checks every plan begins with; a result ends the plan: GOAL_INVALID when the
        goal margin leaves no region to reach, START_INVALID for an invalid start state,
        SUCCEEDED when the start is already in the goal. Sets `best`."""
        scene, seed = physics.scene, self.seed
        radius = self.options.goal_radius(scene)
        if radius <= 0.0:
            return PlanResult(Outcome.GOAL_INVALID, f"goal_margin {self.options.goal_margin:g} "
                                                    f"m leaves nothing of the goal region "
                                                    f"(radius {scene.goal.radius:g} m)", seed)
        problem = physics.check_state(start)
        if problem is not None:
            return PlanResult(Outcome.START_INVALID, f"start state invalid: {problem[1]}", seed)
        self.best = scene.goal.distance(start.objects[scene.goal_index, :2])
        if self.best <= radius:
            return PlanResult(Outcome.SUCCEEDED, "start already in the goal region", seed,
                              (start,), plan_time=self.elapsed(), best_goal_distance=self.best)
        return None

    def elapsed(self) -> float:
        return time.monotonic() - self.t0

    def success(self, states: Sequence[State], distance: float) -> PlanResult:
        return PlanResult(Outcome.SUCCEEDED, f"goal reached after {self.iterations} iterations",
                          self.seed, tuple(states), self.iterations, self.tree.n, self.steps,
                          self.elapsed(), distance)

    def failure(self, outcome: Outcome, message: str) -> PlanResult:
        return PlanResult(outcome, message, self.seed, (), self.iterations, self.tree.n,
                          self.steps, self.elapsed(), self.best)
