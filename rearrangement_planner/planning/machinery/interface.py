"""What every planner shares: the `Planner` protocol, the options base, the result, the outcome
codes and the reasons a propagation stops (one planner interface, like OMPL's
`base::Planner`).

A planner is built from the models and its options, `Planner(scene, options, physics)`, and
answers `plan(start, seed, stop, progress) -> PlanResult`, `stop` the one condition that ends
it (`planning.machinery.termination.Termination`: deadline, cancel, iteration bound, a race's
gate). The
registry (`planning.requests.registry`) maps names to planners; nothing else branches on a planner's
name.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol, TypeVar

import numpy as np

from rearrangement_planner.model.scene import Scene
from rearrangement_planner.model.settings import Settings, setting
from rearrangement_planner.model.state import State
from rearrangement_planner.physics.step import Physics
from rearrangement_planner.planning.machinery.outcome import SUPERSEDED, Outcome, StopReason
from rearrangement_planner.planning.machinery.termination import (
    CancelFlag,
    IterationGate,
    Termination,
)

__all__ = ["SUPERSEDED", "CancelFlag", "IterationGate", "Outcome", "StopReason", "Termination"]

_O = TypeVar("_O", bound="PlannerOptions")


@dataclass(frozen=True)
class PlannerOptions(Settings):
    """The settings every planner has; each planner's own options extend these."""

    time_limit: float = setting(60.0, low=0.001, high=86400.0)
    """Planning budget, s; running out is a TIMEOUT failure, never an approximate plan."""
    max_iterations: int = setting(1_000_000, low=1, high=2**31 - 1)
    """Iteration budget (PLANNING_FAILED when exhausted)."""
    goal_bias: float = setting(0.2, low=0.0, high=1.0)
    """Probability of sampling the goal object inside the goal region."""
    goal_margin: float = setting(0.05, low=0.0, high=0.5)
    """How far inside its goal region the goal object must end, m: a plan is found when the
    object's centre is within radius - goal_margin of the goal point. Open-loop execution never
    reproduces the prediction exactly, so a plan ending on the region's edge misses it
    (docs/experiments.md). 0 = on entering the region, as in King et al. 2015."""
    dt: float = setting(0.1, low=0.001, high=1.0)
    """Propagation step, s (Δt of Algorithm 2 of King et al. 2015)."""
    progress_period: float = setting(0.25, low=0.0, high=60.0)
    """Seconds between progress reports."""

    def goal_radius(self, scene: Scene) -> float:
        """The radius (m) a plan must bring the goal object within: the region's less the
        margin."""
        return scene.goal.radius - self.goal_margin

    def termination(self, cancel: CancelFlag | None = None) -> Termination:
        """A search's budget from now: `time_limit`, `max_iterations` and `cancel`."""
        return Termination.within(self.time_limit, cancel, self.max_iterations)

    @classmethod
    def adopt(cls: type[_O], options: PlannerOptions | None) -> _O:
        """`options` as this options type: itself if it is one, else its shared fields with
        the rest at their defaults (`PlannerOptions(time_limit=5)` for any planner)."""
        if isinstance(options, cls):
            return options
        if options is None:
            return cls()
        mine = {f.name for f in dataclasses.fields(cls)}
        return cls(**{f.name: getattr(options, f.name) for f in dataclasses.fields(options)
                      if f.name in mine})


@dataclass(frozen=True)
class PushingPlannerOptions(PlannerOptions):
    """The settings of the planners that push through the quasistatic physics (PC-RRT, the
    Static RRT, the slice-based RRT): the bounds of their actions and the weights of their
    object metric, one meaning each."""

    max_speed: float = setting(0.10, low=0.001, high=1.0)
    """Bound on each planar tool velocity component of an action, m/s."""
    nullspace_speed: float = setting(0.3, low=0.0, high=10.0)
    """Bound on each component of an action's nullspace joint velocity, rad/s."""
    object_weight: float = setting(1.0, low=0.0, high=1000.0)
    """w_i of the metric for the non-goal objects, per m."""
    goal_weight: float = setting(5.0, low=0.0, high=1000.0)
    """w_i of the metric for the goal object, per m."""


@dataclass(frozen=True)
class Progress:
    iterations: int
    tree_size: int
    best_goal_distance: float
    elapsed: float
    goal_positions: Callable[[], np.ndarray] | None = None
    """The goal object's (x, y) (m) at every node of the tree so far, (N, 2), computed when
    called (a live view asks; nothing else pays for it); None when the planner has no tree to
    show."""


@dataclass(frozen=True)
class PlanResult:
    outcome: Outcome
    message: str
    seed: int
    states: tuple[State, ...] = ()
    """Every propagation step of the plan, the start first (empty unless SUCCEEDED)."""
    iterations: int = 0
    tree_size: int = 0
    propagation_steps: int = 0
    plan_time: float = 0.0
    best_goal_distance: float = math.inf

    @property
    def solved(self) -> bool:
        return self.outcome is Outcome.SUCCEEDED

    @property
    def arm_path(self) -> np.ndarray:
        return np.array([s.q for s in self.states])


ProgressCallback = Callable[[Progress], None]


class Planner(Protocol):
    """The one planner interface."""

    name: str

    def __init__(self, scene: Scene, options: PlannerOptions | None = None,
                 physics: Physics | None = None) -> None: ...

    def plan(self, start: State | None = None, seed: int = 0, stop: Termination | None = None,
             progress: ProgressCallback | None = None) -> PlanResult:
        """Plan from `start` (default the scene's initial state) with all randomness from
        `seed`, until `stop` (default: the options' time_limit and max_iterations) ends it: it
        is asked before every iteration, its clock and cancel between batches of propagation
        steps."""
        ...
