"""Judged in 3D, and mended (docs/design.md "Judged in 3D"): before a request answers, its plan
is executed open loop by the servo arm in the product's 3D world (`world3d.judge`), nominally
and in `judge_worlds` perturbed worlds. A plan that misses or tips an object there is not
answered as it is: the request mends it, and draws candidates from the other planner.

    answer = judge_and_mend(first, request, stop, cancel)
    answer.judgement.nominal.reached, answer.judgement.robustness, answer.trajectory

The model's robust selection (`pipeline.robust_search`) still chooses the first candidate: its
quasistatic rollouts cost a few ms, the 3D judge about a second. Then, in this order, while the
best judged so far is not *accepted* (it reaches the goal in the nominal 3D world and in at
least `judge_accept` of the perturbed ones) and the request's time remains:
1. **Mend** (`mend`), up to `mends` times: where the nominal 3D execution left the plan, the
   arm stops (at the plan's end after a miss; before the object began to tilt, after a tip),
   backs out of contact the way it came (`retreat.retreat_path`), and the request plans again
   from the 3D state there. The spliced trajectory (the plan up to the cut, a pause, the
   retreat, a pause, the new plan) is judged again as a whole. This is the closed loop's
   execute-observe-retreat-re-plan (docs/design.md "Closed loop") run in simulation before the
   answer, the dynamic planning horizon of Ren, Kavraki & Hang (IROS 2022) with the world's
   own physics as the observation. An object other than the goal object that tipped is a static
   obstacle to the re-plan, which then pushes around it.
2. **The other planner** (`both_planners`): PC-RRT's and the slice-based RRT's plans reach
   different requests (docs/benchmark.md), so a request of one draws a candidate from the
   other (with its own model selection), judges it and mends it the same way.
The answer is the best judged: reached nominally first, then the share of perturbed worlds
reached. Its trajectory is one JointTrajectory, its predicted object poses those the nominal
3D execution gave, and its robustness the 3D share. One that does not reach nominally is
fragile (`PlanOutput.fragile`).
"""

from __future__ import annotations

import dataclasses
import math
import threading
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from rearrangement_planner.model.errors import SceneError
from rearrangement_planner.model.scene import Scene
from rearrangement_planner.model.settings import Settings, setting
from rearrangement_planner.model.state import State
from rearrangement_planner.physics.validation import check_scene, separate_objects
from rearrangement_planner.planning.machinery.interface import PlanResult
from rearrangement_planner.planning.machinery.termination import Termination
from rearrangement_planner.planning.requests.parallel import tree_seed
from rearrangement_planner.planning.requests.retreat import retreat_path
from rearrangement_planner.planning.requests.trajectory import (
    TimingOptions,
    Trajectory,
    cut,
    splice,
    time_parameterize,
)
from rearrangement_planner.world3d.execution import perturbed_worlds
from rearrangement_planner.world3d.judge import Judgement, judge


@dataclass(frozen=True)
class JudgeOptions(Settings):
    """Judging a request's answer in 3D, and mending it (a plan request's; `judging`)."""

    judge_worlds: int = setting(8, low=0, high=64)
    """Perturbed 3D worlds each judged candidate is executed in, besides the nominal one
    (object poses 5 mm / 2 deg, friction x0.7-1.3, mass x0.8-1.2, centres of mass): the
    answer's robustness is the share it reaches the goal in, with nothing tipped. 0 = no 3D
    judge: the answer is the model's, its robustness the quasistatic rollouts'."""
    judge_accept: float = setting(0.6, low=0.0, high=1.0)
    """A judged candidate that reaches the goal in the nominal 3D world and in at least this
    share of the perturbed ones is answered at once; until one does, the request mends and
    draws from the other planner while its time lasts."""
    mends: int = setting(2, low=0, high=10)
    """Times a candidate that misses or tips an object in the nominal 3D world is mended:
    stopped where it left its plan, backed out and planned on from the 3D state there."""
    both_planners: bool = setting(True)
    """Draw a candidate from the other of PC-RRT and the slice-based RRT when the request's
    own planner's are not accepted in 3D (they reach different requests)."""
    search_iterations: int = setting(10000, low=1, high=10**9)
    """Each mend's re-plan and the other planner's candidate searches at most this many
    iterations (and the request's time left): its first plan, not scored by the model, as
    the 3D judge scores what it becomes. Counted in iterations, so the answer does not depend
    on the machine's speed."""
    tilt_bound: float = setting(round(math.radians(10.0), 4), low=0.01, high=1.5)
    """rad: an object tilted further than this at any moment of a judged execution fails it,
    though it may fall back upright."""


