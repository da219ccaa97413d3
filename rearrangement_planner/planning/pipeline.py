"""One plan request end to end, shared by the CLI and the ROS node: planner -> (shortcutting) ->
timed trajectory -> predicted object poses along it -> the result record of DESIGN §8.

    output = plan_scene(scene, "pc-rrt", PlannerOptions(time_limit=30), seed=0)
    output.result.outcome, output.trajectory, output.to_dict()
"""

from __future__ import annotations

import dataclasses
import math
import threading
import time
from dataclasses import dataclass

import numpy as np

from rearrangement_planner.model.scene import Scene
from rearrangement_planner.model.state import State
from rearrangement_planner.physics.step import Physics
from rearrangement_planner.planning.interface import (
    Outcome,
    PlannerOptions,
    PlanResult,
    ProgressCallback,
    planning_physics,
)
from rearrangement_planner.planning.parallel import plan_race, tree_seed
from rearrangement_planner.planning.registry import make_planner, planner_spec
from rearrangement_planner.planning.robustness import candidate_rank, goal_travel, robustness
from rearrangement_planner.planning.settings import Settings, setting
from rearrangement_planner.planning.shortcut import shortcut
from rearrangement_planner.planning.trajectory import (
    DUPLICATE_TOLERANCE,
    TimingOptions,
    Trajectory,
    time_parameterize,
)
from rearrangement_planner.planning.warmup import warm_up

CANDIDATE_SEED_OFFSET = 1000
"""Candidate k > 0 of a robust search plans with `tree_seed(seed, CANDIDATE_SEED_OFFSET + k)`
(apart from the seeds of raced trees)."""


def candidate_seed(seed: int, k: int) -> int:
    """The seed candidate `k` of a robust search with `seed` plans with: the request's own for
    the first, derived ones after it. Each candidate is the plan its seed gives alone."""
    return seed if k == 0 else tree_seed(seed, CANDIDATE_SEED_OFFSET + k)


@dataclass(frozen=True)
class PipelineOptions(Settings):
    """What happens to a plan after the search: shortcutting and trajectory timing."""

    shortcut_time: float = setting(10.0, low=0.0, high=600.0)
    """Longest path shortcutting (King et al. §IV) after a plan is found, s; 0 = none."""
    shortcut_attempts: int = setting(40, low=0, high=100000)
    """Shortcut attempts (about 50 ms each); the attempt bound, when it ends shortcutting
    before shortcut_time, keeps plans reproducible. 0 = until shortcut_time."""
    velocity_scale: float = setting(0.5, low=0.01, high=1.0)
    """Fraction of each joint's velocity limit the trajectory may use."""
    max_tool_speed: float = setting(0.1, low=0.001, high=1.0)
    """Largest end-effector speed of the trajectory, m/s (slow enough for quasistatic
    pushing)."""
    max_joint_acceleration: float = setting(0.0, low=0.0, high=100.0)
    """Joint acceleration limit of the trajectory, rad/s^2; 0 = none."""
    min_robustness: float = setting(1.0, low=0.0, high=1.0)
    """Robust selection (`planning.robustness`): a plan is judged by the share of `rollouts`
    perturbed worlds (object poses 5 mm / 2 deg, friction x0.7-1.3, mass x0.8-1.2, the arm's
    contact shapes +-5 mm) in which it reaches the goal in the planner's physics; the first
    candidate reaching min_robustness answers, else up to `candidates` are planned within the
    time limit and the best answers (`accept_best`: the most robust, less `travel_penalty`)
    or the request fails. 0 = accept the first plan, unchecked. The default (1, 3
    candidates, travel_penalty 0.5; on the 35 benchmark scenes, seeds 0-2, 54 of 105 requests
    reached the goal in MuJoCo against 45 with the first plan, 7 toppled an object against
    19, as many solved) is measured in docs/benchmark.md "Session 14" and "Session 15"."""
    rollouts: int = setting(20, low=1, high=1000)
    """Perturbed rollouts per candidate plan (with min_robustness > 0)."""
    candidates: int = setting(3, low=1, high=20)
    """Most candidate plans planned for min_robustness, within the one time limit (a hard
    scene's searches use it up after one or two). 6 reached the goal in 4 more of 105
    requests than 3, but in 3 fewer of the 35 held out from that choice."""
    travel_penalty: float = setting(0.5, low=0.0, high=100.0)
    """Candidates are ranked by robustness less this much per metre their goal object is
    pushed (`robustness.goal_travel`): the model's error grows along every push, so between
    two nearly equally robust plans the shorter push is the safer (seeds 0-2: as many reached
    the goal in MuJoCo as with the most robust, 7 toppled an object against 12). 0 = the
    most robust."""
    accept_best: bool = setting(True)
    """When no candidate reaches min_robustness: answer with the best ranked one (its
    robustness reported) instead of failing. A request then fails only when no plan is found
    at all, as without robust selection; the candidates only choose among plans."""

    @property
    def timing(self) -> TimingOptions:
        acceleration = self.max_joint_acceleration
        return TimingOptions(self.velocity_scale, self.max_tool_speed,
                             acceleration if acceleration > 0 else None)


