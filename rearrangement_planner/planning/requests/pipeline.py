"""One plan request end to end, shared by the CLI, the ROS node and the benchmarks: planner
(raced trees) -> shortcutting -> the finishing push -> (robust selection among candidates) ->
timed trajectory -> judged in 3D and mended (`judging`) -> predicted object poses along it ->
the result record of docs/design.md ("CLI").

    output = plan_scene(PlanRequest(scene, "pc-rrt", seed=0))
    output.result.outcome, output.trajectory, output.to_dict()
"""

from __future__ import annotations

import dataclasses
import math
import threading
import time
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass

import numpy as np

from rearrangement_planner.model.scene import Scene
from rearrangement_planner.model.state import State
from rearrangement_planner.physics.step import Physics
from rearrangement_planner.planning.machinery.interface import (
    Outcome,
    PlanResult,
    ProgressCallback,
    PushingPlannerOptions,
)
from rearrangement_planner.planning.machinery.termination import Termination
from rearrangement_planner.planning.requests.finish import FINISH_TIME, finish
from rearrangement_planner.planning.requests.judging import (
    NO_JUDGE,
    OTHER_SEED_OFFSET,
    Judged,
    JudgeSummary,
    Judging,
    mended,
)
from rearrangement_planner.planning.requests.parallel import plan_race, tree_seed, warm_up_race
from rearrangement_planner.planning.requests.registry import PLANNERS
from rearrangement_planner.planning.requests.request import PlanRequest
from rearrangement_planner.planning.requests.robustness import (
    FIRST_PLAN,
    candidate_iterations,
    candidate_rank,
    goal_travel,
    robustness,
)
from rearrangement_planner.planning.requests.shortcut import shortcut
from rearrangement_planner.planning.requests.trajectory import (
    DUPLICATE_TOLERANCE,
    Trajectory,
    time_parameterize,
)
from rearrangement_planner.world3d.judge import JudgeCancelled
from rearrangement_planner.world3d.mujoco_model import ExecutionCheckError

CANDIDATE_SEED_OFFSET = 1000
"""Candidate k > 0 of a robust search plans with `tree_seed(seed, CANDIDATE_SEED_OFFSET + k)`
(apart from the seeds of raced trees)."""


def candidate_seed(seed: int, k: int) -> int:
    """The seed candidate `k` of a robust search with `seed` plans with: the request's own for
    the first, derived ones after it. Each candidate is the plan its seed gives alone."""
    return seed if k == 0 else tree_seed(seed, CANDIDATE_SEED_OFFSET + k)


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


