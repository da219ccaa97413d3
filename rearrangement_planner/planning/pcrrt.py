"""PC-RRT: the physics-constrained kinodynamic RRT of King et al. (Algorithm 1, §III).

The tree grows over full states x = (q, o^1 ... o^M). Each iteration samples x_rand
(SampleConfiguration, §III-B), finds the nearest node by the weighted metric (§III-D), samples
k actions (k = 3 in §V), propagates each with ConstrainedProp (Algorithm 2) and keeps the one
that ends closest to x_rand. The plan is found when a state has the goal object's centre inside
the goal region.

Sampling (`PlannerOptions.sampler`):
- 'uniform': the paper's rejection sampler: arm configuration uniform in the joint limits,
  every object uniform on the table, rejected while objects overlap (§III-B).
- 'tool': the same for the objects, but the arm is represented by its tool position, sampled
  uniformly over the table (the metric then compares tool positions instead of joint vectors,
  which on the pushing manifold says more about where the arm can push next).
Goal bias (`goal_bias`): with this probability the goal object is sampled inside the goal
region. The metric weighs the goal object higher (`goal_weight`), as §III-D suggests.

Reproducible: all randomness comes from one numpy Generator seeded by the request.
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from enum import Enum

import numpy as np

from rearrangement_planner.model.scene import Scene
from rearrangement_planner.model.state import State
from rearrangement_planner.physics.step import Invalid, Physics
from rearrangement_planner.planning.approach import approach_path
from rearrangement_planner.planning.propagation import (
    Action,
    Propagation,
    constrained_prop,
    push_policy_prop,
)

_Leg = tuple[int, np.ndarray, bool]
"""One closed-loop push of a chained action: object, where to, must it move (`_push_past`)."""

SUPERSEDED = "superseded: another tree of the race found a plan in fewer iterations"

GREEDY_STEPS = 3
"""The greedy goal push may take this many times `push_steps` (it has to go round the goal
object and then push it all the way)."""


class Outcome(str, Enum):
    """Planning outcome codes (DESIGN §4, modelled on Nav2)."""

    SUCCEEDED = "SUCCEEDED"
    START_INVALID = "START_INVALID"
    GOAL_INVALID = "GOAL_INVALID"
    TIMEOUT = "TIMEOUT"
    CANCELLED = "CANCELLED"
    INVALID_INPUT = "INVALID_INPUT"
    INTERNAL = "INTERNAL"


@dataclass(frozen=True)
class PlannerOptions:
    time_limit: float = 30.0
    """Wall-clock budget, s. Running out is a failure (TIMEOUT), never an approximate plan."""
    max_iterations: int = 1_000_000
    """Iteration budget (also a TIMEOUT when exhausted)."""
    k_actions: int = 3
    """Actions sampled and propagated per iteration (k of Algorithm 1)."""
    dt: float = 0.1
    """Propagation step Δt of Algorithm 2, s."""
    max_speed: float = 0.10
    """Bound on each planar tool velocity component, m/s."""
    max_yaw_rate: float = 0.5
    """Bound on the tool yaw rate, rad/s."""
    min_duration: float = 0.5
    """Shortest action duration, s."""
    max_duration: float = 2.0
    """Longest action duration, s."""
    nullspace_speed: float = 0.3
    """Bound on each component of the per-action nullspace joint velocity, rad/s."""
    sampler: str = "tool"
    """'uniform' (the paper's sampler over joint configurations) or 'tool' (see module doc)."""
    goal_bias: float = 0.2
    """Probability of sampling the goal object inside the goal region."""
    arm_weight: float = 0.5
    """w_q of the metric: per rad of joint distance ('uniform') or per m of tool distance."""
    object_weight: float = 1.0
    """w_i of the metric for the non-goal objects, per m."""
    goal_weight: float = 5.0
    """w_i of the metric for the goal object, per m."""
    progress_period: float = 0.5
    """Seconds between progress callbacks."""
    push_bias: float = 0.6
    """Probability that an iteration replaces one of its k random actions by a closed-loop
    push (`propagation.push_policy_prop`) of one object towards its sampled position: the goal
    object with probability `push_goal_share`, else a random other object. 0 = the paper's
    PC-RRT."""
    push_goal_share: float = 0.5
    """Share of push-bias pushes aimed at the goal object."""
    push_steps: int = 30
    """Longest closed-loop push, in steps of dt."""
    greedy_goal: bool = True
    """Whenever a new node brings the goal object closer to the goal than any before, try at
    once a closed-loop push of the goal object from it to the goal centre (a greedy
    extension, like the Connect step of RRT-Connect; needs push_bias > 0 only for its
    blocked-push handling)."""
    clear_blockers: bool = True
    """When a push-bias push of the goal object ends against another object, push that object
    out of the goal object's way and push on, within the same action (`_clear_and_push`)."""
    push_yaw_rate: float = 0.0
    """Yaw rate (rad/s) at which the closed-loop pushes turn the hand to push finger first
    (`propagation.push_policy_prop`); 0 = the hand keeps its yaw and the tool point is taken
    as the pusher."""
    avoid_others: bool = False
    """The closed-loop pushes' approach slides the tool round the objects it is not pushing
    (`propagation._around_others`) instead of running straight into them."""
    detour: float = 0.0
    """When a push of the goal object towards the goal (greedy or push-bias) ends against
    another object, the probability of going round that object (`_detour_push`) rather than
    clearing it out of the way (`_clear_and_push`, if `clear_blockers`)."""
    trees: int = 1
    """Independent trees grown at once on separate processes, the first plan in iteration
    order winning (`parallel`, OR-parallel RRT); 1 = one tree in this process. Honoured by
    `pipeline.plan_scene` (the CLI, the node and the benchmarks), not by `PCRRT.plan` itself."""
    fail_penalty: float = 0.0
    """Added to a node's metric distance in Nearest for every extension from it that made no
    progress towards its sample (nothing valid, or ending no closer than the node): dead ends
    such as a goal object pushed out of the arm's reach near the goal stop attracting the
    goal-biased samples. 0 = the plain Voronoi bias of Algorithm 1."""

    def __post_init__(self) -> None:
        if self.sampler not in ("uniform", "tool"):
            raise ValueError(f"sampler must be 'uniform' or 'tool', not {self.sampler!r}")
        for name in ("goal_bias", "push_bias", "push_goal_share", "detour"):
            if not 0.0 <= getattr(self, name) <= 1.0:
                raise ValueError(f"{name} must be in [0, 1], not {getattr(self, name)}")
        if self.push_yaw_rate < 0 or self.fail_penalty < 0:
            raise ValueError("push_yaw_rate and fail_penalty must be >= 0")
        if self.push_steps < 1:
            raise ValueError(f"push_steps must be >= 1, not {self.push_steps}")
        if not 0 < self.min_duration <= self.max_duration:
            raise ValueError("need 0 < min_duration <= max_duration")
        if not 1 <= self.trees <= 64:
            raise ValueError(f"trees must be between 1 and 64, not {self.trees}")
        if self.k_actions < 1 or self.dt <= 0 or self.time_limit <= 0:
            raise ValueError("k_actions >= 1, dt > 0 and time_limit > 0 are required")


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


class _Tree:
    """Nodes stored in growing arrays so that Nearest is one vectorised expression."""

    def __init__(self, root: State, root_arm: np.ndarray, capacity: int = 1024):
        self.n = 0
        self.q = np.empty((capacity, root.q.size))
        self.arm = np.empty((capacity, root_arm.size))
        self.objects = np.empty((capacity, *root.objects.shape))
        self.fails = np.zeros(capacity)
        self.parent: list[int] = []
        self.segments: list[tuple[State, ...]] = []
        self.add(root, root_arm, -1, ())

    def add(self, state: State, arm: np.ndarray, parent: int, segment: tuple[State, ...]) -> int:
        if self.n == len(self.arm):
            self.q = np.concatenate([self.q, np.empty_like(self.q)])
            self.arm = np.concatenate([self.arm, np.empty_like(self.arm)])
            self.objects = np.concatenate([self.objects, np.empty_like(self.objects)])
            self.fails = np.concatenate([self.fails, np.zeros_like(self.fails)])
        self.q[self.n] = state.q
        self.arm[self.n] = arm
        self.objects[self.n] = state.objects
        self.parent.append(parent)
        self.segments.append(segment)
        self.n += 1
        return self.n - 1

    def path_to(self, node: int, root: State) -> list[State]:
        pieces = []
        while node > 0:
            pieces.append(self.segments[node])
            node = self.parent[node]
        states = [root]
        for piece in reversed(pieces):
            states.extend(piece)
        return states


class PCRRT:
    """PC-RRT on one scene (models + options, STYLE 1)."""

    name = "pc-rrt"

    def __init__(self, scene: Scene, options: PlannerOptions | None = None,
                 physics: Physics | None = None):
        self.scene = scene
        self.options = options or PlannerOptions()
        self.physics = physics or Physics(scene)
        self.robot = self.physics.robot
        m = len(scene.objects)
        weights = np.full(m, self.options.object_weight)
        weights[scene.goal_index] = self.options.goal_weight
        self._weights = weights
        self._goal_xy = np.asarray(scene.goal.position, dtype=float)
        self._tool_frame = self.robot.tool_frame_id

    # -- the algorithm -------------------------------------------------------------------------

    def plan(self, start: State | None = None, seed: int = 0,
             cancel: threading.Event | None = None,
             progress: Callable[[Progress], None] | None = None,
             iteration_gate: Callable[[int], bool] | None = None) -> PlanResult:
        """Algorithm 1. `cancel` is checked every iteration and every propagation step.
        `iteration_gate(i)`, if given, is asked before iteration i; False ends the plan as
        CANCELLED (`parallel`: another tree of a race has already found a better plan)."""
        t0 = time.monotonic()
        opts = self.options
        start = start or self.scene.initial_state()
        problem = self.physics.check_state(start)
        if problem is not None:
            return PlanResult(Outcome.START_INVALID, f"start state invalid: {problem[1]}", seed)
        rng = np.random.default_rng(seed)
        best = self._goal_distance(start)
        if best <= self.scene.goal.radius:
            return PlanResult(Outcome.SUCCEEDED, "start already in the goal region", seed,
                              (start,), plan_time=time.monotonic() - t0, best_goal_distance=best)
        approach, why = approach_path(self.physics, start, rng)
        if approach is None:
            return PlanResult(Outcome.START_INVALID, why, seed, plan_time=time.monotonic() - t0,
                              best_goal_distance=best)
        root = approach[-1]
        tree = _Tree(root, self._arm_feature(root.q))
        iterations = steps = 0
        last_report = t0
        cancelled = cancel.is_set if cancel is not None else (lambda: False)
        stop = self._stop_check(cancelled, t0 + opts.time_limit)
        while True:
            now = time.monotonic()
            if cancelled():
                return self._failure(Outcome.CANCELLED, "cancelled", seed, tree, iterations,
                                     steps, t0, best)
            if now - t0 > opts.time_limit or iterations >= opts.max_iterations:
                return self._failure(Outcome.TIMEOUT, f"no plan within {opts.time_limit:g} s / "
                                     f"{iterations} iterations", seed, tree, iterations, steps,
                                     t0, best)
            if progress is not None and now - last_report >= opts.progress_period:
                progress(Progress(iterations, tree.n, best, now - t0))
                last_report = now
            if iteration_gate is not None and not iteration_gate(iterations + 1):
                return self._failure(Outcome.CANCELLED, SUPERSEDED, seed, tree, iterations,
                                     steps, t0, best)
            iterations += 1
            sample_arm, sample_objects = self._sample(rng)
            near = self._nearest(tree, sample_arm, sample_objects)
            x_near = State(tree.q[near], tree.objects[near])
            near_cost = self._distance(tree.arm[near], x_near.objects, sample_arm,
                                       sample_objects)
            chosen, chosen_cost = None, math.inf
            policy = opts.push_bias > 0 and rng.random() < opts.push_bias
            for k in range(opts.k_actions):
                if policy and k == 0:
                    result = self._policy_push(x_near, sample_objects, rng, stop)
                else:
                    result = constrained_prop(self.physics, x_near, self._sample_action(rng),
                                              opts.dt, stop)
                steps += len(result.states)
                if not result.states:
                    continue
                end = result.states[-1]
                cost = self._distance(self._arm_feature(end.q), end.objects,
                                      sample_arm, sample_objects)
                if result.stopped == "goal":
                    cost = -math.inf
                if cost < chosen_cost:
                    chosen, chosen_cost = result, cost
                if result.stopped in ("cancel", "timeout"):
                    break
            if chosen is None or chosen_cost >= near_cost:
                tree.fails[near] += 1.0
            if chosen is None:
                continue
            parent = near
            while True:
                end = chosen.states[-1]
                node = tree.add(end, self._arm_feature(end.q), parent, chosen.states)
                if chosen.stopped == "goal":
                    states = approach[:-1] + tree.path_to(node, root)
                    return PlanResult(Outcome.SUCCEEDED, f"goal reached after {iterations} "
                                      f"iterations", seed, tuple(states), iterations, tree.n,
                                      steps, time.monotonic() - t0, self._goal_distance(end))
                distance = self._goal_distance(end)
                if (distance >= best - 1e-3 or not opts.greedy_goal
                        or chosen.stopped in ("cancel", "timeout")):
                    best = min(best, distance)
                    break
                # A new best: push the goal object from it straight for the goal (greedy).
                best = distance
                chosen = self._goal_push(end, rng, stop)
                steps += len(chosen.states)
                if not chosen.states:
                    break
                parent = node

    # -- pieces ---------------------------------------------------------------------------------

    def _stop_check(self, cancelled: Callable[[], bool],
                    deadline: float) -> Callable[[State], str | None]:
        """Ends a propagation early: 'goal' (the goal object is in the goal region), 'cancel',
        or 'timeout' (past the `time.monotonic()` deadline: an action that would run past the
        time limit is cut, so a plan is never found after its budget)."""
        radius = self.scene.goal.radius
        g = self.scene.goal_index

        def stop(state: State) -> str | None:
            if time.monotonic() > deadline:
                return "timeout"
            if float(np.hypot(*(state.objects[g, :2] - self._goal_xy))) <= radius:
                return "goal"
            if cancelled():
                return "cancel"
            return None

        return stop

    def _goal_distance(self, state: State) -> float:
        return float(np.hypot(*(state.objects[self.scene.goal_index, :2] - self._goal_xy)))

    def _arm_feature(self, q: np.ndarray) -> np.ndarray:
        """What the metric compares of the arm: q ('uniform') or the tool's (x, y) ('tool')."""
        if self.options.sampler == "uniform":
            return np.asarray(q, dtype=float)
        return self.robot.frame_pose(q, self._tool_frame)[:2, 3]

    def _sample(self, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
        """SampleConfiguration (§III-B): rejection sampling of object poses without overlap."""
        scene, opts = self.scene, self.options
        lo, hi = scene.table.lower, scene.table.upper
        m = len(scene.objects)
        world = self.physics.world
        for _ in range(100):
            objects = np.column_stack([rng.uniform(lo[0], hi[0], m), rng.uniform(lo[1], hi[1], m),
                                       rng.uniform(-math.pi, math.pi, m)])
            if rng.random() < opts.goal_bias:
                r = scene.goal.radius * math.sqrt(rng.random())
                a = rng.uniform(-math.pi, math.pi)
                objects[scene.goal_index, :2] = self._goal_xy + r * np.array([math.cos(a),
                                                                              math.sin(a)])
            if not world.object_overlaps(objects):
                break
        if opts.sampler == "uniform":
            arm = rng.uniform(self.robot.lower, self.robot.upper)
        else:
            arm = np.array([rng.uniform(lo[0], hi[0]), rng.uniform(lo[1], hi[1])])
        return arm, objects

    def _distance(self, arm: np.ndarray, objects: np.ndarray, sample_arm: np.ndarray,
                  sample_objects: np.ndarray) -> float:
        """Dist(x, x') of §III-D on positions: w_q |arm - arm'| + sum_i w_i |o_i - o'_i|."""
        d_obj = np.hypot(*(objects[:, :2] - sample_objects[:, :2]).T)
        return float(self.options.arm_weight * np.linalg.norm(arm - sample_arm)
                     + self._weights @ d_obj)

    def _nearest(self, tree: _Tree, sample_arm: np.ndarray, sample_objects: np.ndarray) -> int:
        n = tree.n
        d_arm = np.linalg.norm(tree.arm[:n] - sample_arm, axis=1)
        diff = tree.objects[:n, :, :2] - sample_objects[:, :2]
        d_obj = np.sqrt((diff * diff).sum(axis=2)) @ self._weights
        return int(np.argmin(self.options.arm_weight * d_arm + d_obj
                             + self.options.fail_penalty * tree.fails[:n]))

    def _sample_action(self, rng: np.random.Generator) -> Action:
        """SampleAction: uniform in the bounds (§V: 'Actions are uniformly sampled from a
        bounded range'); the duration is a whole number of steps."""
        opts = self.options
        velocity = np.array([rng.uniform(-opts.max_speed, opts.max_speed),
                             rng.uniform(-opts.max_speed, opts.max_speed),
                             rng.uniform(-opts.max_yaw_rate, opts.max_yaw_rate)])
        duration = rng.uniform(opts.min_duration, opts.max_duration)
        duration = max(1, round(duration / opts.dt)) * opts.dt
        nullspace = rng.uniform(-opts.nullspace_speed, opts.nullspace_speed, self.robot.nq)
        return Action(velocity, duration, nullspace)

    def _policy_push(self, x_near: State, sample_objects: np.ndarray, rng: np.random.Generator,
                     stop: Callable[[State], str | None]):
        """The push-bias action: push one object towards its position in the sample."""
        opts = self.options
        g = self.scene.goal_index
        m = len(self.scene.objects)
        movable = np.flatnonzero(self._weights > 0)
        if m == 1 or rng.random() < opts.push_goal_share or movable.size <= 1:
            obj = g
        else:
            others = movable[movable != g]
            obj = int(others[rng.integers(others.size)])
        nullspace = rng.uniform(-opts.nullspace_speed, opts.nullspace_speed, self.robot.nq)
        result = self._push(x_near, obj, sample_objects[obj, :2], opts.push_steps, nullspace,
                            stop)
        if obj != g:
            return result
        return self._when_blocked(x_near, result, sample_objects[g, :2], nullspace, rng, stop)

    def _goal_push(self, x: State, rng: np.random.Generator,
                   stop: Callable[[State], str | None]) -> Propagation:
        """The greedy extension: push the goal object from x towards the goal centre."""
        opts = self.options
        nullspace = rng.uniform(-opts.nullspace_speed, opts.nullspace_speed, self.robot.nq)
        result = self._push(x, self.scene.goal_index, self._goal_xy,
                            GREEDY_STEPS * opts.push_steps, nullspace, stop)
        return self._when_blocked(x, result, self._goal_xy, nullspace, rng, stop)

    def _push(self, x: State, obj: int, where: np.ndarray, steps: int, nullspace: np.ndarray,
              stop: Callable[[State], str | None]) -> Propagation:
        """The closed-loop push of `obj` from x towards `where`, with the options' policy."""
        opts = self.options
        return push_policy_prop(self.physics, x, obj, where, steps, opts.dt, opts.max_speed,
                                nullspace, stop, avoid=opts.avoid_others,
                                yaw_rate=opts.push_yaw_rate)

    def _when_blocked(self, x: State, result: Propagation, target: np.ndarray,
                      nullspace: np.ndarray, rng: np.random.Generator,
                      stop: Callable[[State], str | None]) -> Propagation:
        """A push of the goal object from x towards `target` that ended against another object
        goes on round it or clears it away (`detour`, `clear_blockers`)."""
        opts = self.options
        if result.stopped is not Invalid.OBJECT_OVERLAP:
            return result
        if opts.detour > 0 and (not opts.clear_blockers or rng.random() < opts.detour):
            return self._detour_push(x, result, target, nullspace, rng, stop)
        if opts.clear_blockers:
            return self._clear_and_push(x, result, target, nullspace, rng, stop)
        return result

    def _blocker(self, x: State) -> int:
        """The object nearest to the goal object's footprint (the one a blocked push hit)."""
        g = self.scene.goal_index
        centre = x.objects[g, :2]
        gaps = [float(np.hypot(*(x.objects[i, :2] - centre))) - o.footprint_radius
                if i != g else math.inf for i, o in enumerate(self.scene.objects)]
        return int(np.argmin(gaps))

    def _detour_push(self, x_near: State, blocked: Propagation, target: np.ndarray,
                     nullspace: np.ndarray, rng: np.random.Generator,
                     stop: Callable[[State], str | None]) -> Propagation:
        """The goal object's push towards `target` ran into another object B: push the goal
        object to a point beside B where it is clear of every object (`_via_point`), then on
        towards `target`; up to three times (the next blocker)."""
        g = self.scene.goal_index

        def legs(x: State, u: np.ndarray, perp: np.ndarray) -> list[_Leg] | None:
            via = self._via_point(x, target, u, perp, rng)
            return None if via is None else [(g, via, True), (g, target, True)]

        return self._push_past(x_near, blocked, target, nullspace, stop, 3, legs)

    def _via_point(self, x: State, target: np.ndarray, u: np.ndarray, perp: np.ndarray,
                   rng: np.random.Generator) -> np.ndarray | None:
        """Where to push the goal object to get round the object blocking it: beside the
        blocker, on either side, stepping out (3 cm at a time) until the goal object's
        footprint there is clear of every object and on the table, so that a row of objects
        is gone round as a whole. The shorter way round is taken with probability 3/4."""
        scene = self.scene
        g = scene.goal_index
        centre = x.objects[g, :2]
        b = self._blocker(x)
        others = np.array([i for i in range(len(scene.objects)) if i != g])
        need = scene.objects[g].footprint_radius + np.array(
            [scene.objects[i].footprint_radius for i in others]) + 0.01
        lo = np.asarray(scene.table.lower) + scene.objects[g].footprint_radius
        hi = np.asarray(scene.table.upper) - scene.objects[g].footprint_radius
        ahead = u * rng.uniform(-0.02, 0.04)
        base = scene.objects[g].footprint_radius + scene.objects[b].footprint_radius \
            + rng.uniform(0.01, 0.03)
        options = []
        for side in (-1.0, 1.0):
            for k in range(6):
                via = x.objects[b, :2] + perp * side * (base + 0.03 * k) + ahead
                free = np.all(np.hypot(*(x.objects[others, :2] - via).T) >= need)
                if free and np.all(via >= lo) and np.all(via <= hi):
                    options.append((float(np.hypot(*(via - centre)) + np.hypot(*(target - via))),
                                    via))
                    break
        if not options:
            return None
        options.sort(key=lambda o: o[0])
        return options[0][1] if len(options) == 1 or rng.random() < 0.75 else options[1][1]

    def _clear_and_push(self, x_near: State, blocked: Propagation, target: np.ndarray,
                        nullspace: np.ndarray, rng: np.random.Generator,
                        stop: Callable[[State], str | None]) -> Propagation:
        """The goal object's push towards `target` ran into another object B: push B sideways
        out of the corridor the goal object sweeps on its way to `target` (to a random point
        just clear of it), then push the goal object on; up to twice."""
        scene = self.scene
        g = scene.goal_index

        def legs(x: State, u: np.ndarray, perp: np.ndarray) -> list[_Leg]:
            b = self._blocker(x)
            across = float((x.objects[b, :2] - x.objects[g, :2]) @ perp)
            side = math.copysign(1.0, across) if abs(across) > 1e-3 else rng.choice([-1.0, 1.0])
            clear = (scene.objects[g].footprint_radius + scene.objects[b].footprint_radius
                     + rng.uniform(0.01, 0.05))
            goal_b = x.objects[b, :2] + perp * side * (clear - abs(across)) \
                + u * rng.uniform(-0.03, 0.03)
            return [(b, goal_b, True), (g, target, False)]

        return self._push_past(x_near, blocked, target, nullspace, stop, 2, legs)

    def _push_past(self, x_near: State, blocked: Propagation, target: np.ndarray,
                   nullspace: np.ndarray, stop: Callable[[State], str | None], rounds: int,
                   legs: Callable[[State, np.ndarray, np.ndarray], list[_Leg] | None],
                   ) -> Propagation:
        """Go on from the blocked push of the goal object towards `target`: each round,
        `legs(x, u, perp)` (u towards the target, perp to its left) gives the closed-loop
        pushes (object, where, must_move) to chain; another round while the last one ends in
        an object overlap. The action ends at the goal, on cancel or timeout, or when a
        must_move leg cannot take a step. One action, every step through the physics, so the
        edge replays like any other."""
        opts = self.options
        g = self.scene.goal_index
        states = list(blocked.states)
        links = set(blocked.pushing_links)
        x = states[-1] if states else x_near
        stopped: Invalid | str | None = blocked.stopped
        for _ in range(rounds):
            to_target = target - x.objects[g, :2]
            distance = float(np.hypot(*to_target))
            if distance < 0.01:
                break
            u = to_target / distance
            chain = legs(x, u, np.array([-u[1], u[0]]))
            if chain is None:
                break
            for obj, where, must_move in chain:
                part = self._push(x, obj, where, opts.push_steps, nullspace, stop)
                states.extend(part.states)
                links |= part.pushing_links
                x = states[-1] if states else x_near
                stopped = part.stopped
                if (stopped in ("goal", "cancel", "timeout")
                        or (must_move and stopped is not None and not part.states)):
                    return Propagation(tuple(states), len(states) * opts.dt, stopped,
                                       frozenset(links))
            if stopped is not Invalid.OBJECT_OVERLAP:
                break
        return Propagation(tuple(states), len(states) * opts.dt, stopped, frozenset(links))

    def _failure(self, outcome: Outcome, message: str, seed: int, tree: _Tree, iterations: int,
                 steps: int, t0: float, best: float) -> PlanResult:
        return PlanResult(outcome, message, seed, (), iterations, tree.n, steps,
                          time.monotonic() - t0, best)
