"""The DARRT baseline of King et al. 2015, §V-A, in the same framework as PC-RRT (same scene,
physics, validity checks, outcome codes and `Planner` interface).

**DARRT** (Barry et al., as implemented in §V-A) — an RRT over the same states whose edges are
primitives instead of sampled controls:
- *Transit*: a straight joint-space line, free of collision with the table, the obstacles and
  every movable object;
- *RRTTransit*: RRT-Connect (Kuffner & LaValle 2000) between two configurations under the same
  collision rule, given `transit_time_limit` s (15 s in the paper) before it fails;
- *Push*: the tool moves the object along a straight line on the pushing plane with the object
  "caged in the hand", i.e. rigidly attached to the tool; the arm must stay clear of the static
  world and of every other movable object, and the carried object must not overlap anything or
  leave the table.
Each iteration samples, with equal probability, a new arm configuration (Transit, else
RRTTransit from the nearest node), a new pose for the goal object, or a new pose for one other
movable object (RRTTransit to a configuration holding the object, then Push towards the
sampled pose). A push extends at most `push_step` m towards the sample, as an RRT extends.

DARRT's paths follow its own world model (rigid carrying), not the quasistatic physics; they
are checked by the rules above.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from rearrangement_planner.model.scene import Scene
from rearrangement_planner.model.settings import setting
from rearrangement_planner.model.state import State
from rearrangement_planner.physics.step import Physics
from rearrangement_planner.planning.machinery.interface import (
    Outcome,
    PlannerOptions,
    PlanResult,
    ProgressCallback,
)
from rearrangement_planner.planning.machinery.manifold import (
    ik_on_manifold,
    project_step,
    tool_planar_pose,
)
from rearrangement_planner.planning.machinery.push_policy import support_distance
from rearrangement_planner.planning.machinery.search import Search
from rearrangement_planner.planning.machinery.termination import Termination
from rearrangement_planner.planning.machinery.tree import Tree

TRANSIT_STEP = 0.02      # rad, joint-space resolution of transit motions (collision checks)
PUSH_STEP = 0.01         # m, tool travel per push step
STANDOFF = 0.005         # m, gap between the finger tips and the carried object's surface


@dataclass(frozen=True)
class DARRTOptions(PlannerOptions):
    """DARRT's settings."""

    transit_time_limit: float = setting(15.0, low=0.01, high=3600.0)
    """Budget of one RRTTransit (RRT-Connect) call, s (15 s in King et al. 2015, §V-A)."""
    push_step: float = setting(0.25, low=0.001, high=2.0)
    """Longest straight-line push of one extension, m (as an RRT extends towards a sample)."""


class _Cancelled(Exception):
    pass