@dataclass
class Phases:
    """Where a request's wall time went (s), phase by phase (docs/experiments.md, "Where the
    time goes"): the searches (every candidate's, raced trees and the wait on their workers
    included), shortcutting and the finishing push, the robustness rollouts, trajectory
    timing, and loading or compiling the compiled core (once per process, outside the plan's
    clock)."""

    search: float = 0.0
    shortcut: float = 0.0
    rollouts: float = 0.0
    timing: float = 0.0
    judge: float = 0.0
    """The 3D judge's own executions (a mend's re-plan counts as search, shortcut, ...)."""
    warm_up: float = 0.0
    candidates: int = 0
    """Searches made (robust selection makes one per candidate, a mend's re-plan its own)."""
    searches: list[str] = dataclasses.field(default_factory=list)
    """Robust selection's candidates in order (`log_candidate`): what a rule bounding them
    differently would have kept and answered."""

    def log_candidate(self, result: PlanResult, seconds: float, score: float | None = None,
                      travel: float | None = None) -> None:
        """One candidate's search in `searches`: `iterations:robustness:goal travel
        (m):search seconds`, the last three `-` when it found no plan."""
        judged = "-:-" if score is None else f"{score:g}:{travel:.3f}"
        self.searches.append(f"{result.iterations}:{judged}:{seconds:.2f}")

    @contextmanager
    def timed(self, phase: str) -> Iterator[None]:
        """Add the time the block takes to `phase`."""
        start = time.perf_counter()
        try:
            yield
        finally:
            setattr(self, phase, getattr(self, phase) + time.perf_counter() - start)

    def add(self, other: Phases) -> None:
        """Count a nested request's phases (a mend's re-plan, the other planner's candidate)
        in these."""
        for name in ("search", "shortcut", "rollouts", "timing", "judge"):
            setattr(self, name, getattr(self, name) + getattr(other, name))
        self.candidates += other.candidates

    def to_dict(self) -> dict[str, float]:
        return {f"{name}_s": round(getattr(self, name), 3)
                for name in ("search", "shortcut", "rollouts", "timing", "judge", "warm_up")} | {
            "candidates": self.candidates}


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
    """Share of the perturbed worlds the plan reached the goal in, with nothing tipped: the 3D
    judge's when it judged the plan (`judged`), else the model's rollouts' (None: not
    measured)."""
    fragile_below: float = 0.0
    """The request's `fragile_below` (a plan without `robustness` is never fragile)."""
    phases: Phases = dataclasses.field(default_factory=Phases)
    judged: JudgeSummary | None = None
    """What the 3D judge saw of the answer and the candidates it tried (None: not judged)."""
    model_robustness: float | None = None
    """The model's robustness of the first candidate, when the 3D judge gave `robustness`."""
    unjudged: str = ""
    """Why a request that asked for the 3D judge was answered without it ('' otherwise)."""

    @property
    def solved(self) -> bool:
        return self.result.solved

    @property
    def fragile(self) -> bool:
        """A solved plan whose robustness is below `fragile_below`: it reached the goal in too
        few perturbed worlds to trust it open loop. The same bound makes robust selection search
        `fragile_candidates` more for a fragile best, so a fragile answer is the best those
        found (docs/design.md, "Fragile plans")."""
        if not self.solved:
            return False
        if self.judged is not None and not self.judged.reached:
            return True
        return self.robustness is not None and self.robustness < self.fragile_below

    def fragile_note(self) -> str:
        """'' or the sentence that says the plan is fragile, for every answer a user reads."""
        if not self.fragile:
            return ""
        assert self.robustness is not None
        share = math.floor(100 * self.robustness)       # rounded down: never "100% < 100%"
        if self.judged is not None and not self.judged.reached:
            return (f"FRAGILE: executed in the 3D judge's nominal world it "
                    f"{self.judged.failure}, and it reached the goal in {share}% of "
                    f"{self.judged.worlds} perturbed worlds; executed open loop it will "
                    f"likely miss")
        worlds = "perturbed 3D worlds" if self.judged is not None else "perturbed rollouts"
        return (f"FRAGILE: it reached the goal in {share}% of the {worlds}, below "
                f"fragile_below {self.fragile_below:.0%}; executed open loop it will likely "
                f"miss")

    @property
    def final_objects(self) -> np.ndarray:
        states = self.result.states
        return states[-1].objects if states else self.scene.object_poses

    def to_dict(self) -> dict:
        """The JSON result of the CLI (docs/design.md; plus outcome, message and shortcut
        figures)."""
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
            "model_robustness": self.model_robustness,
            "judged": self.judged.to_dict() if self.judged is not None else None,
            "unjudged": self.unjudged,
            "fragile_below": self.fragile_below,
            "fragile": self.fragile,
            "before_shortcut": (self.metrics_before_shortcut.to_dict()
                                if self.metrics_before_shortcut else None),
            "phases": self.phases.to_dict(),
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


