"""Slice-based RRT: the rearrangement planner of Haustein et al. 2018 (Algorithm 1, §II).

The tree grows over full states x = (q, o^1 ... o^M), like PC-RRT's, but its nodes are grouped
into *slices*: the states that share one object arrangement and differ only in the arm. Each
iteration:

1. SAMPLESLICE: an object arrangement s^d, every object uniform on the table, the goal object in
   the goal region with probability `goal_bias`;
2. the slice s^a of the tree closest to s^d (Σ_j w_j |o_j - o^d_j| over object positions, the
   goal object weighted higher);
3. a target t: the robot (probability `robot_share`) or one object, uniformly;
4. the robot state x_r^d to steer to: for the robot a random tool pose over the table; for an
   object the oracle's *manipulation state* in s^a, a place from which one push moves object t
   towards its place in s^d (`Oracle.manipulation_state`);
5. x^a, the state of s^a whose tool is nearest x_r^d;
6. with probability `random_share` a random control from x^a; else the *transit*: the tool
   steered on the pushing plane from x^a towards x_r^d through the same quasistatic physics,
   kept only up to the first step that would move an object (a transit leaves its slice
   unchanged); then, when it arrived and t is an object, the oracle's push
   (`Oracle.push`) through the physics, which moves to another slice.

Every propagation is the compiled Project step and physics of PC-RRT (King et al. 2015,
Algorithm 2; `propagation.constrained_prop`), so any link may push any object, several at
once. The plan is found when a state has the goal object's centre inside the goal region; an
oracle's push is judged where it ends (it is not cut at its first step inside the region, so
that plans end nearer the goal point than its edge).

The oracles, behind one `Oracle` interface: `HandOracle`, the paper's hand-made baseline (the
finger tips just behind the object on the far side from its target, the hand facing the push;
a straight push towards the target), and `learned_oracle.LearnedOracle`, the paper's learned
generator and policy (§II), the default.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from rearrangement_planner.model.scene import Scene
from rearrangement_planner.model.settings import setting
from rearrangement_planner.model.state import State, wrap_angle
from rearrangement_planner.physics.step import Physics
from rearrangement_planner.planning.machinery.approach import approach_path
from rearrangement_planner.planning.machinery.interface import (
    Outcome,
    PlannerOptions,
    PlanResult,
    ProgressCallback,
    PushingPlannerOptions,
    StopReason,
)
from rearrangement_planner.planning.machinery.manifold import tool_planar_pose
from rearrangement_planner.planning.machinery.propagation import (
    Action,
    Propagation,
    Stops,
    constrained_prop,
)
from rearrangement_planner.planning.machinery.push_policy import support_distance
from rearrangement_planner.planning.machinery.search import Search
from rearrangement_planner.planning.machinery.termination import Termination
from rearrangement_planner.planning.machinery.tree import Tree
from rearrangement_planner.planning.planners.learned_oracle import LearnedOracle, shipped_models
from rearrangement_planner.planning.planners.pcrrt import sample_arrangement

MAX_YAW_RATE = 0.5
"""rad/s: the largest tool yaw rate of a transit or a random control."""
ARRIVED = (0.02, 0.15)
"""m, rad: a transit that ends this close to its target pose has arrived there."""
RANDOM_DURATION = (0.5, 2.0)
"""s: the range of a random control's duration."""


@dataclass(frozen=True)
class SliceRRTOptions(PushingPlannerOptions):
    """The slice-based RRT's settings."""

    oracle: str = setting("learned", choices=("learned", "hand"))
    """Where manipulation states and pushes come from: 'learned', the generator and policy
    trained for the scene's robot (`config/models/<robot>_oracle.npz`, Haustein et al. 2018
    §II; results in docs/benchmark.md), or 'hand', their hand-made baseline (the hand behind
    the object, a straight push)."""
    robot_share: float = setting(0.2, low=0.0, high=1.0)
    """Probability that an iteration grows its slice towards a random arm state (t = r in
    Algorithm 1 of Haustein et al. 2018) instead of moving an object."""
    random_share: float = setting(0.1, low=0.0, high=1.0)
    """Probability of a random control from the chosen state instead of a transit and a
    push (p_rand of Algorithm 1)."""
    max_transit: float = setting(6.0, low=0.1, high=60.0)
    """Longest transit, s: a farther target is approached this far."""
    max_push: float = setting(4.0, low=0.1, high=60.0)
    """Longest push, s."""
    standoff: float = setting(0.01, low=0.0, high=0.1)
    """Gap between the finger tips and the object in a hand-made manipulation state, m."""