class DARRT:
    """DARRT with Transit, RRTTransit and straight-line Push primitives (King et al. 2015, §V-A)."""

    name = "darrt"

    def __init__(self, scene: Scene, options: PlannerOptions | None = None,
                 physics: Physics | None = None):
        self.scene = scene
        self.options = DARRTOptions.adopt(options)
        self.physics = physics or Physics(scene)
        self.robot = self.physics.robot
        self.world = self.physics.world
        self._goal_xy = np.asarray(scene.goal.position, dtype=float)
        self._table_height = scene.table.height

    # -- the algorithm -------------------------------------------------------------------------

    def plan(self, start: State | None = None, seed: int = 0, stop: Termination | None = None,
             progress: ProgressCallback | None = None) -> PlanResult:
        """The `Planner` protocol (as `PCRRT.plan`); a transit's RRT-Connect asks `stop` too."""
        search = Search(self.options, seed, stop, progress)
        start = start or self.scene.initial_state()
        ended = search.check_start(self.physics, start, pushes=False)   # DARRT carries it
        if ended is not None:
            return ended
        if not self._free(start.q, start.objects):
            return PlanResult(Outcome.START_INVALID, "start configuration touches an object; "
                              "DARRT's transit primitives need a collision-free start", seed)
        search.tree = Tree(start, start.q)
        try:
            while True:
                ended = search.check()
                if ended is not None:
                    return ended
                found = self._iteration(search, start)
                if found is not None:
                    return found
        except _Cancelled:
            return search.failure(Outcome.CANCELLED, "cancelled")

    def _iteration(self, search: Search, start: State) -> PlanResult | None:
        """Sample the arm, the goal object or another object with equal probability and
        extend the tree by the primitive that reaches it (§V-A); the plan once at the goal."""
        rng, tree, g = search.rng, search.tree, self.scene.goal_index
        search.iterations += 1
        others = [i for i in range(len(self.scene.objects)) if i != g]
        choice = int(rng.integers(3))
        if choice == 0:
            segment, node = self._extend_arm(tree, rng, search.termination)
        else:
            obj = g if choice == 1 or not others else others[int(rng.integers(len(others)))]
            segment, node = self._extend_object(tree, obj, rng, search.termination)
        if not segment:
            return None
        search.steps += len(segment)
        end_state = segment[-1]
        tree.add(end_state, end_state.q, node, tuple(segment))
        search.best = min(search.best, min(self._goal_distance(s) for s in segment))
        end = self._first_at_goal(segment)
        if end is None:
            return None
        states = tree.path_to(node, start) + segment[:end + 1]
        return search.success(states, self._goal_distance(states[-1]))

    # -- primitives -----------------------------------------------------------------------------

    def _extend_arm(self, tree: Tree, rng: np.random.Generator, stop: Termination):
        """Sample a configuration; Transit, else RRTTransit, from the nearest node."""
        robot = self.robot
        q_rand = rng.uniform(robot.lower, robot.upper)
        node = int(np.argmin(np.linalg.norm(tree.q[:tree.n] - q_rand, axis=1)))
        objects = tree.objects[node]
        if not self._free(q_rand, objects):
            return [], node
        path = self._transit(tree.q[node], q_rand, objects, rng, stop)
        return ([State(q, objects) for q in path[1:]] if path else []), node

    def _extend_object(self, tree: Tree, obj: int, rng: np.random.Generator,
                       stop: Termination):
        """Sample a pose for object `obj`; from the node where it is nearest, RRTTransit to a
        configuration holding it, then Push it straight towards the sample."""
        scene, opts = self.scene, self.options
        lo, hi = scene.table.lower, scene.table.upper
        if obj == scene.goal_index and rng.random() < opts.goal_bias:
            r = self.options.goal_radius(scene) * math.sqrt(rng.random())
            a = rng.uniform(-math.pi, math.pi)
            target = self._goal_xy + r * np.array([math.cos(a), math.sin(a)])
        else:
            target = np.array([rng.uniform(lo[0], hi[0]), rng.uniform(lo[1], hi[1])])
        d_obj = np.linalg.norm(tree.objects[:tree.n, obj, :2] - target, axis=1)
        node = int(np.argmin(d_obj))
        here = State(tree.q[node], tree.objects[node])
        pose = here.objects[obj]
        delta = target - pose[:2]
        length = float(np.hypot(*delta))
        if length < 1e-3:
            return [], node
        direction = delta / length
        length = min(length, self.options.push_step)
        q_hold = self._holding_configuration(here, obj, direction, rng)
        if q_hold is None:
            return [], node
        path = self._transit(here.q, q_hold, here.objects, rng, stop)
        if path is None:
            return [], node
        segment = [State(q, here.objects) for q in path[1:]]
        start = segment[-1] if segment else here
        segment += self._push(start, obj, direction, length)
        return segment, node

    def _holding_configuration(self, state: State, obj: int, direction: np.ndarray,
                               rng: np.random.Generator) -> np.ndarray | None:
        """An on-plane configuration with the finger tips just behind the object, pointing
        along the push direction, free of collision; None if IK or the collision check fails.
        (The hand model has no cavity to cage an object in: the object sits at the finger
        tips and is carried rigidly from there.)"""
        pose = state.objects[obj]
        back = self._extent(obj, pose, -direction) + self.robot.tool_reach + STANDOFF
        xy = pose[:2] - direction * back
        yaw = math.atan2(direction[1], direction[0])
        q = ik_on_manifold(self.robot, float(xy[0]), float(xy[1]), yaw, self._table_height,
                           state.q, rng=rng, restarts=3)
        if q is None or not self._free(q, state.objects):
            return None
        return q

    def _extent(self, obj: int, pose: np.ndarray, u: np.ndarray) -> float:
        return support_distance(self.scene.objects[obj], float(pose[2]), u)

    def _push(self, start: State, obj: int, direction: np.ndarray, length: float) -> list[State]:
        """The Push primitive: states while the tool carries the object `length` m along
        `direction` (rigid attachment: the object keeps its pose relative to the tool); the
        valid prefix."""
        robot, dt = self.robot, self.options.dt
        tool0 = tool_planar_pose(robot, start.q)
        rel = start.objects[obj, :2] - tool0[:2]
        c, s = math.cos(-tool0[2]), math.sin(-tool0[2])
        rel_local = np.array([c * rel[0] - s * rel[1], c * rel[1] + s * rel[0]])
        dyaw = start.objects[obj, 2] - tool0[2]
        n = max(1, math.ceil(length / PUSH_STEP))
        velocity = np.array([*(direction * (length / n / dt)), 0.0])
        others = [i for i in range(len(self.scene.objects)) if i != obj]
        states: list[State] = []
        x = start
        for _ in range(n):
            q = project_step(robot, x.q, velocity, dt, self._table_height)
            tool = tool_planar_pose(robot, q)
            c, s = math.cos(tool[2]), math.sin(tool[2])
            objects = x.objects.copy()
            objects[obj] = (tool[0] + c * rel_local[0] - s * rel_local[1],
                            tool[1] + s * rel_local[0] + c * rel_local[1],
                            math.remainder(tool[2] + dyaw, math.tau))
            if not self._push_valid(q, objects, obj, others):
                break
            x = State(q, objects)
            states.append(x)
            if self._goal_distance(x) <= self.options.goal_radius(self.scene):
                break
        return states

    def _push_valid(self, q: np.ndarray, objects: np.ndarray, obj: int, others: list[int]) -> bool:
        world = self.world
        if not self.robot.within_limits(q, tol=1e-9):
            return False
        poses = self.robot.shape_poses(q)
        if world.arm_static_collision(poses) is not None:
            return False
        if others and world.arm_object_contacts(poses, objects, objects=others):
            return False
        if any(obj in pair for pair in world.object_overlaps(objects)):
            return False
        if any(i == obj for i, _ in world.object_obstacle_overlaps(objects)):
            return False
        return obj not in world.objects_off_table(objects)

    # -- transit --------------------------------------------------------------------------------

    def _free(self, q: np.ndarray, objects: np.ndarray) -> bool:
        """The arm at q is within limits and clear of the table, obstacles and objects."""
        if not self.robot.within_limits(q, tol=1e-9):
            return False
        poses = self.robot.shape_poses(q)
        return (self.world.arm_static_collision(poses) is None
                and not self.world.arm_object_contacts(poses, objects))

    def _line_free(self, q_a: np.ndarray, q_b: np.ndarray, objects: np.ndarray) -> bool:
        n = max(1, math.ceil(float(np.abs(q_b - q_a).max()) / TRANSIT_STEP))
        return all(self._free(q_a + (q_b - q_a) * (i / n), objects) for i in range(1, n + 1))

    def _transit(self, q_a: np.ndarray, q_b: np.ndarray, objects: np.ndarray,
                 rng: np.random.Generator, stop: Termination) -> list[np.ndarray] | None:
        """Transit (a straight line) if free, else RRTTransit; the configurations from q_a to
        q_b at TRANSIT_STEP resolution, or None."""
        if self._line_free(q_a, q_b, objects):
            return _densify([q_a, q_b])
        waypoints = self._rrt_connect(q_a, q_b, objects, rng,
                                      stop.split(self.options.transit_time_limit))
        return None if waypoints is None else _densify(waypoints)

    def _rrt_connect(self, q_a: np.ndarray, q_b: np.ndarray, objects: np.ndarray,
                     rng: np.random.Generator, stop: Termination, step: float = 0.2
                     ) -> list[np.ndarray] | None:
        """RRT-Connect (Kuffner & LaValle 2000) in joint space; waypoints q_a ... q_b."""
        robot = self.robot
        trees = [([np.asarray(q_a, float)], [-1]), ([np.asarray(q_b, float)], [-1])]
        arrays = [np.array([q_a], float), np.array([q_b], float)]

        def extend(k: int, target: np.ndarray) -> tuple[str, int]:
            nodes, parents = trees[k]
            near = int(np.argmin(np.linalg.norm(arrays[k] - target, axis=1)))
            q_near = nodes[near]
            delta = target - q_near
            dist = float(np.linalg.norm(delta))
            reached = dist <= step
            q_new = target if reached else q_near + delta * (step / dist)
            if not self._line_free(q_near, q_new, objects):
                return "trapped", -1
            nodes.append(q_new)
            parents.append(near)
            arrays[k] = np.vstack([arrays[k], q_new])
            return ("reached" if reached else "advanced"), len(nodes) - 1

        a = 0
        while not stop.expired():
            if stop.cancelled():
                raise _Cancelled
            q_rand = rng.uniform(robot.lower, robot.upper)
            status, new = extend(a, q_rand)
            if status != "trapped":
                b = 1 - a
                target = trees[a][0][new]
                while True:
                    status_b, new_b = extend(b, target)
                    if status_b != "advanced":
                        break
                if status_b == "reached":
                    path_a = _branch(trees[a], new)
                    path_b = _branch(trees[b], new_b)
                    path = path_a[::-1] + path_b[1:]
                    return path if a == 0 else path[::-1]
            a = 1 - a
        return None

    # -- helpers --------------------------------------------------------------------------------

    def _goal_distance(self, state: State) -> float:
        return float(np.hypot(*(state.objects[self.scene.goal_index, :2] - self._goal_xy)))

    def _first_at_goal(self, segment: list[State]) -> int | None:
        radius = self.options.goal_radius(self.scene)
        for k, s in enumerate(segment):
            if self._goal_distance(s) <= radius:
                return k
        return None



def _branch(tree: tuple[list[np.ndarray], list[int]], node: int) -> list[np.ndarray]:
    """Configurations from `node` back to the tree's root."""
    nodes, parents = tree
    out = []
    while node >= 0:
        out.append(nodes[node])
        node = parents[node]
    return out


def _densify(waypoints: list[np.ndarray]) -> list[np.ndarray]:
    """The waypoints joined by straight lines at TRANSIT_STEP resolution (first included)."""
    out = [np.asarray(waypoints[0], float)]
    for q_a, q_b in zip(waypoints[:-1], waypoints[1:], strict=True):
        n = max(1, math.ceil(float(np.abs(q_b - q_a).max()) / TRANSIT_STEP))
        out.extend(q_a + (q_b - q_a) * (i / n) for i in range(1, n + 1))
    return out
