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
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numba import njit

from rearrangement_planner.model.state import State
from rearrangement_planner.physics.step import Invalid, Physics, step_kernel
from rearrangement_planner.planning.interface import StopReason
from rearrangement_planner.planning.manifold import project_arrays, project_kernel, project_step

StopCheck = Callable[[State], StopReason | None]
"""Called after every valid step; a reason ends the action there, keeping that state."""

_GOAL, _CHECK_EVERY = 1, 64


@dataclass(frozen=True)
class Stops:
    """The early ends of PC-RRT's propagations, as a `StopCheck` (after every valid step:
    TIMEOUT past `deadline` (`time.monotonic()`), GOAL when object `goal_index`'s centre is
    within `goal_radius` of `goal_xy`, CANCEL when `cancelled()`), and in the form the compiled
    propagation (`constrained_prop`) takes: the goal test runs inside it, the clock and the
    cancel flag between its batches of at most _CHECK_EVERY steps."""

    goal_index: int
    goal_xy: tuple[float, float]
    goal_radius: float
    deadline: float
    cancelled: Callable[[], bool]

    def __call__(self, state: State) -> StopReason | None:
        if time.monotonic() > self.deadline:
            return StopReason.TIMEOUT
        if self.reached(state.objects):
            return StopReason.GOAL
        if self.cancelled():
            return StopReason.CANCEL
        return None

    def reached(self, objects: np.ndarray) -> bool:
        g = self.goal_index
        return math.hypot(objects[g, 0] - self.goal_xy[0],
                          objects[g, 1] - self.goal_xy[1]) <= self.goal_radius

    def interrupted(self) -> StopReason | None:
        if time.monotonic() > self.deadline:
            return StopReason.TIMEOUT
        if self.cancelled():
            return StopReason.CANCEL
        return None


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
                     stop: Stops | None = None) -> Propagation:
    """Algorithm 2 of King et al.: step the action through Project and the physics, compiled
    (`_propagate_kernel`: Project, the physics step and the goal test for a batch of steps in
    one call).

    `stop` may end the action early (`Stops`); that state is kept. TIMEOUT and CANCEL are
    checked between batches of _CHECK_EVERY steps; a batch that ends past the deadline ends
    the action with TIMEOUT, whatever it reached (a plan is never found after its budget)."""
    steps = int(round(action.duration / dt))
    nq, shape = len(state.q), state.objects.shape
    arm, objects = np.empty((steps, nq)), np.empty((steps, *shape))
    flags = np.zeros(physics.flag_count, dtype=np.int64)
    goal = (np.array([stop.goal_index, *stop.goal_xy, stop.goal_radius]) if stop is not None
            else np.array([-1.0, 0.0, 0.0, 0.0]))
    project = project_arrays(physics.robot, physics.scene.table.height)
    velocity = np.asarray(action.velocity, dtype=float)
    nullspace = np.asarray(action.nullspace, dtype=float)
    done = 0
    stopped: Invalid | StopReason | None = None
    while done < steps and stopped is None:
        batch = min(_CHECK_EVERY, steps - done)
        # Writable copies (one compiled signature, whether from the state or the last batch).
        q0 = np.array(state.q if done == 0 else arm[done - 1])
        objects0 = np.array(state.objects if done == 0 else objects[done - 1])
        count, code = _propagate_kernel(q0, objects0, velocity, nullspace, batch, dt, goal,
                                        project, physics.arrays, arm[done:], objects[done:],
                                        flags)
        done += count
        if code > 0:
            stopped = physics.reason(code)
        elif code == -_GOAL:
            stopped = StopReason.GOAL
        if stop is not None:
            stopped = stop.interrupted() or stopped
    states = tuple(State.trusted(arm[i], objects[i]) for i in range(done))
    return Propagation(states, done * dt, stopped, physics.pushing_links(flags))


@njit(cache=True)
def _propagate_kernel(q: np.ndarray, objects: np.ndarray, velocity: np.ndarray,
                      nullspace: np.ndarray, steps: int, dt: float, goal: np.ndarray,
                      project: tuple, world: tuple, arm: np.ndarray, out: np.ndarray,
                      flags: np.ndarray) -> tuple[int, int]:
    """Up to `steps` steps of Project and the physics step from (q, objects); the valid ones
    into arm[i], out[i], the pushing shapes and moved objects OR-ed into `flags`. Returns
    (valid steps, 0 | the invalid step's code | -_GOAL when the goal test held after the last
    valid step)."""
    info = np.zeros(4 + flags.shape[0], dtype=np.int64)
    value = np.zeros(1)
    g = int(goal[0])
    for i in range(steps):
        q_new = project_kernel(q, velocity, dt, nullspace, project[0], project[1], project[2],
                               project[3], project[4], project[5], project[6], 0.5, 1.0, 1.0)
        info[:] = 0
        code = step_kernel(q, q_new, objects, world[0], world[1], world[2], world[3],
                           world[4], world[5], world[6], world[7], world[8], world[9],
                           world[10], world[11], world[12], out[i], info, value)
        if code != 0:
            return i, code
        arm[i] = q_new
        for k in range(flags.shape[0]):
            flags[k] |= info[4 + k]
        q, objects = arm[i], out[i]
        if g >= 0 and math.hypot(objects[g, 0] - goal[1], objects[g, 1] - goal[2]) <= goal[3]:
            return i + 1, -_GOAL
    return steps, 0


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
