"""Robust plans (the future work of King et al. 2015 and Haustein et al. 2018, after Koval,
King et al., "Robust trajectory selection for rearrangement planning as a multi-armed bandit
problem", IROS 2015): an open-loop plan is only as good as the share of slightly different worlds in
which it still works. `robustness` replays a plan's arm path in N perturbed copies of the
scene (object poses, frictions, masses, the arm's contact shapes grown or shrunk a few mm:
`model.perturbation`) through the planner's own quasistatic physics and counts the rollouts
that stay valid and end with the goal object in its goal region. `pipeline.plan_scene` uses it
to accept a candidate plan only at `min_robustness`, or to keep the best of several
candidates: the most robust, less `travel_penalty` for each metre its goal object is pushed
(`goal_travel`).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from rearrangement_planner.model.perturbation import Perturbation
from rearrangement_planner.model.scene import Scene
from rearrangement_planner.model.settings import Settings, setting
from rearrangement_planner.model.state import State
from rearrangement_planner.physics.options import PhysicsOptions
from rearrangement_planner.physics.step import Physics
from rearrangement_planner.planning.propagation import replay


@dataclass(frozen=True)
class RobustOptions(Settings):
    """Robust selection among candidate plans (a plan request's; `pipeline.robust_search`)."""

    min_robustness: float = setting(1.0, low=0.0, high=1.0)
    """A plan is judged by the share of `rollouts` perturbed worlds (object poses 5 mm / 2 deg,
    friction x0.7-1.3, mass x0.8-1.2, the arm's contact shapes +-5 mm) in which it reaches the
    goal in the planner's physics. The first candidate reaching min_robustness answers; else
    up to `candidates` are planned within the time limit and the best ranked answers
    (`accept_best`) or the request fails. 0 = the first plan, unchecked. Results:
    docs/benchmark.md."""
    rollouts: int = setting(20, low=1, high=1000)
    """Perturbed rollouts per candidate plan (with min_robustness > 0)."""
    candidates: int = setting(3, low=1, high=20)
    """Most candidate plans for min_robustness, all within the one time limit (a hard scene's
    searches use it up after one or two)."""
    travel_penalty: float = setting(0.5, low=0.0, high=100.0)
    """Candidates are ranked by robustness less this much per metre their goal object is
    pushed (`goal_travel`): the model's error grows along every push, so of two nearly equally
    robust plans the shorter push is the safer. 0 = the most robust."""
    accept_best: bool = setting(True)
    """When no candidate reaches min_robustness, answer with the best ranked one (its
    robustness reported) instead of failing: a request then fails only when no plan is found
    at all."""


ROLLOUT_PERTURBATION = Perturbation(pressure=(1.0, 1.0), centre_offset=0.0)
"""The rollouts' perturbed worlds: every object's support pressure nominal."""

FIRST_PLAN = RobustOptions(min_robustness=0.0)
"""A request answered by the first plan found, unchecked."""

ROLLOUT_PENETRATION_TOLERANCE = 0.01
"""Residual arm-object penetration (m) a perturbed rollout tolerates (see `robustness`)."""


def rollout_reaches(scene: Scene, arm_path: np.ndarray, physics_options: PhysicsOptions) -> bool:
    """Whether `arm_path` (the first configuration the start), replayed in `scene`, stays
    valid from start to end and leaves the goal object inside its goal region."""
    physics = Physics(scene, physics_options)
    start = State(np.asarray(arm_path[0], dtype=float), scene.object_poses)
    if physics.check_state(start) is not None:
        return False
    states, problem = replay(physics, start, arm_path)
    if problem:
        return False
    return scene.goal.reached(states[-1].objects[scene.goal_index, :2])


def goal_travel(scene: Scene, states: Sequence[State]) -> float:
    """How far (m) the plan `states` push the goal object, summed along its path on the table.
    The model's error grows with every push (turns and long pushes are where it loses the
    object; docs/experiments.md), so of two equally robust plans the one that moves the goal
    object less is the safer one to execute open loop."""
    path = np.array([s.objects[scene.goal_index, :2] for s in states])
    return float(np.linalg.norm(np.diff(path, axis=0), axis=1).sum())


def candidate_rank(score: float, travel: float, travel_penalty: float) -> float:
    """How robust selection ranks a candidate plan that is not robust enough to answer at
    once: its robustness `score` less `travel_penalty` per metre it pushes the goal object
    (`travel`, `goal_travel`)."""
    return score - travel_penalty * travel


def rollout_options(options: PhysicsOptions) -> PhysicsOptions:
    """The physics options a rollout judges a plan with, from the planner's.

    A perturbed object meets the arm a few mm from where the plan had it: the arm then ends a
    step up to a few mm inside it, which the planner's 3 mm residual check would call an
    invalid step although the object is simply pushed. Rollouts judge the goal, not that. The
    turn limit chooses which pushes the planner may plan with; a perturbed world that turns an
    object a little faster does not fail the plan."""
    return dataclasses.replace(options, penetration_tolerance=max(
        options.penetration_tolerance, ROLLOUT_PENETRATION_TOLERANCE), max_turn=0.0)


def robustness(scene: Scene, states: Sequence[State], rollouts: int, seed: int,
               perturbation: Perturbation | None = None,
               physics_options: PhysicsOptions | None = None) -> float:
    """The share (0..1) of `rollouts` perturbed worlds, drawn from `seed`, in which the plan
    `states` (its arm path) reaches the goal."""
    if rollouts < 1:
        raise ValueError(f"rollouts must be >= 1, got {rollouts}")
    rng = np.random.default_rng(seed)
    perturbation = perturbation or ROLLOUT_PERTURBATION
    options = rollout_options(physics_options or PhysicsOptions())
    arm_path = np.array([s.q for s in states])
    reached = sum(rollout_reaches(perturbation.apply(scene, rng), arm_path, options)
                  for _ in range(rollouts))
    return reached / rollouts