NO_JUDGE = JudgeOptions(judge_worlds=0)
"""A request answered by the model alone (the mends' own re-plans, `first_plan` requests)."""

JUDGE_SEED_OFFSET = 2000
"""The judge's perturbed worlds are drawn from `tree_seed(seed, JUDGE_SEED_OFFSET)`: the same
worlds for every candidate of a request, apart from the seeds of its searches."""
OTHER_SEED_OFFSET = 3000
MEND_SEED_OFFSET = 4000
CUT_MARGIN = 0.5
"""s: a plan that tipped an object is cut this long before the object began to tilt."""
DIVERGENCE = 0.02
"""m: a plan that missed is cut where an object first strays this far from its prediction."""
MIN_TIME = 0.5
"""s of the request's budget below which no further mend or candidate is started."""


@dataclass(frozen=True)
class Judged:
    """A candidate answer with its 3D judgement."""

    trajectory: Trajectory
    states: tuple[State, ...]
    """The model's predicted state at every trajectory point."""
    judgement: Judgement
    planner: str
    """The planner that found it (the request's, or the other)."""
    result: PlanResult
    """Its first search's result (outcome, iterations, tree size)."""
    mends: int = 0
    """How many re-plans it splices."""
    static: frozenset[str] = frozenset()
    """Objects its mends' re-plans treated as obstacles."""

    def accepted(self, options: JudgeOptions) -> bool:
        return (self.judgement.nominal.reached
                and self.judgement.robustness >= options.judge_accept)

    @property
    def rank(self) -> tuple[bool, float, bool, float]:
        """Reached nominally first, then the perturbed share; of those that did not, the
        upright ones, then the nearer."""
        nominal = self.judgement.nominal
        if nominal.reached:
            return (True, self.judgement.robustness, True, -self.trajectory.duration)
        return (False, 0.0, not nominal.tipped, -nominal.goal_distance_m)

    def predicted_states(self) -> tuple[State, ...]:
        """The state at every trajectory point as the nominal 3D execution gave it: the arm's
        commanded configuration and the objects' executed poses."""
        poses = self.judgement.nominal.poses
        return tuple(State(np.array(q), poses[min(i, len(poses) - 1)].copy())
                     for i, q in enumerate(self.trajectory.positions))


