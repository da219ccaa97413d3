"""Robust plans (the future work of King et al. 2015 and Haustein et al. 2018, after Koval,
King et al., "Robust trajectory selection for rearrangement planning as a multi-armed bandit
problem", IROS 2015): an open-loop plan is only as good as the share of slightly different worlds in
which it still works. `robustness` replays a plan's arm path in N perturbed copies of the
scene (object poses, frictions, masses, how each object's weight rests on the table, the arm's
contact shapes grown or shrunk a few mm: `model.perturbation`) through the quasistatic physics
and counts the rollouts that end with the goal object in its goal region and nothing toppled:
the user's question. A rollout simulates what the planner's rules would refuse: objects that
meet push each other (`PhysicsOptions.object_contact`), a push may turn an object as fast as
it does, and a push that would tip an object topples it only if it carries it far enough while
it tips (`rollout_kernel`; `PhysicsOptions.tip_judgement`). `pipeline.plan_scene` uses it to
accept a candidate plan only at `min_robustness`, or to keep the best of several candidates:
the most robust, less `travel_penalty` for each metre its goal object is pushed
(`goal_travel`).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numba import njit

from rearrangement_planner.model.perturbation import Perturbation
from rearrangement_planner.model.scene import Scene
from rearrangement_planner.model.settings import Settings, setting
from rearrangement_planner.model.state import State
from rearrangement_planner.physics.options import PhysicsOptions
from rearrangement_planner.physics.step import Physics, step_kernel, step_workspace


@dataclass(frozen=True)
class RobustOptions(Settings):
    """Robust selection among candidate plans (a plan request's; `pipeline.robust_search`)."""

    min_robustness: float = setting(1.0, low=0.0, high=1.0)
    """A plan is judged by the share of `rollouts` perturbed worlds (object poses 5 mm / 2 deg,
    friction x0.7-1.3, mass x0.8-1.2, the arm's contact shapes +-5 mm) in which it reaches the
    goal in the planner's physics. The first candidate reaching min_robustness answers; else
    `candidates` (and `fragile_candidates` more for a fragile best) are planned within the
    time limit and the best ranked answers
    (`accept_best`) or the request fails. 0 = the first plan, unchecked. At 1, a second
    candidate is searched unless the first reached the goal in every rollout; whether an
    answer is fragile is `fragile_below`'s. Results: docs/benchmark.md."""
    rollouts: int = setting(20, low=1, high=1000)
    """Perturbed rollouts per candidate plan (with min_robustness > 0)."""
    candidates: int = setting(2, low=1, high=20)
    """Candidate plans for min_robustness, all within the one time limit (a hard scene's
    searches use it up after one or two); `fragile_candidates` more for a fragile best."""
    fragile_candidates: int = setting(3, low=0, high=20)
    """More candidates, beyond `candidates`, planned while the best so far reaches the goal in
    fewer than `fragile_below` of its rollouts (within the time limit and `candidate_effort`):
    a fragile best is worth another look, a sound one is not. The score is calibrated (a plan
    scored s reaches in about s of its perturbed executions), so a best below 0.3 is a plan
    that mostly misses. 0 = none. Measured: docs/experiments.md ("More candidates for a fragile
    best")."""
    fragile_below: float = setting(0.3, low=0.0, high=1.0)
    """The robustness below which a plan is fragile: the best candidate so far earns
    `fragile_candidates`, and an answer below it says FRAGILE and is not executed unless asked
    (`PlanOutput.fragile`). Measured: of 204 answers on varied and fixed seeds 0–2, the 37
    below 0.3 reached the goal in 11 nominal MuJoCo executions, the rest in 109 of 167
    (docs/experiments.md, "Plans that survive the world: the one protocol at the close")."""
    candidate_effort: float = setting(1.0, low=0.0, high=1000.0)
    """A candidate after the first may search at most this many times the iterations the
    first plan took (at least `MIN_CANDIDATE_ITERATIONS`), so a request does not spend its
    whole budget looking for a better plan than the one its first seconds gave; counted in
    iterations, so the answer does not depend on the machine's speed. 0 = only the time
    limit bounds them. Measured: docs/experiments.md ("A robust plan sooner")."""
    fragile_search_iterations: int = setting(10000, low=0, high=10**9)
    """Each of a fragile best's extra candidates (`fragile_candidates`) searches at most this
    many iterations, besides `candidate_effort`'s bound: the extra candidates that rescue a
    fragile best are mostly plans found quickly, and the long ones mostly find another
    fragile plan, on the scenes whose every search is long. Counted in iterations, so the
    answer does not depend on the machine's speed. 0 = only `candidate_effort` and the time
    limit bound them. Measured: docs/experiments.md ("A fragile best's extra candidates within
    10,000 iterations each")."""
    travel_penalty: float = setting(0.5, low=0.0, high=100.0)
    """Candidates are ranked by robustness less this much per metre their goal object is
    pushed (`goal_travel`): the model's error grows along every push, so of two nearly equally
    robust plans the shorter push is the safer. 0 = the most robust."""
    accept_best: bool = setting(True)
    """When no candidate reaches min_robustness, answer with the best ranked one (its
    robustness reported) instead of failing: a request then fails only when no plan is found
    at all."""


MIN_CANDIDATE_ITERATIONS = 100
"""The least iterations a candidate after the first may search (`candidate_effort`): a first
plan found in a handful of iterations still leaves the next candidates a real search."""


def candidate_iterations(options: RobustOptions, first: int) -> int | None:
    """The iteration bound of every candidate after a first plan found in `first` iterations
    (`candidate_effort`), or None (no bound but the time limit)."""
    if options.candidate_effort <= 0:
        return None
    return max(MIN_CANDIDATE_ITERATIONS, math.ceil(options.candidate_effort * first))


ROLLOUT_PERTURBATION = Perturbation()
"""The rollouts' perturbed worlds (the same draws as the MuJoCo check's perturbed executions)."""

FIRST_PLAN = RobustOptions(min_robustness=0.0)
"""A request answered by the first plan found, unchecked."""

ROLLOUT_PENETRATION_TOLERANCE = 0.01
"""Residual arm-object penetration (m) a perturbed rollout tolerates (see `robustness`)."""


def rollout_reaches(scene: Scene, arm_path: np.ndarray, physics_options: PhysicsOptions) -> bool:
    """Whether `arm_path` (the first configuration the start), replayed in `scene`, leaves the
    goal object inside its goal region with nothing toppled (`rollout`)."""
    return rollout(scene, arm_path, physics_options) == ""


def rollout(scene: Scene, arm_path: np.ndarray, physics_options: PhysicsOptions) -> str:
    """Replay `arm_path` (the first configuration the start) in `scene` with the rollout's
    physics (`rollout_options`): '' when the goal object ends inside its goal region and
    nothing toppled, else why not ('toppled', 'missed', or the step's invalid reason:
    an object pushed off the table, the arm pressing on one from above, a jam...)."""
    physics = Physics(scene, physics_options)
    arm = np.array(arm_path, dtype=float)
    start = State(arm[0], scene.object_poses)
    problem = physics.check_state(start)
    if problem is not None:
        return problem[0].value
    objects = np.empty((len(arm), *start.objects.shape))
    objects[0] = start.objects
    code = rollout_kernel(arm, objects, physics.arrays, physics.flag_count)
    if code == TOPPLED:
        return "toppled"
    if code > 0:
        return physics.reason(code).value
    return "" if scene.goal.reached(objects[-1, scene.goal_index, :2]) else "missed"


TOPPLED = -1
"""`rollout_kernel`'s code for an object carried far enough while it tips to fall over."""


@njit(cache=True)
def rollout_kernel(arm: np.ndarray, objects: np.ndarray, world: tuple, flags: int) -> int:
    """Physics steps from arm[i - 1] to arm[i], objects[i - 1] -> objects[i], with the tip
    judgement (`PhysicsOptions.tip_judgement`): an object whose pushes keep tipping it
    accumulates the distance it is carried; it topples (TOPPLED) once that reaches the
    travel its step reports (`physics.step._tip_travel`); a step that moves it without
    tipping it, or leaves it alone, lets it fall back upright (the count starts again).
    Returns 0, TOPPLED or the first invalid step's code."""
    M = objects.shape[1]
    info = np.zeros(4 + flags, dtype=np.int64)
    value = np.zeros(1 + M)
    carried = np.zeros(M)
    work = step_workspace(world, arm[0], objects[0])
    for i in range(1, arm.shape[0]):
        info[:] = 0
        value[:] = 0.0
        code = step_kernel(arm[i - 1], arm[i], objects[i - 1], world, objects[i], info, value, work)
        if code != 0:
            return code
        for m in range(M):
            if value[1 + m] > 0.0:
                carried[m] += math.hypot(objects[i, m, 0] - objects[i - 1, m, 0],
                                         objects[i, m, 1] - objects[i - 1, m, 1])
                if carried[m] >= value[1 + m]:
                    return TOPPLED
            else:
                carried[m] = 0.0
    return 0


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
    """The physics options a rollout judges a plan with, from the planner's: the world as it
    is, not the planner's rules for choosing pushes.

    A perturbed object meets the arm a few mm from where the plan had it: the arm then ends a
    step up to a few mm inside it, which the planner's 3 mm residual check would call an
    invalid step although the object is simply pushed. Rollouts judge the goal, not that. The
    turn limit chooses which pushes the planner may plan with; a perturbed world that turns an
    object a little faster does not fail the plan. Objects that meet push each other, and a
    push that would tip an object is judged by whether it topples it (`rollout_kernel`), not
    refused; and every object is movable (the Static RRT's static objects are its rule too)."""
    return dataclasses.replace(options, penetration_tolerance=max(
        options.penetration_tolerance, ROLLOUT_PENETRATION_TOLERANCE), max_turn=0.0,
        tipping=False, tip_judgement=True, object_contact=True, static_objects=frozenset())


def robustness(scene: Scene, states: Sequence[State], rollouts: int, seed: int,
               perturbation: Perturbation | None = None,
               physics_options: PhysicsOptions | None = None) -> float:
    """The share (0..1) of `rollouts` perturbed worlds, drawn from `seed`, in which the plan
    `states` (its arm path) reaches the goal."""
    return arm_path_robustness(scene, np.array([s.q for s in states]), rollouts, seed,
                               perturbation, physics_options)


def arm_path_robustness(scene: Scene, arm_path: np.ndarray, rollouts: int, seed: int,
                        perturbation: Perturbation | None = None,
                        physics_options: PhysicsOptions | None = None) -> float:
    """`robustness` of a plan given by its arm path alone, (T, nq), the first configuration
    the start (a recorded plan: `rearrangement-bench calibrate`)."""
    if rollouts < 1:
        raise ValueError(f"rollouts must be >= 1, got {rollouts}")
    rng = np.random.default_rng(seed)
    perturbation = perturbation or ROLLOUT_PERTURBATION
    options = rollout_options(physics_options or PhysicsOptions())
    reached = sum(rollout_reaches(perturbation.apply(scene, rng), arm_path, options)
                  for _ in range(rollouts))
    return reached / rollouts
