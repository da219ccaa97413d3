"""PC-RRT: the physics-constrained kinodynamic RRT of King et al. 2015 (Algorithm 1, §III).

The tree grows over full states x = (q, o^1 ... o^M). Each iteration samples x_rand
(SampleConfiguration, §III-B), finds the nearest node by the weighted metric (§III-D), samples
k actions (k = 3 in §V), propagates each with ConstrainedProp (Algorithm 2,
`propagation.constrained_prop`) and keeps the one that ends closest to x_rand. The plan is
found when a state has the goal object's centre inside the goal region.

Sampling (`PCRRTOptions.sampler`):
- 'uniform': the paper's rejection sampler: arm configuration uniform in the joint limits,
  every object uniform on the table, rejected while objects overlap (§III-B).
- 'tool': the same for the objects, but the arm is represented by its tool position, sampled
  uniformly over the table (the metric then compares tool positions instead of joint vectors,
  which on the pushing manifold says more about where the arm can push next).
Goal bias (`goal_bias`): with this probability the goal object is sampled inside the goal
region. The metric weighs the goal object higher (`goal_weight`), as §III-D suggests.

Beyond the paper, switchable (`push_policy`): a push bias (one of the k actions a closed-loop
push), a greedy goal push from every new best node and clearing of blocking objects.
`push_bias=0, greedy_goal=False` is the paper's planner.

Reproducible: all randomness comes from one numpy Generator seeded by the request.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

from rearrangement_planner.model.scene import Scene
from rearrangement_planner.model.settings import SettingError, setting
from rearrangement_planner.model.state import State
from rearrangement_planner.physics.collision import CollisionWorld
from rearrangement_planner.physics.step import Invalid, Physics
from rearrangement_planner.planning.machinery.approach import approach_path
from rearrangement_planner.planning.machinery.interface import (
    Outcome,
    PlannerOptions,
    PlanResult,
    ProgressCallback,
    PushingPlannerOptions,
    StopReason,
)
from rearrangement_planner.planning.machinery.manifold import project_arrays
from rearrangement_planner.planning.machinery.propagation import (
    GOAL,
    Propagation,
    PushTarget,
    Stops,
    policy_array,
)
from rearrangement_planner.planning.machinery.push_policy import PushPolicy
from rearrangement_planner.planning.machinery.search import Search
from rearrangement_planner.planning.machinery.termination import CLOCK, Termination
from rearrangement_planner.planning.machinery.tree import Tree
from rearrangement_planner.planning.planners.pcrrt_kernel import (
    HAND_OVER,
    NO_ROOM,
    IterationArrays,
    iterations,
)

_NAMING = (Invalid.TIPPING, Invalid.TURNING)
"""The rules whose refusal names the object that would tip or turn too fast."""
SLICE = 0.01
"""s: how long one compiled call of iterations runs before the search asks its cancel, its
race's gate and its progress report (the deadline is read inside)."""
MAX_BATCH = 1_000_000
"""Iterations one compiled call may run (SLICE ends it first)."""