@dataclass
class Judging:
    """One request's judging: its budget, its worlds, and what it has tried."""

    scene: Scene
    options: JudgeOptions
    timing: TimingOptions
    stop: Termination
    seed: int
    cancel: threading.Event | None = None
    tried: list[Judged] = dataclasses.field(default_factory=list)
    seconds: float = 0.0
    """Wall time spent judging (the judge's own, not the mends' re-plans)."""
    log: list[str] = dataclasses.field(default_factory=list)
    """One line per judged candidate: planner, mends, nominal outcome, robustness."""

    def __post_init__(self) -> None:
        self.worlds = perturbed_worlds(self.scene, self.options.judge_worlds,
                                       tree_seed(self.seed, JUDGE_SEED_OFFSET))

    def judged(self, trajectory: Trajectory, states: tuple[State, ...], planner: str,
               result: PlanResult, mends: int = 0,
               static: frozenset[str] = frozenset()) -> Judged:
        verdict = judge(self.scene, trajectory, self.worlds, tilt_bound=self.options.tilt_bound,
                        nominal_decides=True, cancel=self.cancel)
        self.seconds += verdict.wall_time_s
        candidate = Judged(trajectory, states, verdict, planner, result, mends, static)
        self.tried.append(candidate)
        outcome = failure(verdict, self.scene) or "reached"
        judged = (f"{verdict.reached}/{len(verdict.perturbed)} perturbed" if verdict.complete
                  else "perturbed worlds not judged")
        self.log.append(f"{planner}{'+mend' * mends}: {outcome}, {judged}")
        return candidate

    def answer(self) -> Judged:
        """The best judged candidate, its judgement complete: a candidate that failed in the
        nominal world stopped its perturbed worlds (`judge`'s `nominal_decides`), so the one
        answered is judged in all of them now."""
        best = self.best
        if best.judgement.complete:
            return best
        verdict = judge(self.scene, best.trajectory, self.worlds,
                        tilt_bound=self.options.tilt_bound, cancel=self.cancel)
        self.seconds += verdict.wall_time_s
        return dataclasses.replace(best, judgement=verdict)

    def nominal_only(self, trajectory: Trajectory) -> Judgement:
        """`trajectory` executed in the nominal world alone (a mend's way to its cut)."""
        verdict = judge(self.scene, trajectory, (), tilt_bound=self.options.tilt_bound,
                        cancel=self.cancel)
        self.seconds += verdict.wall_time_s
        return verdict

    def time_left(self) -> bool:
        return self.stop.remaining() > MIN_TIME and not self.stop.cancelled()

    @property
    def best(self) -> Judged:
        return max(self.tried, key=lambda c: c.rank)


def failure(verdict: Judgement, scene: Scene) -> str:
    """'' when the nominal world reached the goal, else what happened there."""
    nominal = verdict.nominal
    if nominal.reached:
        return ""
    if nominal.tipped:
        return f"tipped {', '.join(nominal.tipped)}"
    return f"missed the goal by {nominal.goal_distance_m - scene.goal.radius:.3f} m"


def cut_point(trajectory: Trajectory, judgement: Judgement,
              states: tuple[State, ...] = ()) -> int:
    """Where a mend stops the plan: after a tip, the last point CUT_MARGIN s before an object
    began to tilt (0: the plan tips one at once); after a miss, the first point where an object
    is DIVERGENCE from where the plan's `states` predict it in the nominal 3D world (the
    plan's end when none is)."""
    nominal = judgement.nominal
    if nominal.tipped:
        began = nominal.tilt_from_s if nominal.tilt_from_s is not None else nominal.tipped_at_s
        assert began is not None
        return max(0, int(np.searchsorted(trajectory.times, began - CUT_MARGIN,
                                          side="right")) - 1)
    if DIVERGENCE > 0 and len(states) == len(trajectory) == len(nominal.poses):
        predicted = np.array([s.objects[:, :2] for s in states])
        errors = np.linalg.norm(nominal.poses[:, :, :2] - predicted, axis=2).max(axis=1)
        strayed = np.flatnonzero(errors > DIVERGENCE)
        if strayed.size:
            return int(strayed[0])
    return len(trajectory) - 1


Replan = Callable[[Scene, frozenset[str], int], "tuple[Trajectory, tuple[State, ...]] | str"]
"""How a mend plans on: `replan(scene, static, seed)` -> (trajectory, states) of the
request's own planner from `scene`'s start, with the objects in `static` as obstacles, within
the request's time, unjudged; or why it found no plan."""


def mend(judging: Judging, candidate: Judged, replan: Replan) -> Judged | None:
    """The candidate stopped where its nominal 3D execution left the plan, backed out, and
    planned on from the 3D state there (module doc, 1.), judged; None when it tips an object
    at once, no retreat is clear, the 3D state is not a valid start, or the re-plan finds
    nothing (the log says which)."""
    made = _mend(judging, candidate, replan)
    if isinstance(made, str):
        judging.log.append(f"{candidate.planner}{'+mend' * (candidate.mends + 1)}: not made, "
                           f"{made}")
        return None
    return made


