"""Robust plans (DESIGN §6; the future work of both source papers, after Koval, King et al.,
"Robust trajectory selection for rearrangement planning as a multi-armed bandit problem",
IROS 2015): an open-loop plan is only as good as the share of slightly different worlds in
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

import numpy as np

from rearrangement_planner.model.perturbation import Perturbation
from rearrangement_planner.model.scene import Scene
from rearrangement_planner.model.state import State
from rearrangement_planner.physics.step import Physics, PhysicsOptions
from rearrangement_planner.planning.propagation import replay

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
    The model's error grows with every push (docs/benchmark.md "Session 13": turns and long
    pushes are where it loses the object), so of two equally robust plans the one that moves
    the goal object less is the safer one to execute open loop."""
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
    edge margin, the top clearance, the turn limit and the tipping margin choose which pushes
    and passes the planner may plan with; a perturbed world that turns an object a little
    faster does not fail the plan, and each rollout draws its own friction for the tipping
    check."""
    return dataclasses.replace(options, penetration_tolerance=max(
        options.penetration_tolerance, ROLLOUT_PENETRATION_TOLERANCE), edge_margin=0.0,
        top_clearance=0.0, max_turn=0.0, tipping_margin=0.0)


def robustness(scene: Scene, states: Sequence[State], rollouts: int, seed: int,
               perturbation: Perturbation | None = None,
               physics_options: PhysicsOptions | None = None) -> float:
    """The share (0..1) of `rollouts` perturbed worlds, drawn from `seed`, in which the plan
    `states` (its arm path) reaches the goal."""
    if rollouts < 1:
        raise ValueError(f"rollouts must be >= 1, got {rollouts}")
    rng = np.random.default_rng(seed)
    perturbation = perturbation or Perturbation()
    options = rollout_options(physics_options or PhysicsOptions())
    arm_path = np.array([s.q for s in states])
    reached = sum(rollout_reaches(perturbation.apply(scene, rng), arm_path, options)
                  for _ in range(rollouts))
    return reached / rollouts
