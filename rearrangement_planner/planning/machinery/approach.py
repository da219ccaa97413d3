"""The approach onto the pushing manifold when the start configuration is off it (docs/design.md).

King et al. plan on the manifold "plane parallel to the table"; a robot usually starts above
it. We look for an on-plane configuration by IK (`manifold.ik_on_manifold`) at candidate tool
positions over the table, nearest to the current tool position first, and accept the first
whose straight joint-space motion from the start is collision-free: every step through the
physics must be valid and must not move any object (a transit, not a push).
"""

from __future__ import annotations

import math

import numpy as np

from rearrangement_planner.model.state import State
from rearrangement_planner.physics.step import Physics
from rearrangement_planner.planning.machinery.manifold import (
    ik_on_manifold,
    on_manifold,
    tool_planar_pose,
)

APPROACH_STEP = 0.02   # rad, largest joint change between two approach waypoints


def approach_path(physics: Physics, start: State, rng: np.random.Generator,
                  candidates: int = 40) -> tuple[list[State] | None, str]:
    """States from `start` onto the pushing manifold (start included), or (None, reason).
    Returns [start] alone when the start is already on the manifold."""
    robot, scene = physics.robot, physics.scene
    table_height = scene.table.height
    if on_manifold(robot, start.q, table_height):
        return [start], ""
    lo, hi = scene.table.lower, scene.table.upper
    here = tool_planar_pose(robot, start.q)[:2]
    points = np.column_stack([rng.uniform(lo[0], hi[0], candidates),
                              rng.uniform(lo[1], hi[1], candidates)])
    points = points[np.argsort(np.linalg.norm(points - here, axis=1))]
    tried = 0
    for x, y in points:
        yaw = math.atan2(y, x)   # fingers pointing away from the base: the reachable posture
        q = ik_on_manifold(robot, float(x), float(y), yaw, table_height, start.q, rng=rng,
                           restarts=3)
        if q is None:
            continue
        tried += 1
        target = State(q, start.objects)
        if physics.check_state(target) is not None:
            continue
        path = _transit(physics, start, q)
        if path is not None:
            return path, ""
    return None, (f"no collision-free straight approach onto the pushing plane found "
                  f"({tried} reachable candidates of {candidates} tried)")


def _transit(physics: Physics, start: State, q_goal: np.ndarray) -> list[State] | None:
    n = max(1, math.ceil(float(np.abs(q_goal - start.q).max()) / APPROACH_STEP))
    states, x = [start], start
    for i in range(1, n + 1):
        result = physics.step(x, start.q + (q_goal - start.q) * (i / n))
        if not result.valid or result.moved_objects:
            return None
        x = result.state
        states.append(x)
    return states