def plan_scene(request: PlanRequest, cancel: threading.Event | None = None,
               progress: ProgressCallback | None = None) -> PlanOutput:
    """Plan `request`: its planner with `request.trees` raced trees, the path shortcut
    (`request.shortcut`; not for planners whose registry entry says so: DARRT's rigid carrying
    is a different world model from the quasistatic physics shortcutting re-simulates), robust
    selection among candidates (`request.robust`, `robust_search`), the trajectory timed
    (`request.timing`) and the object poses predicted along it. The compiled core is warmed up
    first (`warmup.warm_up`), and with it the race's worker processes (`parallel.warm_up_race`),
    outside the plan's clock."""
    phases = Phases()
    with phases.timed("warm_up"):
        warm_up_race(request.trees)
    t0 = time.monotonic()
    scene = request.scene
    candidates = Candidates(request, Physics(scene, request.physics),
                            request.options.termination(cancel), progress, phases)
    score = None
    if request.robust.min_robustness > 0:
        candidate, score = robust_search(candidates)
    else:
        candidate = candidates.shortcut(candidates.plan(request.seed), request.seed)
    result = candidate.result
    name = request.planner.name
    floor = request.robust.fragile_below
    if result.solved and cancel is not None and cancel.is_set():
        # cancelled while shortcutting or scoring: a cancel that was accepted never ends in
        # a plan answered as found
        result = PlanResult(Outcome.CANCELLED, "cancelled", request.seed,
                            plan_time=time.monotonic() - t0)
    if not result.solved:
        return PlanOutput(scene, name, result, robustness=score, fragile_below=floor,
                          phases=phases)
    with phases.timed("timing"):
        trajectory = time_parameterize(scene.robot, result.arm_path, request.timing)
        states = _states_at_points(result.states, trajectory)
    shortened = request.shortcut.shortcut_time > 0 and request.planner.shortcut
    before = candidate.before if shortened else None
    unjudged = ""
    if request.judge.judge_worlds > 0:
        try:
            judging = Judging(scene, request.judge, request.timing, candidates.stop,
                              request.seed, cancel)
            answer = judge_and_mend(judging, judging.judged(trajectory, states, name, result),
                                    request, cancel, progress, phases,
                                    candidates.ranked(candidate))
            if cancel is not None and cancel.is_set():     # a mend's search saw it first
                raise JudgeCancelled("cancelled while judging in 3D")
        except ExecutionCheckError as exc:    # no 3D model of this arm: the model's answer
            unjudged = f"not judged in 3D: {exc}"
        except JudgeCancelled:
            cancelled = PlanResult(Outcome.CANCELLED, "cancelled while judging in 3D",
                                   request.seed, plan_time=time.monotonic() - t0)
            return PlanOutput(scene, name, cancelled, fragile_below=floor, phases=phases)
        else:
            return _judged_output(request, judging, answer, candidate, score, phases, t0)
    return PlanOutput(scene, name, result, trajectory, states,
                      PathMetrics.of(scene, result.states), before, candidate.shortcut_time,
                      score, floor, phases, unjudged=unjudged)


def _judged_output(request: PlanRequest, judging: Judging, answer: Judged, candidate: Candidate,
                   score: float | None, phases: Phases, t0: float) -> PlanOutput:
    """The request's output from its judged answer (`judge_and_mend`): the answer's trajectory,
    the object poses its nominal 3D execution gave, its 3D robustness; the plan time all the
    request took but the first candidate's shortcutting (as without the judge), its seed the
    request's (which reproduces the whole request)."""
    scene = request.scene
    phases.judge += judging.seconds
    final = answer.predicted_states()
    result = dataclasses.replace(answer.result, states=final, seed=request.seed,
                                 plan_time=time.monotonic() - t0 - candidate.shortcut_time)
    shortened = request.shortcut.shortcut_time > 0 and request.planner.shortcut
    return PlanOutput(scene, request.planner.name, result, answer.trajectory, final,
                      PathMetrics.of(scene, final), candidate.before if shortened else None,
                      candidate.shortcut_time, answer.judgement.robustness,
                      request.robust.fragile_below, phases, JudgeSummary.of(judging, answer),
                      score)


OTHER_PLANNER = {"pc-rrt": "slice-rrt", "slice-rrt": "pc-rrt"}
"""The planner a request's 3D judging draws a candidate from when its own are not accepted
(`JudgeOptions.both_planners`)."""