class Oracle(Protocol):
    """What the slice-based RRT asks of a manipulation model (Haustein et al. 2018, §II): a
    robot state from which object t can be pushed towards its target (the generator), and
    the push (the policy)."""

    def manipulation_state(self, objects: np.ndarray, t: int, target: np.ndarray,
                           rng: np.random.Generator) -> np.ndarray | None:
        """The tool's planar pose (x, y, yaw) to push object `t` of the arrangement `objects`
        towards `target` (x, y) from; None if there is no push to make."""
        ...

    def push(self, tool: np.ndarray, objects: np.ndarray, t: int, target: np.ndarray
             ) -> Action | None:
        """The push of object `t` towards `target` from the tool pose `tool`."""
        ...


class HandOracle:
    """The hand-made oracle (Haustein et al. 2018's baseline): the finger tips `standoff` behind
    the object on the far side from its target, the hand facing the push; the push a straight
    line towards the target at `max_speed`, at most `max_push` s long."""

    def __init__(self, scene: Scene, reach: float, nq: int, options: SliceRRTOptions):
        self.objects = scene.objects
        self.reach = reach
        self.nq = nq
        self.options = options

    def manipulation_state(self, objects: np.ndarray, t: int, target: np.ndarray,
                           rng: np.random.Generator) -> np.ndarray | None:
        u = _unit(target - objects[t, :2])
        if u is None:
            return None
        back = support_distance(self.objects[t], float(objects[t, 2]), -u) + self.reach \
            + self.options.standoff
        x, y = objects[t, :2] - u * back
        return np.array([x, y, math.atan2(u[1], u[0])])

    def push(self, tool: np.ndarray, objects: np.ndarray, t: int, target: np.ndarray
             ) -> Action | None:
        opts = self.options
        offset = target - objects[t, :2]
        u = _unit(offset)
        if u is None:
            return None
        duration = min(float(np.linalg.norm(offset)) / opts.max_speed, opts.max_push)
        return Action(np.array([u[0] * opts.max_speed, u[1] * opts.max_speed, 0.0]), duration,
                      np.zeros(self.nq))


def _unit(v: np.ndarray) -> np.ndarray | None:
    norm = float(np.linalg.norm(v))
    return None if norm < 1e-3 else v / norm


def check_oracle(scene: Scene, options: PlannerOptions) -> None:
    """ValueError when the learned oracle is asked for and has no weights for the scene's arm
    (`PlannerSpec.check`)."""
    from rearrangement_planner.planning.planners.learned_oracle import model_path

    if SliceRRTOptions.adopt(options).oracle != "learned":
        return
    path = model_path(scene.robot.config.name)
    if not path.is_file():
        shipped = sorted(p.name.removesuffix("_oracle.npz")
                         for p in path.parent.glob("*_oracle.npz"))
        raise ValueError(f"oracle: no learned oracle for robot '{scene.robot.config.name}' "
                         f"({path} is missing; shipped for {', '.join(shipped) or 'none'}); "
                         f"use oracle=hand")


