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

from rearrangement_planner.model.state import State
from rearrangement_planner.physics.step import Invalid, Physics
from rearrangement_planner.planning.manifold import project_step, tool_planar_pose


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


def pusher_footprint(physics: Physics, q: np.ndarray) -> np.ndarray:
    """The part of the arm that pushes, as planar capsules in the tool's frame on the pushing
    plane: (K, 5) rows (a0, b0, a1, b1, r), a along the tool heading, b to its left, m. These
    are the contact capsules and spheres (robot config) that reach down to object height
    within 0.35 m of the tool: on the Panda the finger nub, the 24 cm hand bar behind it and
    the wrist. The posture is fixed on the manifold but for the yaw, so the footprint does not
    change as the hand moves along the plane."""
    robot = physics.robot
    tool = tool_planar_pose(robot, q)
    c, s = math.cos(tool[2]), math.sin(tool[2])
    top = physics.scene.table.height + max(o.height for o in physics.scene.objects)
    tool_z = robot.tool_pose(q)[2, 3]
    rows = []
    for shape, pose in zip(robot.config.contact_shapes, robot.shape_poses(q), strict=True):
        if shape.kind not in ("capsule", "sphere"):
            continue
        half = 0.5 * shape.dims[1] if shape.kind == "capsule" else 0.0
        ends = [pose[:3, 3] + pose[:3, 2] * half, pose[:3, 3] - pose[:3, 2] * half]
        radius = shape.dims[0]
        if min(e[2] for e in ends) - radius > top or max(
                abs(e[2] - tool_z) for e in ends) > 0.05:
            continue
        local = []
        for e in ends:
            d = e[:2] - tool[:2]
            local += [c * d[0] + s * d[1], -s * d[0] + c * d[1]]
        if min(math.hypot(local[0], local[1]), math.hypot(local[2], local[3])) <= 0.35:
            rows.append(local + [radius])
    return np.array(rows).reshape(-1, 5)


def _lead_offset(footprint: np.ndarray, yaw: float, u: np.ndarray) -> np.ndarray:
    """World offset from the tool of the footprint's point furthest along u (support); zero
    when the footprint is empty (no part of the arm reaches object height near the tool)."""
    if footprint.size == 0:
        return np.zeros(2)
    c, s = math.cos(yaw), math.sin(yaw)
    ua, ub = c * u[0] + s * u[1], -s * u[0] + c * u[1]
    ends = np.concatenate([footprint[:, 0:2], footprint[:, 2:4]])
    radii = np.concatenate([footprint[:, 4], footprint[:, 4]])
    k = int(np.argmax(ends[:, 0] * ua + ends[:, 1] * ub + radii))
    a, b = ends[k] + radii[k] * np.array([ua, ub])
    return np.array([c * a - s * b, s * a + c * b])


