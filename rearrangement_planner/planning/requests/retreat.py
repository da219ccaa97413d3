"""The retreat before a re-plan: a plan ends with the arm touching what it pushed, and a start
in contact is refused (`physics.validation.check_scene`), so the closed loop (docs/design.md
"Closed loop") first moves the arm until it stands `clearance` clear of every object:
1. back the way it came, along the executed plan's own arm path;
2. where that way is not clear (an object came to rest across it), off the objects: each
   step moves every contact point within `clearance` away from its object and up, by damped
   least squares on the contact points' Jacobians (a differential-IK retreat).
The objects stay where they were observed: each move is checked like a transit move (within
the joint limits, LIMIT_MARGIN inside them off the path, no static collision, no deeper into
any object than the arm starts, give or take DEEPER_TOLERANCE), not simulated as a push.

    path = retreat_path(scene, observed, plan_positions)   # (K, nq) or None
"""

from __future__ import annotations

from typing import Any

import numpy as np

from rearrangement_planner.model.scene import Scene
from rearrangement_planner.model.state import State
from rearrangement_planner.physics.collision import CollisionWorld

RETREAT_CLEARANCE = 0.02
"""m: the retreat ends where no contact shape of the arm comes this near an object."""
RETREAT_RESOLUTION = 0.02
"""rad: the retreat is checked at configurations this far apart (largest joint change)."""
TOUCH = 2e-3
"""m: an arm this near an object touches it (MuJoCo's and a perception's poses are not
exact); one farther re-plans from where it stands when the way back is not clear."""
LIMIT_MARGIN = 0.02
"""rad: a move off the objects (`_push_off`) stays this far inside every joint limit, so that
the re-plan that follows does not start on a limit (a controller reports positions a hair
past it)."""
DEEPER_TOLERANCE = 5e-3
"""m: how much deeper than at its start the arm may reach into an object along the retreat
(it starts in contact; the check is that it does not push further)."""


def retreat_path(scene: Scene, observed: State, path: np.ndarray,
                 clearance: float = RETREAT_CLEARANCE,
                 world: CollisionWorld | None = None) -> np.ndarray | None:
    """Arm configurations (K, nq) from `observed.q` back along `path` (the executed plan's arm
    path, (N, nq)) from its point nearest `observed.q`, ending at the first configuration
    `clearance` m clear of every object at `observed.objects`; `observed.q` alone when it is
    already clear, or when it touches nothing (TOUCH m) and the way back is not clear. None
    when the arm touches an object and no configuration along the path is clear, or the way
    back hits the table or an obstacle or reaches deeper into an object than the arm
    starts."""
    world = world if world is not None else CollisionWorld(scene)
    robot, objects = scene.robot, observed.objects
    q = np.asarray(observed.q, dtype=float)
    if _clear(world, robot.shape_poses(q), objects, clearance):
        return q[None, :].copy()
    back = _back_out(world, robot, observed, np.asarray(path, dtype=float), clearance)
    if back is None:
        back = _push_off(world, robot, observed, clearance)
    if back is None and _clear(world, robot.shape_poses(q), objects, TOUCH):
        return q[None, :].copy()
    return back


def _back_out(world: CollisionWorld, robot: Any, observed: State, path: np.ndarray,
              clearance: float) -> np.ndarray | None:
    """The way back of `retreat_path`, or None."""
    objects, q = observed.objects, np.asarray(observed.q, dtype=float)
    start_depth = world.arm_object_penetration(robot.shape_poses(q), objects)
    nearest = int(np.argmin(np.max(np.abs(path - q), axis=1)))
    waypoints = [q]
    for target in path[nearest::-1]:
        here = waypoints[-1]
        count = max(1, int(np.ceil(np.max(np.abs(target - here)) / RETREAT_RESOLUTION)))
        for k in range(1, count + 1):
            config = here + (target - here) * (k / count)
            shapes = robot.shape_poses(config)
            if world.arm_static_collision(shapes) is not None:
                return None
            if world.arm_object_penetration(shapes, objects) > start_depth + DEEPER_TOLERANCE:
                return None
            if _clear(world, shapes, objects, clearance):
                return np.array(waypoints + [config])
        waypoints.append(np.array(target, dtype=float))
    return None


PUSH_OFF_STEP = 0.01
"""m: how far each push-off step moves the contact points (away and up)."""
PUSH_OFF_STEPS = 40
DAMPING = 1e-3


def _push_off(world: CollisionWorld, robot: Any, observed: State,
              clearance: float) -> np.ndarray | None:
    """The differential-IK retreat of `retreat_path` (module doc, 2.), or None."""
    objects, q = observed.objects, np.asarray(observed.q, dtype=float)
    start_depth = world.arm_object_penetration(robot.shape_poses(q), objects)
    waypoints = [q]
    for _ in range(PUSH_OFF_STEPS):
        contacts = world.arm_object_contacts(robot.shape_poses(q), objects, margin=clearance)
        if not contacts:
            return np.array(waypoints)
        jacobian = np.vstack([robot.shape_jacobian(q, c.shape, c.point)[:3] for c in contacts])
        away = np.concatenate([PUSH_OFF_STEP * (np.array([0.0, 0.0, 0.5]) - c.normal)
                               for c in contacts])
        step = jacobian.T @ np.linalg.solve(jacobian @ jacobian.T
                                            + DAMPING * np.eye(len(away)), away)
        step *= min(1.0, RETREAT_RESOLUTION / max(float(np.max(np.abs(step))), 1e-12))
        q = q + step
        shapes = robot.shape_poses(q)
        if (not robot.within_limits(q, tol=-LIMIT_MARGIN)
                or world.arm_static_collision(shapes) is not None
                or world.arm_object_penetration(shapes, objects)
                > start_depth + DEEPER_TOLERANCE):
            return None
        waypoints.append(q)
    return None


def _clear(world: CollisionWorld, shapes: np.ndarray, objects: np.ndarray,
           clearance: float) -> bool:
    return not world.arm_object_contacts(shapes, objects, margin=clearance)