@dataclass(frozen=True)
class PCRRTOptions(PushingPlannerOptions):
    """PC-RRT's settings (and the Static RRT's)."""

    k_actions: int = setting(3, low=1, high=100)
    """Actions sampled and propagated per iteration (k of Algorithm 1)."""
    max_yaw_rate: float = setting(0.5, low=0.0, high=10.0)
    """Bound on the tool yaw rate of an action, rad/s."""
    min_duration: float = setting(0.5, low=0.001, high=60.0)
    """Shortest action duration, s (at most max_duration)."""
    max_duration: float = setting(2.0, low=0.001, high=60.0)
    """Longest action duration, s."""
    sampler: str = setting("tool", choices=("tool", "uniform"))
    """State sampler: 'uniform' (the paper's, over joint configurations) or 'tool' (the tool
    position over the table; the metric then compares tool positions)."""
    arm_weight: float = setting(0.5, low=0.0, high=1000.0)
    """w_q of the metric: per rad of joint distance ('uniform') or per m of tool distance."""
    push_bias: float = setting(0.6, low=0.0, high=1.0)
    """Probability that an iteration replaces one of its k random actions by a closed-loop push
    of one object towards its sampled position (`push_policy`); 0 = the paper's PC-RRT."""
    push_goal_share: float = setting(0.5, low=0.0, high=1.0)
    """Share of the push-bias pushes aimed at the goal object."""
    push_steps: int = setting(30, low=1, high=10000)
    """Longest closed-loop push, in steps of dt."""
    greedy_goal: bool = setting(True)
    """On every new best goal distance, push the goal object from that node straight for the
    goal (a greedy extension, like the Connect step of RRT-Connect)."""
    face_push: bool = setting(True)
    """The closed-loop pushes turn the hand to face the push, its flat face across the push
    line (a line contact, the stable push of Lynch & Mason 1996), instead of keeping the
    hand's yaw; the turn has its own bound (`propagation.FACING_YAW_RATE`, 1 rad/s), not
    max_yaw_rate, which bounds the random actions. Measured: docs/experiments.md."""

    def __post_init__(self) -> None:
        super().__post_init__()
        if self.min_duration > self.max_duration:
            raise SettingError("min_duration",
                               f"min_duration ({self.min_duration:g} s) must be at most "
                               f"max_duration ({self.max_duration:g} s)")


def sample_arrangement(scene: Scene, rng: np.random.Generator, goal_bias: float,
                       goal_radius: float, goal_xy: np.ndarray, world: CollisionWorld
                       ) -> np.ndarray:
    """Object poses (M, 3) for a sample (King et al. 2015, §III-B): each object uniform on the
    table, the goal object within `goal_radius` of `goal_xy` with probability `goal_bias`,
    redrawn while objects overlap (at most 100 draws)."""
    lo, hi = scene.table.lower, scene.table.upper
    m = len(scene.objects)
    objects = np.empty((m, 3))
    for _ in range(100):
        objects[:, 0] = rng.uniform(lo[0], hi[0], m)
        objects[:, 1] = rng.uniform(lo[1], hi[1], m)
        objects[:, 2] = rng.uniform(-math.pi, math.pi, m)
        if rng.random() < goal_bias:
            r = goal_radius * math.sqrt(rng.random())
            a = rng.uniform(-math.pi, math.pi)
            objects[scene.goal_index, :2] = goal_xy + r * np.array([math.cos(a), math.sin(a)])
        if not world.objects_overlap(objects):
            break
    return objects


