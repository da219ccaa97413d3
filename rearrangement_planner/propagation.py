"""ConstrainedProp (King et al. Algorithm 2): apply a sampled action step by step, projecting
every step back onto the pushing manifold and through the quasistatic physics.

An action (§V of King et al.) is a planar end-effector velocity (v_x, v_y, yaw rate) in the
base frame, held for a duration; we add one nullspace joint velocity per action, the paper's
h(q) "samples the nullspace", drawn once per action so that the arm's self-motion is smooth
(a fresh sample every step would make it a random walk). Each step:

    q_new <- Project(q + dt a)      (manifold.project_step: q + dt (J+ a + h))
    x_new <- PhysicsPropagate(x, q_new - q)
    stop at the first invalid x_new and keep the valid prefix.

Everything a replay needs is the sequence of arm configurations: the physics is a pure
function, so stepping it along the stored configurations reproduces the object poses exactly.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from .manifold import project_step, tool_planar_pose
from .physics import Invalid, Physics
from .state import State


@dataclass(frozen=True)
class Action:
    """A planar tool velocity held for `duration` s, with a nullspace joint velocity."""

    velocity: np.ndarray    # (3,) v_x m/s, v_y m/s, yaw rate rad/s, base frame
    duration: float         # s
    nullspace: np.ndarray   # (nq,) rad/s, projected into the task nullspace by Project


@dataclass(frozen=True)
class Propagation:
    """The valid prefix of one action: `states[i]` after step i+1 (the start is not included)."""

    states: tuple[State, ...]
    duration: float                 # s actually applied (a multiple of dt)
    stopped: Invalid | str | None   # why it stopped early: an Invalid reason, 'goal', 'cancel'
    pushing_links: frozenset[str]


def constrained_prop(physics: Physics, state: State, action: Action, dt: float,
                     stop: Callable[[State], str | None] | None = None) -> Propagation:
    """Algorithm 2 of King et al.: step the action through Project and the physics.

    `stop(state)`, called after every valid step, may end the action early with a reason
    (e.g. 'goal' when the goal is reached, 'cancel'); that state is kept."""
    velocity = action.velocity
    return _propagate(physics, state, lambda x: velocity, int(round(action.duration / dt)), dt,
                      action.nullspace, stop)


def _propagate(physics: Physics, state: State, velocity: Callable[[State], np.ndarray | None],
               steps: int, dt: float, nullspace: np.ndarray,
               stop: Callable[[State], str | None] | None) -> Propagation:
    """Up to `steps` steps: tool velocity `velocity(x)` (None ends the action) through Project
    and the physics; stops at the first invalid step and keeps the valid prefix."""
    robot, table_height = physics.robot, physics.scene.table.height
    states: list[State] = []
    links: set[str] = set()
    x = state
    stopped: Invalid | str | None = None
    for _ in range(steps):
        v = velocity(x)
        if v is None:
            break
        q_new = project_step(robot, x.q, v, dt, table_height, nullspace_velocity=nullspace)
        result = physics.step(x, q_new)
        if not result.valid:
            stopped = result.reason
            break
        x = result.state
        states.append(x)
        links |= result.pushing_links
        if stop is not None:
            stopped = stop(x)
            if stopped is not None:
                break
    return Propagation(tuple(states), len(states) * dt, stopped, frozenset(links))


def replay(physics: Physics, start: State, arm_path: np.ndarray) -> tuple[list[State], str]:
    """Re-simulate the objects along a sequence of arm configurations (the first equal to
    start.q). Returns the states (one per configuration) and '' or the first invalid reason."""
    states = [start]
    x = start
    for q in np.asarray(arm_path)[1:]:
        result = physics.step(x, q)
        if not result.valid:
            return states, f"{result.reason.value}: {result.detail}"
        x = result.state
        states.append(x)
    return states, ""


PUSH_BAND = 0.02
"""Lateral offset (m) of the tool from the push line within which the push policy pushes."""


def support_distance(obj, yaw: float, u: np.ndarray) -> float:
    """How far the footprint of `obj` (a scene MovableObject at heading `yaw`) reaches from its
    centre along the unit vector u (the support function), m."""
    if obj.shape == "cylinder":
        return float(obj.radius)
    c, s = math.cos(yaw), math.sin(yaw)
    ux, uy = c * u[0] + s * u[1], -s * u[0] + c * u[1]
    return 0.5 * (abs(ux) * float(obj.size[0]) + abs(uy) * float(obj.size[1]))


def push_policy_prop(physics: Physics, state: State, obj: int, target: np.ndarray,
                     max_steps: int, dt: float, speed: float,
                     nullspace: np.ndarray,
                     stop: Callable[[State], str | None] | None = None) -> Propagation:
    """A feedback push towards `target` (x, y) for object `obj`, propagated exactly like an
    action of Algorithm 2 (every step through Project and the physics; valid prefix kept).

    The planner's "push bias" (`PlannerOptions.push_bias`): a closed-loop action in the spirit
    of the pushing policy of Haustein et al. (002, §IV) but analytic: bring the tool behind the
    object on the line through the object and the target (going around the object when the
    tool is on the wrong side), then push along the line with a lateral correction. The hand
    keeps its yaw. Whatever else the arm meets on the way is pushed by the physics."""
    robot = physics.robot
    shape = physics.scene.objects[obj]
    radius = shape.footprint_radius
    target = np.asarray(target, dtype=float)

    def velocity(x: State) -> np.ndarray | None:
        tool = tool_planar_pose(robot, x.q)
        centre = x.objects[obj, :2]
        to_target = target - centre
        distance = float(np.hypot(*to_target))
        if distance < 0.01:
            return None
        u = to_target / distance
        perp = np.array([-u[1], u[0]])
        rel = tool[:2] - centre
        along, across = float(rel @ u), float(rel @ perp)
        extent = support_distance(shape, x.objects[obj, 2], u)
        if abs(across) <= PUSH_BAND and -(extent + 0.06) <= along <= -extent + 0.005:
            v = u * speed - (0.5 / dt) * across * perp        # push, staying on the line
        elif along > -extent - 0.005 and abs(across) < radius + 0.04:
            # Beside or in front of the object: go round it, on the tool's side.
            side = 1.0 if across >= 0 else -1.0
            v = (centre + perp * side * (radius + 0.07) - u * (extent + 0.03) - tool[:2]) / dt
        else:                                                  # line up behind it
            v = (centre - u * (extent + 0.025) - tool[:2]) / dt
        norm = float(np.hypot(*v))
        v = v * (speed / norm) if norm > speed else v
        # The hand keeps its yaw: turning it to face the push often runs into joint 7.
        return np.array([v[0], v[1], 0.0])

    return _propagate(physics, state, velocity, max_steps, dt, nullspace, stop)
