"""Path shortcutting (King et al. 2015, §IV, Fig. 3).

A randomized planner's path wanders. We pick two states i < j of the path at random and try to
connect only their *arm configurations* with a new on-plane motion (there is no two-point
boundary value solver for the objects). The new motion is simulated through the physics from
state i, and because the objects may now end elsewhere than in state j, the arm motion of the
rest of the path (unchanged) is re-simulated from there. The shortcut is accepted only if every
step is valid, the goal object still ends in the goal region, and the arm path is shorter.

The connection steers the tool's planar pose (x, y, yaw) from q_i to q_j with the same
Project as ConstrainedProp (`manifold.project_step`), the arm's self-motion pulled towards q_j
through the nullspace term, and lands exactly on q_j with a last small joint step, so that the
remainder of the path keeps its arm motion bit for bit.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

from rearrangement_planner.model.settings import Settings, setting
from rearrangement_planner.model.state import State, wrap_angle
from rearrangement_planner.physics.step import Physics
from rearrangement_planner.planning.machinery.manifold import (
    on_manifold,
    project_step,
    tool_planar_pose,
)
from rearrangement_planner.planning.machinery.propagation import Stops, replay
from rearrangement_planner.planning.machinery.termination import Termination

LANDING_STEP = 0.05     # rad, largest joint step allowed to land exactly on q_j
STEP_LENGTH = 0.01      # m, tool travel per connection step
YAW_STEP = 0.05         # rad, tool yaw change per connection step
JOINT_STEP = 0.05       # rad, largest joint change per connection step (estimate)


@dataclass(frozen=True)
class ShortcutOptions(Settings):
    """How long a found path is shortcut (a plan request's; `pipeline.plan_scene`)."""

    shortcut_time: float = setting(10.0, low=0.0, high=600.0)
    """Longest path shortcutting after a plan is found, s, within the request's time_limit (a
    plan found late is shortcut less); 0 = none."""
    shortcut_attempts: int = setting(40, low=0, high=100000)
    """Most shortcut attempts (about 50 ms each); when this bound ends shortcutting before
    shortcut_time, the shortened path is reproducible. 0 = until shortcut_time."""


NO_SHORTCUT = ShortcutOptions(shortcut_time=0.0)
"""A request whose plan is returned as the planner found it."""


@dataclass(frozen=True)
class ShortcutResult:
    states: tuple[State, ...]
    attempts: int
    accepted: int
    elapsed: float
    length_before: float
    """Arm path length in joint space (rad) before and after."""
    length_after: float


def path_length(states) -> float:
    """Arm path length in joint space (rad): sum of |q_{k+1} - q_k|."""
    arm = np.array([s.q for s in states])
    return float(np.linalg.norm(np.diff(arm, axis=0), axis=1).sum())


def shortcut(physics: Physics, states, stop: Termination, seed: int = 0, dt: float = 0.1,
             goal_radius: float | None = None) -> ShortcutResult:
    """Shortcut `states` (a valid plan ending in the goal: consecutive states one physics step
    apart) until `stop` ends it (its deadline, cancel, or iteration bound: the attempts; an
    attempt bound that ends first makes the result reproducible). Never lengthens the path and
    never loses the goal, which is the goal object's centre within `goal_radius` (m; default
    the region's, less the planner's goal margin when the pipeline passes it); a state list
    that does not end in the goal is returned unchanged."""
    t0 = time.monotonic()
    scene = physics.scene
    radius = scene.goal.radius if goal_radius is None else goal_radius
    path = list(states)
    before = path_length(path)
    if len(path) < 3 or not _at_goal(scene, path[-1], radius):
        return ShortcutResult(tuple(path), 0, 0, time.monotonic() - t0, before, before)
    table_height = scene.table.height
    # The approach onto the plane (if any) is kept: shortcuts connect on-plane states only.
    first = next((k for k, s in enumerate(path) if on_manifold(physics.robot, s.q, table_height,
                                                               tol=2e-3)), len(path))
    rng = np.random.default_rng(seed)
    attempts = accepted = 0
    length = before
    while stop.check(attempts) is None:
        n = len(path)
        if n - first < 3:
            break
        attempts += 1
        i, j = sorted(rng.choice(np.arange(first, n), size=2, replace=False).tolist())
        if j - i < 2:
            continue
        bridge = connect(physics, path[i].q, path[j].q, dt)
        if bridge is None:
            continue
        old_piece = path_length(path[i:j + 1])
        new_piece = float(np.linalg.norm(np.diff(np.vstack([path[i].q, bridge]), axis=0),
                                         axis=1).sum())
        if new_piece >= old_piece - 1e-9:
            continue
        candidate = _resimulate(physics, path[:i + 1], bridge,
                                [s.q for s in path[j + 1:]], radius)
        if candidate is None:
            continue
        new_length = path_length(candidate)
        if new_length < length - 1e-9:
            path, length = candidate, new_length
            accepted += 1
    return ShortcutResult(tuple(path), attempts, accepted, time.monotonic() - t0, before, length)


def connect(physics: Physics, q_a: np.ndarray, q_b: np.ndarray, dt: float = 0.1,
            ) -> list[np.ndarray] | None:
    """Arm configurations after q_a (excluded) ending exactly at q_b, moving the tool on the
    pushing plane along the straight line between their planar poses; None if the steering
    does not get within LANDING_STEP of q_b."""
    robot, table_height = physics.robot, physics.scene.table.height
    pose_a, pose_b = tool_planar_pose(robot, q_a), tool_planar_pose(robot, q_b)
    dyaw = float(wrap_angle(pose_b[2] - pose_a[2]))
    steps = max(1, math.ceil(max(float(np.hypot(*(pose_b[:2] - pose_a[:2]))) / STEP_LENGTH,
                                 abs(dyaw) / YAW_STEP,
                                 float(np.abs(q_b - q_a).max()) / JOINT_STEP)))
    q = np.asarray(q_a, dtype=float)
    out: list[np.ndarray] = []
    for k in range(steps - 1):
        remaining = (steps - k) * dt
        pose = tool_planar_pose(robot, q)
        error = np.array([pose_b[0] - pose[0], pose_b[1] - pose[1],
                          wrap_angle(pose_b[2] - pose[2])])
        q = project_step(robot, q, error / remaining, dt, table_height,
                         nullspace_velocity=(q_b - q) / remaining)
        out.append(q)
    if float(np.abs(q_b - q).max()) > LANDING_STEP:
        return None
    out.append(np.array(q_b, dtype=float))
    return out


def _resimulate(physics: Physics, prefix: list[State], bridge: list[np.ndarray],
                rest: list[np.ndarray], radius: float) -> list[State] | None:
    """prefix + the states along bridge and rest re-simulated (`propagation.replay`, one
    compiled call); None if a step is invalid or the goal is not reached. The path is cut at
    the first state in the goal region."""
    scene = physics.scene
    goal = Stops(scene.goal_index, (float(scene.goal.position[0]),
                                    float(scene.goal.position[1])), radius)
    states, problem = replay(physics, prefix[-1], [prefix[-1].q, *bridge, *rest], until=goal)
    if problem or len(states) < 2 or not _at_goal(scene, states[-1], radius):
        return None
    return [*prefix, *states[1:]]


def _at_goal(scene, state: State, radius: float) -> bool:
    return scene.goal.distance(state.objects[scene.goal_index, :2]) <= radius
