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

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from rearrangement_planner.model.state import State
from rearrangement_planner.physics.step import Invalid, Physics
from rearrangement_planner.planning.interface import StopReason
from rearrangement_planner.planning.manifold import project_step

StopCheck = Callable[[State], StopReason | None]
"""Called after every valid step; a reason ends the action there, keeping that state."""


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
    stopped: Invalid | StopReason | None   # why it stopped early, None if it did not
    pushing_links: frozenset[str]


def constrained_prop(physics: Physics, state: State, action: Action, dt: float,
                     stop: StopCheck | None = None) -> Propagation:
    """Algorithm 2 of King et al.: step the action through Project and the physics.

    `stop(state)`, called after every valid step, may end the action early with a reason
    (`StopReason`); that state is kept."""
    velocity = action.velocity
    return propagate(physics, state, lambda x: velocity, int(round(action.duration / dt)), dt,
                      action.nullspace, stop)


def propagate(physics: Physics, state: State, velocity: Callable[[State], np.ndarray | None],
               steps: int, dt: float, nullspace: np.ndarray,
               stop: StopCheck | None) -> Propagation:
    """Up to `steps` steps: tool velocity `velocity(x)` (None ends the action) through Project
    and the physics; stops at the first invalid step and keeps the valid prefix."""
    robot, table_height = physics.robot, physics.scene.table.height
    states: list[State] = []
    links: set[str] = set()
    x = state
    stopped: Invalid | StopReason | None = None
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
            reason = result.reason.value if result.reason is not None else "invalid"
            return states, f"{reason}: {result.detail}"
        x = result.state
        states.append(x)
    return states, ""