def judge_and_mend(judging: Judging, first: Judged, request: PlanRequest,
                   cancel: threading.Event | None, progress: ProgressCallback | None,
                   phases: Phases, others: Sequence[Candidate] = ()) -> Judged:
    """The request's answer among its judged candidates (`judging` module doc): `first`; the
    model's `others` (robust selection's other candidates, already found: judging them costs
    no search), best first; the best of those, mended; then the other planner's candidate,
    mended; the best judged."""
    options = request.judge
    drafts = _Drafts(request, judging, cancel, progress, phases)
    for candidate in others:
        if judging.best.accepted(options) or not judging.time_left():
            break
        trajectory = time_parameterize(request.scene.robot, candidate.result.arm_path,
                                       request.timing)
        judging.judged(trajectory, _states_at_points(candidate.result.states, trajectory),
                       request.planner.name, candidate.result)
    best = mended(judging, judging.best, drafts.replan)
    other = OTHER_PLANNER.get(request.planner.name)
    if (not best.accepted(options) and options.both_planners and other is not None
            and judging.time_left()):
        output = drafts.other(other)
        if isinstance(output, str):
            judging.log.append(f"{other}: not found, {output}")
        else:
            assert output.trajectory is not None
            mended(judging, judging.judged(output.trajectory, output.trajectory_states, other,
                                           output.result), drafts.replan)
    return judging.answer()


@dataclass(frozen=True)
class _Drafts:
    """The unjudged searches of a request's judging: a mend's re-plan and the other planner's
    candidate, each its first plan, shortcut and finished but neither scored nor judged (the
    judge scores what it becomes), within `search_iterations` and the request's time left,
    shortcutting included."""

    request: PlanRequest
    judging: Judging
    cancel: threading.Event | None
    progress: ProgressCallback | None
    phases: Phases

    def plan(self, sub: PlanRequest) -> PlanOutput | str:
        """`sub`'s first plan (class doc), or why there is none."""
        seconds = self.judging.stop.remaining()
        if seconds <= 0.001:
            return "no time left"
        iterations = min(sub.options.max_iterations, self.request.judge.search_iterations)
        sub = dataclasses.replace(
            sub, judge=NO_JUDGE, robust=FIRST_PLAN,
            options=dataclasses.replace(sub.options, time_limit=seconds,
                                        max_iterations=iterations),
            shortcut=dataclasses.replace(sub.shortcut, shortcut_time=min(
                sub.shortcut.shortcut_time, seconds)))
        output = plan_scene(sub, self.cancel, self.progress)
        self.phases.add(output.phases)
        result = output.result
        return output if output.solved else f"{result.outcome.value}: {result.message}"

    def replan(self, scene: Scene, static: frozenset[str], seed: int
               ) -> tuple[Trajectory, tuple[State, ...]] | str:
        """A mend's re-plan (`judging.Replan`): the request's planner from `scene`'s start,
        the objects in `static` as obstacles."""
        request, physics = self.request, self.request.physics
        if static and request.planner.steps_physics:
            physics = dataclasses.replace(physics,
                                          static_objects=physics.static_objects | static)
        output = self.plan(dataclasses.replace(request, scene=scene, start=None, seed=seed,
                                               physics=physics))
        if isinstance(output, str):
            return output
        assert output.trajectory is not None
        return output.trajectory, output.trajectory_states

    def other(self, name: str) -> PlanOutput | str:
        """The other planner's candidate: planner `name` with its default options and the
        request's shared settings, from a seed of its own."""
        request, spec = self.request, PLANNERS[name]
        try:
            sub = PlanRequest(request.scene, spec, spec.options(None), request.physics,
                              request.race, request.shortcut, request.finish, request.timing,
                              request.robust, tree_seed(request.seed, OTHER_SEED_OFFSET),
                              request.start)
        except ValueError as exc:        # e.g. no learned oracle for this arm
            return str(exc)
        return self.plan(sub)


@dataclass(frozen=True)
class Candidate:
    """A search's result, shortcut: what the robustness rollouts judge and the answer holds."""

    result: PlanResult
    before: PathMetrics | None = None
    """The path before shortcutting."""
    shortcut_time: float = 0.0