class SliceRRT:
    """The slice-based RRT on one scene (models + options)."""

    name = "slice-rrt"

    def __init__(self, scene: Scene, options: PlannerOptions | None = None,
                 physics: Physics | None = None):
        self.scene = scene
        self.options = SliceRRTOptions.adopt(options)
        self.physics = physics or Physics(scene)
        self.robot = self.physics.robot
        self.oracle: Oracle = (
            HandOracle(scene, self.robot.tool_reach, self.robot.nq, self.options)
            if self.options.oracle == "hand"
            else LearnedOracle(scene, shipped_models(self.robot.config.name), self.robot.nq))
        weights = np.full(len(scene.objects), self.options.object_weight)
        weights[scene.goal_index] = self.options.goal_weight
        self._weights = weights
        self._goal_xy = np.asarray(scene.goal.position, dtype=float)

    def plan(self, start: State | None = None, seed: int = 0, stop: Termination | None = None,
             progress: ProgressCallback | None = None) -> PlanResult:
        """Algorithm 1 of Haustein et al. 2018 (the `Planner` protocol)."""
        run = _SliceRun(self, seed, stop, progress)
        early = run.begin(start or self.scene.initial_state())
        if early is not None:
            return early
        while True:
            ended = run.check()
            if ended is not None:
                return ended
            found = self._iteration(run)
            if found is not None:
                return found

    def _iteration(self, run: _SliceRun) -> PlanResult | None:
        """One iteration of Algorithm 1 (module docstring, 1-6)."""
        opts, rng, scene = self.options, run.rng, self.scene
        run.iterations += 1
        desired = sample_arrangement(scene, rng, opts.goal_bias, opts.goal_radius(scene),
                                     self._goal_xy, self.physics.world)
        near = run.nearest_slice(desired, self._weights)
        objects = run.slice_objects[near]
        t: int | None = None
        pose: np.ndarray | None
        if rng.random() < opts.robot_share:
            lo, hi = scene.table.lower, scene.table.upper
            pose = np.array([rng.uniform(lo[0], hi[0]), rng.uniform(lo[1], hi[1]),
                             rng.uniform(-math.pi, math.pi)])
        else:
            t = int(rng.integers(len(scene.objects)))
            pose = self.oracle.manipulation_state(objects, t, desired[t, :2], rng)
        if pose is None:
            return None
        node = run.nearest_in_slice(near, pose[:2])
        x_a = run.tree.state(node)
        if rng.random() < opts.random_share:
            return run.extend(node, constrained_prop(self.physics, x_a, self._random(rng),
                                                     opts.dt, run.stop))
        transit = self._transit(x_a, pose, run.stop)
        found = run.extend(node, transit)
        if found is not None or t is None or not transit.count:
            return found
        end = transit.end
        tool = tool_planar_pose(self.robot, end.q)
        if (np.hypot(*(tool[:2] - pose[:2])) > ARRIVED[0]
                or abs(float(wrap_angle(tool[2] - pose[2]))) > ARRIVED[1]):
            return None
        push = self.oracle.push(tool, end.objects, t, desired[t, :2])
        if push is None:
            return None
        push = Action(push.velocity, max(1, round(push.duration / opts.dt)) * opts.dt,
                      push.nullspace)
        # The push runs to its end (towards its target inside the goal region), not to the
        # first step inside the region: a plan that ends at the region's edge misses it when
        # executed (docs/experiments.md, 2026-11-25).
        return run.extend(run.tree.n - 1, constrained_prop(self.physics, end, push, opts.dt,
                                                           run.push_stop), goal_at_end=True)

    def _transit(self, x: State, pose: np.ndarray, stop: Stops) -> Propagation:
        """The tool steered on the pushing plane from x towards `pose` (x, y, yaw) at most
        `max_speed` (and `MAX_YAW_RATE`), for at most `max_transit` s, through the physics;
        cut before the first step that moves an object (a transit stays in its slice)."""
        opts = self.options
        here = tool_planar_pose(self.robot, x.q)
        delta = np.array([pose[0] - here[0], pose[1] - here[1],
                          float(wrap_angle(pose[2] - here[2]))])
        seconds = max(float(np.abs(delta[:2]).max()) / opts.max_speed,
                      abs(delta[2]) / MAX_YAW_RATE)
        steps = max(1, math.ceil(seconds / opts.dt))
        velocity = delta / (steps * opts.dt)
        steps = min(steps, max(1, int(opts.max_transit / opts.dt)))
        result = constrained_prop(self.physics, x, Action(velocity, steps * opts.dt,
                                                          np.zeros(self.robot.nq)),
                                  opts.dt, stop)
        for k in range(result.count):
            if not np.array_equal(result.objects[k], x.objects):
                return result.prefix(k, k * opts.dt)
        return result

    def _random(self, rng: np.random.Generator) -> Action:
        """A random control: a planar tool velocity, yaw rate and duration drawn uniformly."""
        opts = self.options
        velocity = np.array([rng.uniform(-opts.max_speed, opts.max_speed),
                             rng.uniform(-opts.max_speed, opts.max_speed),
                             rng.uniform(-MAX_YAW_RATE, MAX_YAW_RATE)])
        duration = max(1, round(rng.uniform(*RANDOM_DURATION) / opts.dt)) * opts.dt
        nullspace = rng.uniform(-opts.nullspace_speed, opts.nullspace_speed, self.robot.nq)
        return Action(velocity, duration, nullspace)

    def stop_check(self, termination: Termination) -> Stops:
        """Ends a propagation early: GOAL, CANCEL or TIMEOUT (as PC-RRT's)."""
        return Stops(self.scene.goal_index, (float(self._goal_xy[0]), float(self._goal_xy[1])),
                     self.options.goal_radius(self.scene), termination)