@dataclass(frozen=True)
class PathMetrics:
    """Arm path length in joint space (rad) and of the tool (m), total object displacement (m)."""

    path_length_rad: float
    ee_path_length_m: float
    object_displacement_m: float

    @classmethod
    def of(cls, scene: Scene, states: tuple[State, ...] | list[State]) -> PathMetrics:
        robot = scene.robot
        arm = np.array([s.q for s in states])
        tool = np.array([robot.tool_pose(q)[:3, 3] for q in arm])
        objects = np.array([s.objects[:, :2] for s in states])
        return cls(float(np.linalg.norm(np.diff(arm, axis=0), axis=1).sum()),
                   float(np.linalg.norm(np.diff(tool, axis=0), axis=1).sum()),
                   float(np.linalg.norm(np.diff(objects, axis=0), axis=2).sum()))

    def to_dict(self) -> dict[str, float]:
        return {"path_length_rad": self.path_length_rad,
                "ee_path_length_m": self.ee_path_length_m,
                "object_displacement_m": self.object_displacement_m}


@dataclass(frozen=True)
class PlanOutput:
    """Everything one plan request produced."""

    scene: Scene
    planner: str
    result: PlanResult
    trajectory: Trajectory | None = None
    """The timed trajectory (None unless solved)."""
    trajectory_states: tuple[State, ...] = ()
    """The predicted world state at every trajectory point (same length as the trajectory)."""
    metrics: PathMetrics | None = None
    """Of the returned path (after shortcutting, if any)."""
    metrics_before_shortcut: PathMetrics | None = None
    shortcut_time: float = 0.0
    """Seconds spent shortcutting."""
    robustness: float | None = None
    """Share of the perturbed rollouts the plan reached the goal in (None: not measured)."""

    @property
    def solved(self) -> bool:
        return self.result.solved

    @property
    def final_objects(self) -> np.ndarray:
        states = self.result.states
        return states[-1].objects if states else self.scene.object_poses

    def to_dict(self) -> dict:
        """The JSON result of DESIGN §8 (plus outcome, message and shortcut figures)."""
        scene, result = self.scene, self.result
        final = self.final_objects
        record = {
            "solved": result.solved,
            "outcome": result.outcome.value,
            "message": result.message,
            "planner": self.planner,
            "seed": result.seed,
            "plan_time_s": result.plan_time,
            "iterations": result.iterations,
            "tree_size": result.tree_size,
            "propagation_steps": result.propagation_steps,
            "path_length_rad": None, "ee_path_length_m": None, "object_displacement_m": None,
            "goal_distance_m": float(scene.goal.distance(final[scene.goal_index, :2])),
            "final_object_poses": {o.name: [float(v) for v in final[i]]
                                   for i, o in enumerate(scene.objects)},
            "trajectory": trajectory_dict(self.trajectory) if self.trajectory else None,
            "shortcut_time_s": self.shortcut_time,
            "robustness": self.robustness,
            "before_shortcut": (self.metrics_before_shortcut.to_dict()
                                if self.metrics_before_shortcut else None),
        }
        if self.metrics is not None:
            record.update(self.metrics.to_dict())
        return record


def trajectory_dict(trajectory: Trajectory) -> dict:
    return {
        "joint_names": list(trajectory.joint_names),
        "points": [{"positions": p.tolist(), "velocities": v.tolist(), "time_from_start": t}
                   for t, p, v in zip(trajectory.times.tolist(), trajectory.positions,
                                      trajectory.velocities, strict=True)],
    }