def _mend(judging: Judging, candidate: Judged, replan: Replan) -> Judged | str:
    """`mend`'s work: the mended candidate, or why there is none."""
    scene, trajectory = judging.scene, candidate.trajectory
    nominal = candidate.judgement.nominal
    point = cut_point(trajectory, candidate.judgement, candidate.states)
    if point == 0:
        return "the plan tips an object from its start"
    head = trajectory if point == len(trajectory) - 1 else cut(trajectory, point)
    states = candidate.states[:point + 1]
    after = nominal.final if head is trajectory else judging.nominal_only(head).nominal.final
    # The retreat continues the command from where it stopped: the servo holds the arm at the
    # last commanded point, which the 3D arm may miss by its tracking error (a few mrad while it
    # presses on an object), and a spliced trajectory must not jump.
    rest = State(head.positions[-1], after.objects)
    moves = retreat_path(scene.with_start(rest.q, rest.objects), rest, head.positions)
    if moves is None:
        return "no retreat out of contact is clear"
    if len(moves) > 1:
        back = time_parameterize(scene.robot, moves, judging.timing)
        head = splice(head, back)
        states = states + tuple(State(q, after.objects) for q in back.positions)
        ran = judging.nominal_only(head).nominal
        if ran.tipped:
            return f"the retreat tipped {', '.join(ran.tipped)}"
        after = ran.final
    static = candidate.static | frozenset(n for n in nominal.tipped
                                          if n != scene.objects[scene.goal_index].name)
    apart = separate_objects(scene, after.objects)
    if apart is None:
        return "the objects overlap where 3D left them"
    try:            # the arm at rest where it was commanded, the objects where 3D left them
        start = scene.with_start(head.positions[-1], apart)
        check_scene(start)
    except SceneError as exc:
        return f"the 3D state is no start: {exc}"
    planned = replan(start, static, tree_seed(judging.seed, MEND_SEED_OFFSET + len(judging.tried)))
    if isinstance(planned, str):
        return f"the re-plan: {planned}"
    tail, tail_states = planned
    return judging.judged(splice(head, tail), states + tail_states, candidate.planner,
                          candidate.result, candidate.mends + 1, static)


def mended(judging: Judging, candidate: Judged, replan: Replan) -> Judged:
    """`candidate`, mended up to `mends` times while it is not accepted, misses or tips in the
    nominal world, and time remains; the last mend that could be made (or `candidate`)."""
    options = judging.options
    for _ in range(options.mends):
        if candidate.accepted(options) or candidate.judgement.nominal.reached \
                or not judging.time_left():
            break
        better = mend(judging, candidate, replan)
        if better is None:
            break
        candidate = better
    return candidate


@dataclass(frozen=True)
class JudgeSummary:
    """What the 3D judge saw of a request's answer (`PlanOutput.judged`): the CLI's JSON, the
    action's result, the status and the recording say it."""

    reached: bool
    """The answer reached the goal in the nominal 3D world, nothing tipped."""
    failure: str
    """'' or what it did instead ('tipped box' or 'missed the goal by 0.031 m')."""
    robustness: float
    worlds: int
    """Perturbed worlds judged."""
    planner: str
    """The planner that found the answer's first plan."""
    mends: int
    candidates: tuple[str, ...]
    """Every judged candidate, in order (`Judging.log`)."""
    seconds: float
    """The judge's own wall time."""
    max_tilt_deg: float
    """The largest tilt of any object in the nominal world."""

    @classmethod
    def of(cls, judging: Judging, answer: Judged) -> JudgeSummary:
        nominal, verdict = answer.judgement.nominal, answer.judgement
        return cls(nominal.reached, failure(verdict, judging.scene), verdict.robustness,
                   len(verdict.perturbed), answer.planner, answer.mends, tuple(judging.log),
                   judging.seconds, math.degrees(float(nominal.max_tilt.max(initial=0.0))))

    def to_dict(self) -> dict:
        return {"reached": self.reached, "failure": self.failure,
                "robustness": self.robustness, "worlds": self.worlds,
                "planner": self.planner, "mends": self.mends,
                "candidates": list(self.candidates), "seconds": round(self.seconds, 3),
                "max_tilt_deg": round(self.max_tilt_deg, 2)}