class PCRRT:
    """PC-RRT on one scene (models + options)."""

    name = "pc-rrt"

    def __init__(self, scene: Scene, options: PlannerOptions | None = None,
                 physics: Physics | None = None):
        self.scene = scene
        self.options = PCRRTOptions.adopt(options)
        self.physics = physics or Physics(scene)
        self.robot = self.physics.robot
        weights = np.full(len(scene.objects), self.options.object_weight)
        weights[scene.goal_index] = self.options.goal_weight
        self._weights = weights
        self._goal_xy = np.asarray(scene.goal.position, dtype=float)
        self._tool_frame = self.robot.tool_frame_id
        opts = self.options
        self._action_low = np.array([-opts.max_speed, -opts.max_speed, -opts.max_yaw_rate,
                                     opts.min_duration])
        self._action_span = np.array([opts.max_speed, opts.max_speed, opts.max_yaw_rate,
                                      opts.max_duration]) - self._action_low

    # -- the algorithm -------------------------------------------------------------------------

    def plan(self, start: State | None = None, seed: int = 0, stop: Termination | None = None,
             progress: ProgressCallback | None = None) -> PlanResult:
        """Algorithm 1 (the `Planner` protocol): `stop` is asked between compiled calls of
        iterations (every SLICE seconds at most) and, its deadline, between batches of
        propagation steps."""
        run = _Run(self, seed, stop, progress)
        start = start or self.scene.initial_state()
        early = run.begin(start)
        if early is not None:
            return early
        while True:
            ended = run.check()
            if ended is not None:
                return ended
            found = self._iterations(run)
            if found is not None:
                return found

    def _iterations(self, run: _Run) -> PlanResult | None:
        """Iterations of Algorithm 1 (sample, nearest, k propagations, add the best), in one
        compiled call (`pcrrt_kernel.iterations`) for up to SLICE seconds, the termination's
        iteration bound or until one needs Python: a propagation that reached the goal or a
        new best goal distance, added here with the greedy goal pushes from it
        (`_extend`). Returns the plan when the goal is reached."""
        tree, a = run.tree, run.arrays
        bound = run.termination.max_iterations
        most = MAX_BATCH if bound is None else max(1, min(MAX_BATCH, bound - run.iterations))
        a.counters[0], a.counters[1], a.best[0] = tree.n, tree.steps, run.best
        iterations(run.rng, CLOCK, run.termination.deadline, time.monotonic() + SLICE, most,
                   tree.arrays, a.counters, a.best, a.refused, a.naming, a.ints, a.reals,
                   a.goal_xy, a.table, a.limits, a.weights, a.others, a.action, a.pushes,
                   a.held, a.overlap, a.goal, a.project, a.world, a.arm, a.objects, a.flags,
                   a.results, a.features, a.sample_arm, a.sample_objects, a.clock)
        tree.n, tree.steps, run.best = int(a.counters[0]), int(a.counters[1]), float(a.best[0])
        run.iterations += int(a.counters[2])
        run.count(int(a.counters[3]), a.refused)
        why = a.counters[4]
        if why == NO_ROOM:
            tree.make_room(a.arm.shape[1])
        if why != HAND_OVER or run.stop.interrupted() is not None:
            return None                 # a search past its deadline or cancelled ends next
        near, chosen = int(a.counters[5]), int(a.counters[6])
        steps, code, named = (int(v) for v in a.results[chosen])
        stopped = self._stopped(code)
        arm, objects = a.arm[chosen, :steps].copy(), a.objects[chosen, :steps].copy()
        arm.setflags(write=False)
        objects.setflags(write=False)
        result = Propagation(arm, objects, steps * self.options.dt, stopped,
                             self.physics.pushing_links(a.flags[chosen]),
                             named if stopped in _NAMING else -1)
        feature = None if stopped is StopReason.GOAL else a.features[chosen].copy()
        return self._extend(run, near, result, feature)

    def _stopped(self, code: int) -> Invalid | StopReason | None:
        """Why the handed-over propagation of `pcrrt_kernel.iterations` stopped, from its code
        (never TIMED_OUT: a call past its deadline hands nothing over)."""
        if code > 0:
            return self.physics.reason(code)
        return StopReason.GOAL if code == -GOAL else None

    def iteration_arrays(self, stop: Stops) -> IterationArrays:
        """What `pcrrt_kernel.iteration` reads of this planner, and its buffers."""
        scene, opts, physics, robot = self.scene, self.options, self.physics, self.robot
        g, m, k = scene.goal_index, len(scene.objects), opts.k_actions
        pushable = np.flatnonzero(self._weights > 0)
        uniform = opts.sampler == "uniform"
        steps = max(opts.push_steps, round(opts.max_duration / opts.dt) + 1)
        feature = robot.nq if uniform else 2
        reasons = physics.reasons()
        table = np.array([scene.table.lower[:2], scene.table.upper[:2]], dtype=float)
        pushes = np.array([policy_array(physics, PushTarget(i, (0.0, 0.0), opts.max_speed,
                                                            opts.face_push))
                           for i in range(m)])
        return IterationArrays(
            ints=np.array([m, g, k, int(uniform), opts.push_steps, pushable.size,
                           int(opts.greedy_goal)], dtype=np.int64),
            reals=np.array([opts.goal_bias, opts.goal_radius(scene), opts.arm_weight,
                            opts.push_bias, opts.push_goal_share, opts.dt,
                            opts.nullspace_speed]),
            goal_xy=np.array(self._goal_xy, dtype=float), table=table,
            limits=np.array([robot.lower, robot.upper], dtype=float),
            weights=np.array(self._weights, dtype=float),
            others=np.array(pushable[pushable != g], dtype=np.int64),
            action=np.array([self._action_low, self._action_span]),
            pushes=pushes, held=np.array(policy_array(physics, None)),
            overlap=physics.world.overlap_arrays(), goal=np.array(stop.packed),
            project=project_arrays(robot, scene.table.height), world=physics.arrays,
            arm=np.zeros((k, steps, robot.nq)), objects=np.zeros((k, steps, m, 3)),
            flags=np.zeros((k, physics.flag_count), dtype=np.int64),
            results=np.zeros((k, 3), dtype=np.int64), features=np.zeros((k, feature)),
            sample_arm=np.zeros(feature), sample_objects=np.zeros((m, 3)),
            clock=np.zeros(2, dtype=np.int64), counters=np.zeros(7, dtype=np.int64),
            best=np.zeros(1), refused=np.zeros((len(reasons), 2), dtype=np.int64),
            naming=np.array([r in _NAMING for r in reasons], dtype=np.int64))

    def _extend(self, run: _Run, parent: int, chosen: Propagation,
                arm: np.ndarray | None = None) -> PlanResult | None:
        """Add the chosen edge (`arm`: its end's `_arm_feature`, if known); from a new best
        goal distance, push the goal object on for the goal (`greedy_goal`) and add that edge
        too, as long as each brings a new best."""
        while True:
            end = chosen.end
            node = run.tree.add(end, self._arm_feature(end.q) if arm is None else arm, parent,
                                chosen)
            arm = None
            if chosen.stopped is StopReason.GOAL:
                return run.reached(node, self._goal_distance(end))
            distance = self._goal_distance(end)
            if (distance >= run.best - 1e-3 or not self.options.greedy_goal
                    or chosen.stopped in (StopReason.CANCEL, StopReason.TIMEOUT)):
                run.best = min(run.best, distance)
                return None
            run.best = distance
            chosen = run.policy.goal_push(end, run.rng, run.stop)
            run.propagated(chosen)
            if not chosen.count:
                return None
            parent = node

    # -- pieces ---------------------------------------------------------------------------------

    def stop_check(self, termination: Termination) -> Stops:
        """Ends a propagation early: GOAL (the goal object is in the goal region), or CANCEL or
        TIMEOUT when `termination` says so (an action that would run past the time limit is
        cut, so a plan is never found after its budget)."""
        return Stops(self.scene.goal_index, (float(self._goal_xy[0]), float(self._goal_xy[1])),
                     self.options.goal_radius(self.scene), termination)

    def goal_distance(self, state: State) -> float:
        """Distance (m) of the goal object's centre from the goal point."""
        return self._goal_distance(state)

    def _goal_distance(self, state: State) -> float:
        return float(np.hypot(*(state.objects[self.scene.goal_index, :2] - self._goal_xy)))

    def _arm_feature(self, q: np.ndarray) -> np.ndarray:
        """What the metric compares of the arm: q ('uniform') or the tool's (x, y) ('tool')."""
        if self.options.sampler == "uniform":
            return np.asarray(q, dtype=float)
        return self.robot.frame_position(q, self._tool_frame)[:2]