class _SliceRun(Search):
    """One `SliceRRT.plan` call: the shared bookkeeping (`Search`) and the slices: every
    distinct object arrangement of the tree, its members and their tool positions."""

    def __init__(self, planner: SliceRRT, seed: int, stop: Termination | None,
                 progress: ProgressCallback | None):
        super().__init__(planner.options, seed, stop, progress)
        self.planner = planner
        self.stop = planner.stop_check(self.termination)
        self.push_stop = dataclasses.replace(self.stop, goal_index=-1)
        """`stop` without the goal test: a push is judged where it ends."""
        self.approach: list[State] = []
        self.slice_objects = np.empty((0, len(planner.scene.objects), 3))
        self.members: list[list[int]] = []
        self._slice_of: dict[bytes, int] = {}

    def begin(self, start: State) -> PlanResult | None:
        """Check the start and plan the approach onto the manifold; a result ends the plan."""
        planner = self.planner
        ended = self.check_start(planner.physics, start)
        if ended is not None:
            return ended
        approach, why = approach_path(planner.physics, start, self.rng)
        if approach is None:
            return PlanResult(Outcome.START_INVALID, why, self.seed, plan_time=self.elapsed(),
                              best_goal_distance=self.best)
        self.approach = approach
        root = approach[-1]
        self.tree = Tree(root, self._tool_xy(root.q))
        self._join(0, root.objects)
        return None

    def _tool_xy(self, q: np.ndarray) -> np.ndarray:
        return tool_planar_pose(self.planner.robot, q)[:2]

    def _join(self, node: int, objects: np.ndarray) -> None:
        key = objects.tobytes()
        index = self._slice_of.get(key)
        if index is None:
            index = len(self.members)
            self._slice_of[key] = index
            self.slice_objects = np.concatenate([self.slice_objects, objects[None]])
            self.members.append([])
        self.members[index].append(node)

    def nearest_slice(self, desired: np.ndarray, weights: np.ndarray) -> int:
        """The slice closest to the arrangement `desired` (weighted object positions)."""
        offsets = np.linalg.norm(self.slice_objects[:, :, :2] - desired[None, :, :2], axis=2)
        return int(np.argmin(offsets @ weights))

    def nearest_in_slice(self, index: int, tool_xy: np.ndarray) -> int:
        """The node of slice `index` whose tool is nearest `tool_xy`."""
        nodes = self.members[index]
        offsets = np.linalg.norm(self.tree.arm[nodes] - tool_xy, axis=1)
        return nodes[int(np.argmin(offsets))]

    def extend(self, parent: int, result: Propagation, goal_at_end: bool = False
               ) -> PlanResult | None:
        """Add the end of `result` (its states the edge) as a node; the plan when it is in the
        goal region: stopped there (GOAL), or, with `goal_at_end`, ending there (unless the
        budget ran out or the plan was cancelled)."""
        self.propagated(result)
        if not result.count:
            return None
        end = result.end
        node = self.tree.add(end, self._tool_xy(end.q), parent, result)
        self._join(node, end.objects)
        distance = float(np.hypot(*(end.objects[self.planner.scene.goal_index, :2]
                                    - self.planner._goal_xy)))
        self.best = min(self.best, distance)
        ended_in_goal = (goal_at_end and result.stopped not in (StopReason.TIMEOUT,
                                                                StopReason.CANCEL)
                         and self.stop.reached(end.objects))
        if result.stopped is StopReason.GOAL or ended_in_goal:
            return self.success(self.approach[:-1] + self.tree.path_to(node, self.approach[-1]),
                                distance)
        return None