def _states_at_points(states: tuple[State, ...], trajectory: Trajectory) -> tuple[State, ...]:
    """The planned state at every trajectory point: time parameterisation drops repeated arm
    configurations (`trajectory.remove_duplicates`); keep the last state of each run of
    repeats (in a repeat the arm does not move, so neither do the objects)."""
    kept: list[State] = []
    last_q = None
    for s in states:
        if last_q is not None and np.max(np.abs(s.q - last_q)) <= DUPLICATE_TOLERANCE:
            kept[-1] = s
            continue
        kept.append(s)
        last_q = s.q
    if len(kept) != len(trajectory):
        raise RuntimeError(f"internal: {len(kept)} distinct states for {len(trajectory)} "
                           f"trajectory points")
    return tuple(kept)


def plan_scene(scene: Scene, planner: str = "pc-rrt", options: PlannerOptions | None = None,
               seed: int = 0, start: State | None = None,
               cancel: threading.Event | None = None,
               progress: ProgressCallback | None = None,
               shortcut_time: float = 0.0, timing: TimingOptions | None = None,
               physics: Physics | None = None,
               shortcut_attempts: int | None = None,
               robust: PipelineOptions | None = None) -> PlanOutput:
    """Plan `scene` (from `start`, default the scene's initial state) with `options.trees`
    trees (`parallel.plan_race` when more than one), shortcut the path for up
    to `shortcut_time` s or `shortcut_attempts` attempts (whichever ends first; an attempt
    bound that ends first makes the result reproducible), time it, and predict the object
    poses along the trajectory.

    Planners whose registry entry says so are not shortcut (DARRT: its Push primitive holds
    the object rigidly, a different world model from the quasistatic physics that
    shortcutting re-simulates).

    With `robust.min_robustness` > 0 a plan is accepted only if it reaches the goal in that
    share of `robust.rollouts` perturbed rollouts (`planning.robustness`); up to
    `robust.candidates` plans are planned within the time limit and the best ranked answers
    (`robust.accept_best`: the most robust, less `robust.travel_penalty` per metre the goal
    object is pushed) or the request fails (a fragile open-loop plan is not a plan).
    The compiled core is warmed up first (`warmup.warm_up`), outside the plan's clock."""
    warm_up()
    physics = planning_physics(scene, planner_spec(planner).options(options), physics)
    search = _Search(planner, scene, options, start, cancel, progress, physics,
                     shortcut_time, shortcut_attempts)
    score = None
    if robust is not None and robust.min_robustness > 0:
        candidate, score = _robust_search(search, seed, robust)
    else:
        candidate = search.finish(search.run(seed), seed)
    result = candidate.result
    if not result.solved:
        return PlanOutput(scene, planner, result, robustness=score)
    trajectory = time_parameterize(scene.robot, result.arm_path, timing or TimingOptions())
    states = _states_at_points(result.states, trajectory)
    return PlanOutput(scene, planner, result, trajectory, states,
                      PathMetrics.of(scene, result.states),
                      candidate.before if shortcut_time > 0 else None, candidate.shortcut_time,
                      score)


@dataclass(frozen=True)
class _Candidate:
    """A search's result, shortcut: what the robustness rollouts judge and the answer holds."""

    result: PlanResult
    before: PathMetrics | None = None
    """The path before shortcutting."""
    shortcut_time: float = 0.0