@dataclass(frozen=True)
class Candidates:
    """The plans of one request, each from its own seed: the first answers a request without
    robust selection, several are what robust selection (`robust_search`) and the benchmark's
    candidate recording (`tools.bench.candidates`) choose among."""

    request: PlanRequest
    physics: Physics
    """The scene's physics with the request's options (the planner's own is built from it)."""
    stop: Termination
    """The request's budget (its time limit, max_iterations and the user's cancel): every
    candidate's search and shortcutting end with it (the finishing push up to FINISH_TIME
    after it)."""
    progress: ProgressCallback | None = None
    phases: Phases = dataclasses.field(default_factory=Phases)
    found: list[tuple[float, Candidate]] = dataclasses.field(default_factory=list)
    """Every solved candidate robust selection scored, with its rank (best first after
    `ranked`): what the 3D judge looks at next when the answer is not accepted."""

    def ranked(self, answered: Candidate) -> list[Candidate]:
        """The scored candidates but `answered`, the model's best first."""
        return [c for _, c in sorted(self.found, key=lambda f: -f[0])
                if c.result.states is not answered.result.states]

    def plan(self, seed: int) -> PlanResult:
        """The request's search with `seed`, within `stop`."""
        request = self.request
        self.phases.candidates += 1
        with self.phases.timed("search"):
            if request.trees > 1:
                return plan_race(request.planner, request.scene, request.options,
                                 request.trees, seed, request.start, self.stop, self.progress,
                                 self.physics)
            return request.planner.make(request.scene, request.options, self.physics).plan(
                start=request.start, seed=seed, stop=self.stop, progress=self.progress)

    def bounded(self, max_iterations: int | None) -> Candidates:
        """The same candidates, each search ending after `max_iterations` too (None: as
        they are)."""
        if max_iterations is None:
            return self
        bound = min(max_iterations, self.stop.max_iterations or max_iterations)
        return dataclasses.replace(self, stop=dataclasses.replace(self.stop,
                                                                  max_iterations=bound))

    def shortcut(self, result: PlanResult, seed: int) -> Candidate:
        """A solved `result` shortcut for up to shortcut_time s (ending with the request's
        budget at the latest) or shortcut_attempts attempts (whichever ends first; an
        attempt bound that ends first makes it reproducible), then finished (`finish.finish`:
        the goal object pushed on to the goal point); as it is when the planner's paths are
        not shortcut."""
        if not result.solved:
            return Candidate(result)
        request = self.request
        before = PathMetrics.of(request.scene, result.states)
        if not request.planner.shortcut:
            return Candidate(result, before)
        # Shortcutting and the finishing push re-simulate the pushes in the planner's own world
        # (the Static RRT's non-goal objects stay obstacles there, so neither pushes them).
        physics = request.planner.physics(request.scene, self.physics)
        states, elapsed = result.states, 0.0
        seconds = request.shortcut.shortcut_time
        if seconds > 0 and len(states) > 2:
            # within the request's time limit: a plan found late is shortcut less
            stop = self.stop.split(seconds, request.shortcut.shortcut_attempts or None)
            with self.phases.timed("shortcut"):
                short = shortcut(physics, states, stop, seed=seed,
                                 goal_radius=request.options.goal_radius(request.scene))
            states, elapsed = tuple(short.states), short.elapsed
        if request.finish.finish_radius > 0 and isinstance(request.options,
                                                           PushingPlannerOptions):
            with self.phases.timed("shortcut"):
                states = finish(physics, states, request.options, request.finish.finish_radius,
                                self.stop.extended(FINISH_TIME))
        return Candidate(dataclasses.replace(result, states=states), before, elapsed)

    def score(self, candidate: Candidate, seed: int) -> float:
        """The candidate's robustness: the share of `request.robust.rollouts` perturbed
        rollouts, drawn from `seed`, in which it reaches the goal in the planner's physics."""
        request = self.request
        world = request.planner.physics(request.scene, self.physics).options
        with self.phases.timed("rollouts"):
            return robustness(request.scene, candidate.result.states, request.robust.rollouts,
                              seed, physics_options=world)