def push_policy_prop(physics: Physics, state: State, obj: int, target: np.ndarray,
                     max_steps: int, dt: float, speed: float,
                     nullspace: np.ndarray,
                     stop: Callable[[State], str | None] | None = None,
                     avoid: bool = False, yaw_rate: float = 0.0) -> Propagation:
    """A feedback push towards `target` (x, y) for object `obj`, propagated exactly like an
    action of Algorithm 2 (every step through Project and the physics; valid prefix kept).

    The planner's "push bias" (`PlannerOptions.push_bias`): a closed-loop action in the spirit
    of the pushing policy of Haustein et al. (002, §IV) but analytic: bring the pusher behind
    the object on the line through the object and the target (going around the object when it
    is on the wrong side), then push along the line with a lateral correction. With
    `yaw_rate` = 0 the hand keeps its yaw and the tool point is taken as the pusher; with
    `yaw_rate` > 0 the hand turns (at most that fast) to push finger first, or side on when
    finger first would point it back at the robot, and the pusher is the point of the hand's
    real footprint (`pusher_footprint`) that leads in the push direction. With `avoid`, the
    way to the place behind the object slides round the other objects instead of running into
    them (`_around_others`); whatever else the arm meets is pushed by the physics."""
    robot = physics.robot
    shape = physics.scene.objects[obj]
    radius = shape.footprint_radius
    target = np.asarray(target, dtype=float)
    others = np.array([i for i in range(len(physics.scene.objects)) if i != obj], dtype=int)
    radii = np.array([physics.scene.objects[i].footprint_radius for i in others])
    footprint = pusher_footprint(physics, state.q) if yaw_rate > 0 else None

    def velocity(x: State) -> np.ndarray | None:
        tool = tool_planar_pose(robot, x.q)
        centre = x.objects[obj, :2]
        to_target = target - centre
        distance = float(np.hypot(*to_target))
        if distance < 0.01:
            return None
        u = to_target / distance
        perp = np.array([-u[1], u[0]])
        yaw_velocity = 0.0
        lead = np.zeros(2)
        if footprint is not None:
            heading = math.atan2(u[1], u[0])
            radial = math.atan2(tool[1], tool[0])
            if math.cos(heading - radial) < -0.2:          # finger first points at the robot
                heading += math.copysign(0.5 * math.pi, math.sin(radial - heading))
            error = math.remainder(heading - tool[2], 2 * math.pi)
            yaw_velocity = max(-yaw_rate, min(yaw_rate, 0.5 * error / dt))
            lead = _lead_offset(footprint, tool[2], u)
        pusher = tool[:2] + lead
        rel = pusher - centre
        along, across = float(rel @ u), float(rel @ perp)
        extent = support_distance(shape, x.objects[obj, 2], u)
        if abs(across) <= PUSH_BAND and -(extent + 0.06) <= along <= -extent + 0.005:
            v = u * speed - (0.5 / dt) * across * perp        # push, staying on the line
            norm = float(np.hypot(*v))
            v = v * (speed / norm) if norm > speed else v
        else:
            if along > -extent - 0.005 and abs(across) < radius + 0.04:
                # Beside or in front of the object: go round it, on the pusher's side.
                side = 1.0 if across >= 0 else -1.0
                width = 0.0
                if footprint is not None:   # how far the hand reaches towards the object
                    width = max(0.0, float(_lead_offset(footprint, tool[2], -side * perp)
                                           @ (-side * perp)) - float(lead @ (-side * perp)))
                v = (centre + perp * side * (radius + 0.07 + width) - u * (extent + 0.03)
                     - pusher) / dt
            else:                                              # line up behind it
                v = (centre - u * (extent + 0.025) - pusher) / dt
            norm = float(np.hypot(*v))
            v = v * (speed / norm) if norm > speed else v
            if avoid:
                v = _around_others(v, tool[:2], x.objects, others, radii)
        return np.array([v[0], v[1], yaw_velocity])

    return _propagate(physics, state, velocity, max_steps, dt, nullspace, stop)


AVOID_CLEARANCE = 0.045
"""How close (m, beyond an object's footprint radius) the push policy's approach lets the tool
come to an object it is not pushing: the finger nub's radius (1.8 cm) and a margin."""


def _around_others(v: np.ndarray, tool: np.ndarray, objects: np.ndarray, others: np.ndarray,
                   radii: np.ndarray) -> np.ndarray:
    """The approach velocity `v` (planar, m/s) made to slide round the objects `others`: for
    each object the tool is within AVOID_CLEARANCE of, the part of v heading into it is turned
    along its boundary (to the side v already leans to), so the tool goes round instead of
    shoving it. A velocity field, no search: it can still end against an object, and the
    physics then decides."""
    speed = float(np.hypot(*v))
    if speed < 1e-9 or others.size == 0:
        return v
    rel = tool - objects[others, :2]
    dist = np.hypot(rel[:, 0], rel[:, 1])
    out = v.copy()
    for j in np.flatnonzero(dist < radii + AVOID_CLEARANCE):
        n = rel[j] / max(float(dist[j]), 1e-9)          # from the object to the tool
        into = float(out @ n)
        if into >= 0.0:
            continue
        t = np.array([-n[1], n[0]])
        side = 1.0 if float(out @ t) >= 0.0 else -1.0
        out = out - into * n + side * abs(into) * t      # the same speed, along the boundary
    norm = float(np.hypot(*out))
    return out * (speed / norm) if norm > 1e-9 else out