class _Run(Search):
    """One `PCRRT.plan` call: the shared bookkeeping (`Search`), the push policy, the stop
    check of every propagation and the approach onto the manifold."""

    def __init__(self, planner: PCRRT, seed: int, stop: Termination | None,
                 progress: ProgressCallback | None):
        super().__init__(planner.options, seed, stop, progress)
        self.planner = planner
        self.stop = planner.stop_check(self.termination)
        self.policy = PushPolicy(planner.physics, planner.options,
                                 np.flatnonzero(planner._weights > 0))
        self.arrays = planner.iteration_arrays(self.stop)
        self.approach: list[State] = []

    def begin(self, start: State) -> PlanResult | None:
        """Check the start and plan the approach onto the manifold; a result ends the plan."""
        planner, seed = self.planner, self.seed
        ended = self.check_start(planner.physics, start)
        if ended is not None:
            return ended
        approach, why = approach_path(planner.physics, start, self.rng)
        if approach is None:
            return PlanResult(Outcome.START_INVALID, why, seed, plan_time=self.elapsed(),
                              best_goal_distance=self.best)
        self.approach = approach
        self.tree = Tree(approach[-1], planner._arm_feature(approach[-1].q))
        return None

    def reached(self, node: int, distance: float) -> PlanResult:
        return self.success(self.approach[:-1] + self.tree.path_to(node, self.approach[-1]),
                            distance)