def _answer(candidate: Candidate, t0: float, seed: int) -> Candidate:
    """The chosen candidate as the request's answer: its plan time all the selection took
    since `t0` but its own shortcutting, its seed the request's."""
    spent = time.monotonic() - t0 - candidate.shortcut_time
    return dataclasses.replace(candidate, result=dataclasses.replace(
        candidate.result, plan_time=spent, seed=seed))


def robust_search(candidates: Candidates) -> tuple[Candidate, float | None]:
    """Candidates (the request's seed, then derived seeds), each shortcut, until one is robust
    enough; else the best ranked: its robustness less travel_penalty per metre it pushes the
    goal object. `candidates` of them, and up to `fragile_candidates` more while the best so
    far is below `fragile_below`. The rollouts judge the shortcut path: the one the answer
    holds. Searches stop at the time limit, shortcuts at the time limit plus shortcut_time
    (a request takes no longer than without robust selection); the searches after the first
    plan also after `candidate_effort` times its iterations
    (`robustness.candidate_iterations`: a plan the first search took long to find is not
    worth as long again to better, a quick one is worth a quick look), and a fragile best's
    extra candidates also after `fragile_search_iterations` each. The answer's plan time
    is all of it but its own shortcutting (reported apart, as without robust selection), and
    its seed the request's (which reproduces the whole selection). A cancel ends it with the
    cancelled search."""
    request = candidates.request
    robust, seed = request.robust, request.seed
    t0 = time.monotonic()
    best: tuple[Candidate, float, float] | None = None    # candidate, robustness, rank
    most_robust = 0.0
    last: PlanResult | None = None
    searches = candidates
    searched = 0
    for k in range(robust.candidates + robust.fragile_candidates):
        if candidates.stop.remaining() <= 0.001:
            break
        if k >= robust.candidates and (best is None or most_robust >= robust.fragile_below):
            break               # past `candidates`, only a fragile best earns another look
        searched += 1
        k_seed = candidate_seed(seed, k)
        started = time.monotonic()
        extra = k >= robust.candidates and robust.fragile_search_iterations > 0
        last = (searches.bounded(robust.fragile_search_iterations) if extra
                else searches).plan(k_seed)
        searched_s = time.monotonic() - started
        if last.outcome is Outcome.CANCELLED:
            return Candidate(last), None        # the user's cancel ends the selection too
        if not last.solved:
            candidates.phases.log_candidate(last, searched_s)
            continue
        if best is None:
            searches = candidates.bounded(candidate_iterations(robust, last.iterations))
        candidate = candidates.shortcut(last, k_seed)
        score = candidates.score(candidate, k_seed)
        travel = goal_travel(request.scene, candidate.result.states)
        candidates.phases.log_candidate(last, searched_s, score, travel)
        rank = candidate_rank(score, travel, robust.travel_penalty)
        candidates.found.append((rank, candidate))
        if score >= robust.min_robustness:
            return _answer(candidate, t0, seed), score
        if best is None or rank > best[2]:
            best = (candidate, score, rank)
        most_robust = max(most_robust, score)
    return _unrobust_answer(request, best, last, searched, most_robust, t0)


def _unrobust_answer(request: PlanRequest, best: tuple[Candidate, float, float] | None,
                     last: PlanResult | None, searched: int, most_robust: float,
                     t0: float) -> tuple[Candidate, float | None]:
    """Robust selection's answer when no candidate reached min_robustness: the best ranked
    (`accept_best`), else a failure saying how robust the best was; the last search's failure
    when none found a plan."""
    robust = request.robust
    if best is None:
        assert last is not None or request.options.time_limit <= 0.001
        return Candidate(last or PlanResult(Outcome.TIMEOUT, "no time for a candidate",
                                            request.seed)), None
    fragile, score, _ = best
    if robust.accept_best:
        return _answer(fragile, t0, request.seed), score
    return Candidate(dataclasses.replace(
        fragile.result, outcome=Outcome.TIMEOUT, states=(),
        message=f"no plan reached min_robustness {robust.min_robustness:g} within "
                f"{searched} candidates: the most robust reached the goal in "
                f"{most_robust:.0%} of {robust.rollouts} perturbed rollouts",
        plan_time=time.monotonic() - t0)), most_robust
