"""What every planner shares: the `Planner` protocol, the options base, the result, the outcome
codes and the reasons a propagation stops (STYLE 12: one planner interface).

A planner is built from the models and its options, `Planner(scene, options, physics)`, and
answers `plan(start, seed, cancel, progress, iteration_gate) -> PlanResult`. The registry
(`planning.registry`) maps names to planners; nothing else branches on a planner's name.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from dataclasses import dataclass
from enum import Enum
from typing import Any, Protocol, TypeVar

import numpy as np

from rearrangement_planner.model.scene import Scene
from rearrangement_planner.model.state import State
from rearrangement_planner.physics.step import Physics
from rearrangement_planner.planning.settings import Settings, setting

SUPERSEDED = "superseded: another tree of the race found a plan in fewer iterations"
"""The message of a tree that a race (`planning.parallel`) stopped because another won."""


class Outcome(str, Enum):
    """Planning outcome codes (DESIGN §4, modelled on Nav2)."""

    SUCCEEDED = "SUCCEEDED"
    START_INVALID = "START_INVALID"
    GOAL_INVALID = "GOAL_INVALID"
    TIMEOUT = "TIMEOUT"
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


_O = TypeVar("_O", bound="PlannerOptions")


@dataclass(frozen=True)
class PlannerOptions(Settings):
    """The settings every planner has; each planner's own options extend these."""

    time_limit: float = setting(30.0, low=0.001, high=86400.0)
    """Planning budget, s; running out is a TIMEOUT failure, never an approximate plan."""
    max_iterations: int = setting(1_000_000, low=1, high=2**31 - 1)
    """Iteration budget (a TIMEOUT when exhausted)."""
    goal_bias: float = setting(0.2, low=0.0, high=1.0)
    """Probability of sampling the goal object inside the goal region."""
    goal_margin: float = setting(0.05, low=0.0, high=0.5)
    """How far inside its goal region the goal object must end, m: a plan is found when the
    object's centre is within radius - goal_margin of the goal point (DESIGN §6 "goal margin":
    open-loop execution never reproduces the prediction exactly, so a plan ending on the
    region's edge misses it; 0.05 by the executed success in MuJoCo, docs/benchmark.md
    "Executed"). 0 = on entering the region, as in the paper."""
    tipping: bool = setting(True)
    """Refuse a push that would tip an object over (the quasistatic tipping condition,
    `physics.step.tips_over`: push height, support friction, footprint along the push), so
    plans slide objects rather than topple them (on: no plan toppled an object in MuJoCo,
    docs/benchmark.md "Executed"). Off = objects never tip, as in King et al.
    (`PhysicsOptions(tipping=True)` given with the physics switches it on too.)"""
    tipping_margin: float = setting(0.0, low=0.0, high=2.0)
    """With `tipping`, refuse a push that would tip its object were the support friction this
    share higher (`PhysicsOptions.tipping_margin`; 0.3 = x1.3, the top of the friction range
    the perturbed executions draw). 0 = the nominal condition."""
    edge_margin: float = setting(0.0, low=0.0, high=0.05)
    """Refuse a push whose contact is within this distance (m) of the object's top edge or of
    a box's vertical edge with a normal set by the edge (`PhysicsOptions.edge_margin`): there
    the push depends on the exact shape of link and corner, and traced executions went
    elsewhere than predicted. Off by default: with 0.01 fewer plans reached the goal in MuJoCo
    (13/33 against 19/33, docs/benchmark.md "Session 13"). 0 = any contact, as in King et al."""
    top_clearance: float = setting(0.0, low=0.0, high=0.1)
    """Refuse a step in which a link comes within this distance (m) of an object's top from
    above or over its rim (`PhysicsOptions.top_clearance`): a link sweeping just over an
    object, or grazing its rim, tips it in the real arm. 0 = off, as in King et al."""
    max_turn: float = setting(5.0, low=0.0, high=1000.0)
    """Refuse a push that turns its object by more than this many radians per metre of its
    travel (`PhysicsOptions.max_turn`): how fast an off-centre push turns an object is what
    the quasistatic model predicts worst, and a turn mispredicted sends every later push of
    the plan elsewhere. 5 by executed success in MuJoCo: 47 of 105 benchmark requests reached
    the goal, against 38 with no limit, though 86 were solved in the model against 97
    (docs/benchmark.md "Session 13"). 0 = off, as in King et al."""
    dt: float = setting(0.1, low=0.001, high=1.0)
    """Propagation step, s (Δt of Algorithm 2 of King et al.)."""
    progress_period: float = setting(0.25, low=0.0, high=60.0)
    """Seconds between progress reports."""
    trees: int = setting(1, low=1, high=64)
    """Independent trees grown at once on separate processes, the plan found in the fewest
    iterations winning (`planning.parallel`, OR-parallel RRT); 1 = one tree in this process.
    Honoured by `plan_scene` (the CLI, the node and the benchmarks), not by `plan()` itself."""

    def goal_radius(self, scene: Scene) -> float:
        """The radius (m) a plan must bring the goal object within: the region's less the
        margin."""
        return scene.goal.radius - self.goal_margin

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


def planning_physics(scene: Scene, options: PlannerOptions,
                     physics: Physics | None = None) -> Physics:
    """The physics a planner plans in: `physics` (default the scene's), with the tipping check
    on when the options' `tipping` or the physics' own options say so, the larger of the two
    tipping margins, of the two edge margins and of the two top clearances, and the tighter of
    the two turn limits."""
    base = physics or Physics(scene)
    given = base.options
    wanted: dict[str, Any] = dict(
        tipping=given.tipping or options.tipping,
        tipping_margin=max(given.tipping_margin, options.tipping_margin),
        edge_margin=max(given.edge_margin, options.edge_margin),
        top_clearance=max(given.top_clearance, options.top_clearance),
        max_turn=min((t for t in (given.max_turn, options.max_turn) if t > 0), default=0.0))
    if all(getattr(given, name) == value for name, value in wanted.items()):
        return base
    return Physics(base.scene, dataclasses.replace(given, **wanted), base.robot)


@dataclass(frozen=True)
class Progress:
    iterations: int
    tree_size: int
    best_goal_distance: float
    elapsed: float


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


class CancelFlag(Protocol):
    """What a planner needs of a cancel request: `threading.Event` is one."""

    def is_set(self) -> bool: ...


ProgressCallback = Callable[[Progress], None]
IterationGate = Callable[[int], bool]


class Planner(Protocol):
    """The one planner interface."""

    name: str

    def __init__(self, scene: Scene, options: PlannerOptions | None = None,
                 physics: Physics | None = None) -> None: ...

    def plan(self, start: State | None = None, seed: int = 0,
             cancel: CancelFlag | None = None,
             progress: ProgressCallback | None = None,
             iteration_gate: IterationGate | None = None) -> PlanResult:
        """Plan from `start` (default the scene's initial state) with all randomness from
        `seed`. `cancel` is checked every iteration and every propagation step;
        `iteration_gate(i)`, asked before iteration i, ends the plan as CANCELLED when False."""
        ...