@dataclass(frozen=True)
class _Search:
    """One search of a request, repeatable with another seed (the candidates)."""

    planner: str
    scene: Scene
    options: PlannerOptions | None
    start: State | None
    cancel: threading.Event | None
    progress: ProgressCallback | None
    physics: Physics
    shortcut_time: float
    shortcut_attempts: int | None

    def run(self, seed: int, time_limit: float | None = None) -> PlanResult:
        options = self.options
        if time_limit is not None:
            options = dataclasses.replace(planner_spec(self.planner).options(options),
                                          time_limit=time_limit)
        if options is not None and options.trees > 1:
            return plan_race(self.planner, self.scene, options, seed, self.start, self.cancel,
                             self.progress, self.physics)
        return make_planner(self.planner, self.scene, options, self.physics).plan(
            start=self.start, seed=seed, cancel=self.cancel, progress=self.progress)

    def finish(self, result: PlanResult, seed: int, time_left: float = math.inf) -> _Candidate:
        """A solved `result` shortcut for up to shortcut_time s (and `time_left`) or
        shortcut_attempts attempts (whichever ends first; an attempt bound that ends first
        makes it reproducible).
        Planners whose registry entry says so are not shortcut (DARRT: its Push primitive
        holds the object rigidly, a different world model from the quasistatic physics that
        shortcutting re-simulates)."""
        if not result.solved:
            return _Candidate(result)
        before = PathMetrics.of(self.scene, result.states)
        spec = planner_spec(self.planner)
        seconds = min(self.shortcut_time, time_left)
        if seconds <= 0 or len(result.states) <= 2 or not spec.shortcut:
            return _Candidate(result, before)
        # Shortcutting re-simulates the pushes in the planner's own world (the Static RRT's
        # non-goal objects stay obstacles there, so a shortcut cannot push them either).
        short = shortcut(spec.physics(self.scene, self.physics), result.states,
                         seconds, seed=seed, cancel=self.cancel,
                         max_attempts=self.shortcut_attempts,
                         goal_radius=spec.options(self.options).goal_radius(self.scene))
        return _Candidate(dataclasses.replace(result, states=tuple(short.states)), before,
                          short.elapsed)


def _answer(candidate: _Candidate, t0: float, seed: int) -> _Candidate:
    """The chosen candidate as the request's answer: its plan time all the selection took
    since `t0` but its own shortcutting, its seed the request's."""
    spent = time.monotonic() - t0 - candidate.shortcut_time
    return dataclasses.replace(candidate, result=dataclasses.replace(
        candidate.result, plan_time=spent, seed=seed))


def _robust_search(search: _Search, seed: int, robust: PipelineOptions
                   ) -> tuple[_Candidate, float | None]:
    """Candidates (seed, then derived seeds), each shortcut, until one is robust enough; else
    the best ranked: its robustness less travel_penalty per metre it pushes the goal object.
    The rollouts judge the shortcut path: the one the answer holds. Searches stop at the
    time limit, shortcuts at the time limit plus shortcut_time (a request takes no
    longer than without robust selection). The answer's plan time is all of it but its own
    shortcutting (reported apart, as without robust selection), and its seed the request's
    (which reproduces the whole selection)."""
    t0 = time.monotonic()
    budget = planner_spec(search.planner).options(search.options).time_limit
    world = planner_spec(search.planner).physics(search.scene, search.physics).options
    best: tuple[_Candidate, float, float] | None = None    # candidate, robustness, rank
    most_robust = 0.0
    last: PlanResult | None = None
    for k in range(robust.candidates):
        remaining = budget - (time.monotonic() - t0)
        if remaining <= 0.001:
            break
        k_seed = candidate_seed(seed, k)
        last = search.run(k_seed, remaining)
        if not last.solved:
            continue
        candidate = search.finish(last, k_seed, time_left=t0 + budget
                                  + search.shortcut_time - time.monotonic())
        score = robustness(search.scene, candidate.result.states, robust.rollouts, k_seed,
                           physics_options=world)
        if score >= robust.min_robustness:
            return _answer(candidate, t0, seed), score
        rank = candidate_rank(score, goal_travel(search.scene, candidate.result.states),
                              robust.travel_penalty)
        if best is None or rank > best[2]:
            best = (candidate, score, rank)
        most_robust = max(most_robust, score)
    if best is None:
        assert last is not None or budget <= 0.001
        return _Candidate(last or PlanResult(Outcome.TIMEOUT, "no time for a candidate",
                                             seed)), None
    fragile, score, _ = best
    if robust.accept_best:
        return _answer(fragile, t0, seed), score
    return _Candidate(dataclasses.replace(
        fragile.result, outcome=Outcome.TIMEOUT, states=(),
        message=f"no plan reached min_robustness {robust.min_robustness:g} within "
                f"{robust.candidates} candidates: the most robust reached the goal in "
                f"{most_robust:.0%} of {robust.rollouts} perturbed rollouts",
        plan_time=time.monotonic() - t0)), most_robust
