"""ConstrainedProp (King et al. Algorithm 2): apply a sampled action step by step, projecting
every step back onto the pushing manifold and through the quasistatic physics.

An action (King et al. 2015, §V) is a planar end-effector velocity (v_x, v_y, yaw rate) in the
base frame, held for a duration; we add one nullspace joint velocity per action, the paper's
h(q) "samples the nullspace", drawn once per action so that the arm's self-motion is smooth
(a fresh sample every step would make it a random walk). Each step:

    q_new <- Project(q + dt a)      (manifold.project_step: q + dt (J+ a + h))
    x_new <- PhysicsPropagate(x, q_new - q)
    stop at the first invalid x_new and keep the valid prefix.

Everything a replay needs is the sequence of arm configurations: the physics is a pure
function, so stepping it along the stored configurations reproduces the object poses exactly.

Compiled: `propagate_kernel` runs Project (`manifold.project_into`), the physics
step (`step.step_kernel`) and the goal test for a batch of up to CHECK_EVERY steps in one
call, with the tool velocity either held (an action) or fed back (the closed-loop push of
`push_policy`, `PushTarget`); the clock and the cancel flag are read between batches.
`replay` re-simulates a whole arm path in one call (`_replay_kernel`). Batching further (the
k actions of an iteration, the robustness rollouts) would save only the Python call around
each, under 2 % of their time (docs/experiments.md, "The compiled core").
"""

from __future__ import annotations

import math
import weakref
from collections.abc import Sequence
from dataclasses import dataclass
from functools import cached_property

import numpy as np
from numba import njit

from rearrangement_planner.model.robot import RobotModel
from rearrangement_planner.model.state import State
from rearrangement_planner.physics import kernels
from rearrangement_planner.physics.kernels import tool_from_joints, tool_kinematics_into
from rearrangement_planner.physics.step import (
    WORK_JOINTS,
    Invalid,
    Physics,
    step_kernel,
    step_workspace,
)
from rearrangement_planner.planning.machinery.interface import StopReason
from rearrangement_planner.planning.machinery.manifold import (
    project_arrays,
    project_into,
    project_workspace,
)
from rearrangement_planner.planning.machinery.termination import NEVER, Termination

GOAL, ARRIVED, CHECK_EVERY = 1, 2, 64
"""`propagate_kernel`'s ends (returned negated: the goal test held, the pushed object reached
its target) and the most steps it takes between two looks at the clock."""
_NO_GOAL = np.array([-1.0, 0.0, 0.0, 0.0])
"""`Stops.packed` of no goal test."""
PUSH_BAND = 0.02
"""Lateral offset (m) of the tool from the push line within which the push policy pushes."""


@dataclass(frozen=True)
class Stops:
    """The early ends of a propagation, callable on a state (after every valid step): GOAL when
    object `goal_index`'s centre is within `goal_radius` of `goal_xy` (goal_index -1: never),
    TIMEOUT or CANCEL when the search's `termination` says so; and in the form the compiled
    propagation (`constrained_prop`) takes: the goal test runs inside it, the termination is
    asked between its batches of at most CHECK_EVERY steps."""

    goal_index: int
    goal_xy: tuple[float, float]
    goal_radius: float
    termination: Termination = NEVER

    def __call__(self, state: State) -> StopReason | None:
        if self.termination.expired():
            return StopReason.TIMEOUT
        if self.reached(state.objects):
            return StopReason.GOAL
        if self.termination.cancelled():
            return StopReason.CANCEL
        return None

    def reached(self, objects: np.ndarray) -> bool:
        g = self.goal_index
        return g >= 0 and math.hypot(objects[g, 0] - self.goal_xy[0],
                                     objects[g, 1] - self.goal_xy[1]) <= self.goal_radius

    def interrupted(self) -> StopReason | None:
        return self.termination.interrupted()

    @cached_property
    def packed(self) -> np.ndarray:
        """The goal test for `propagate_kernel`: (goal_index, x, y, radius)."""
        return np.array([self.goal_index, *self.goal_xy, self.goal_radius], dtype=float)


@dataclass(frozen=True)
class Action:
    """A planar tool velocity held for `duration` s, with a nullspace joint velocity."""

    velocity: np.ndarray    # (3,) v_x m/s, v_y m/s, yaw rate rad/s, base frame
    duration: float         # s
    nullspace: np.ndarray   # (nq,) rad/s, projected into the task nullspace by Project


@dataclass(frozen=True, eq=False)
class Propagation:
    """The valid prefix of one action: step i+1 brought the arm to `arm[i]` and the objects to
    `objects[i]` (the start is not included). Kept as two arrays, not a State per step: most
    propagations are never chosen, and a tree of a long search holds a million steps, which as
    objects took a quarter of a second to free when the search ended (past its deadline)."""

    arm: np.ndarray                 # (steps, nq), read-only
    objects: np.ndarray             # (steps, objects, 3), read-only
    duration: float                 # s actually applied (a multiple of dt)
    stopped: Invalid | StopReason | None   # why it stopped early, None if it did not
    pushing_links: frozenset[str]
    subject: int = -1
    """The object whose rule cut it short (`Invalid.TIPPING`, `Invalid.TURNING`), else -1."""

    @classmethod
    def of_states(cls, states: Sequence[State], duration: float,
                  stopped: Invalid | StopReason | None,
                  pushing_links: frozenset[str]) -> Propagation:
        arm = np.array([s.q for s in states], dtype=float).reshape(len(states), -1)
        objects = np.array([s.objects for s in states], dtype=float)
        return cls(arm, objects, duration, stopped, pushing_links)

    @property
    def count(self) -> int:
        """Steps in the prefix."""
        return len(self.arm)

    @property
    def end(self) -> State:
        """The state after the last step (there must be one)."""
        return State.trusted(self.arm[-1], self.objects[-1])

    @cached_property
    def states(self) -> tuple[State, ...]:
        """The state after every step."""
        return tuple(State.rows(self.arm, self.objects))

    def prefix(self, k: int, duration: float) -> Propagation:
        """The first k steps (`duration` s), stopped for no reason of their own."""
        return Propagation(self.arm[:k], self.objects[:k], duration, None, frozenset())


def constrained_prop(physics: Physics, state: State, action: Action, dt: float,
                     stop: Stops | None = None) -> Propagation:
    """Algorithm 2 of King et al.: step the action through Project and the physics, compiled
    (`propagate_kernel`: Project, the physics step and the goal test for a batch of steps in
    one call).

    `stop` may end the action early (`Stops`); that state is kept. TIMEOUT and CANCEL are
    checked between batches of CHECK_EVERY steps; a batch that ends past the deadline ends
    the action with TIMEOUT, whatever it reached (a plan is never found after its budget)."""
    return propagate(physics, state, int(round(action.duration / dt)), dt, action.nullspace,
                     stop, velocity=action.velocity)


@dataclass(frozen=True)
class PushTarget:
    """A closed-loop push (the law of `_push_velocity`): object `obj` towards `target` (x, y),
    the tool at most `speed` m/s per component."""

    obj: int
    target: tuple[float, float]
    speed: float
    facing: bool = False
    """Turn the hand to face the push (its flat face across the push line, at most
    FACING_YAW_RATE): a line contact on the object's face rather than a corner (`face_push`)."""


def propagate(physics: Physics, state: State, steps: int, dt: float, nullspace: np.ndarray,
              stop: Stops | None, velocity: np.ndarray | None = None,
              push: PushTarget | None = None) -> Propagation:
    """Up to `steps` steps through Project and the physics, the tool's planar velocity either
    held (`velocity`, an action of Algorithm 2) or fed back (`push`, which ends the action when
    the object is within 1 cm of its target); stops at the first invalid step and keeps the
    valid prefix (see `constrained_prop` for `stop`)."""
    nq, shape = len(state.q), state.objects.shape
    arm, objects = np.empty((steps, nq)), np.empty((steps, *shape))
    flags = np.zeros(physics.flag_count, dtype=np.int64)
    goal = stop.packed if stop is not None else _NO_GOAL
    project = project_arrays(physics.robot, physics.scene.table.height)
    held = np.zeros(3) if velocity is None else np.asarray(velocity, dtype=float)
    policy = policy_array(physics, push)
    nullspace = np.asarray(nullspace, dtype=float)
    done, subject = 0, -1
    stopped: Invalid | StopReason | None = None
    while done < steps and stopped is None:
        batch = min(CHECK_EVERY, steps - done)
        # Writable copies (one compiled signature, whether from the state or the last batch).
        q0 = np.array(state.q if done == 0 else arm[done - 1])
        objects0 = np.array(state.objects if done == 0 else objects[done - 1])
        count, code, named = propagate_kernel(q0, objects0, held, policy, nullspace, batch, dt,
                                               goal, project, physics.arrays, arm[done:],
                                               objects[done:], flags)
        done += count
        if code > 0:
            stopped = physics.reason(code)
            if stopped in (Invalid.TIPPING, Invalid.TURNING):
                subject = named
        elif code == -GOAL:
            stopped = StopReason.GOAL
        elif code == -ARRIVED:
            break
        if stop is not None:
            stopped = stop.interrupted() or stopped
    arm, objects = arm[:done], objects[:done]
    arm.setflags(write=False)
    objects.setflags(write=False)
    return Propagation(arm, objects, done * dt, stopped, physics.pushing_links(flags), subject)


FACING_YAW_RATE = 1.0
"""rad/s: how fast a facing push turns the hand towards the push direction."""


_HELD: weakref.WeakKeyDictionary[RobotModel, np.ndarray] = weakref.WeakKeyDictionary()
"""`policy_array` of a held velocity, by robot (every action of Algorithm 2 asks)."""


def policy_array(physics: Physics, push: PushTarget | None) -> np.ndarray:
    """The push for `propagate_kernel`: (object, target x, y, speed, cylinder (0/1), size x,
    size y, footprint radius, push band, the rows of R0, the posture's tool rotation, the
    facing yaw rate (0: the hand keeps its yaw)); object -1: no push (the velocity is
    held)."""
    if push is None:
        held = _HELD.get(physics.robot)
        if held is None:
            held = _HELD[physics.robot] = np.concatenate(
                [[-1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, PUSH_BAND],
                 physics.robot.config.push_posture.rotation.ravel(), [0.0]])
        return held
    posture = physics.robot.config.push_posture.rotation
    obj = physics.scene.objects[push.obj]
    return np.concatenate([[push.obj, push.target[0], push.target[1], push.speed,
                            float(obj.shape == "cylinder"), obj.size[0], obj.size[1],
                            obj.footprint_radius, PUSH_BAND], posture.ravel(),
                           [FACING_YAW_RATE if push.facing else 0.0]])


@njit(cache=True)
def _push_velocity(tool_x: float, tool_y: float, tool_yaw: float, cx: float, cy: float,
                   yaw: float, policy: np.ndarray, dt: float, out: np.ndarray) -> bool:
    """The closed-loop push law (`push_policy` drives it), the object's shape from `policy`
    (`policy_array`): writes the tool velocity into out[:3]; False once the object is
    within 1 cm of the target. A facing push (policy[18] > 0) also turns the hand, at most
    policy[18] rad/s, until its flat face lies across the push line (tool yaw = the push's
    heading, or that plus pi: the hand is symmetric), so that it meets a face along a line
    rather than at a corner: the stable push of Lynch & Mason 1996, which sticks and does not
    turn the object whatever its support pressure (test_pushing)."""
    tx, ty, speed, band = policy[1], policy[2], policy[3], policy[8]
    dx, dy = tx - cx, ty - cy
    distance = math.hypot(dx, dy)
    if distance < 0.01:
        return False
    ux, uy = dx / distance, dy / distance
    px, py = -uy, ux
    rx, ry = tool_x - cx, tool_y - cy
    along, across = rx * ux + ry * uy, rx * px + ry * py
    radius = policy[7]
    if policy[4] > 0.0:                                    # support distance along u
        extent = radius
    else:
        c, s = math.cos(yaw), math.sin(yaw)
        extent = 0.5 * (abs(c * ux + s * uy) * policy[5] + abs(-s * ux + c * uy) * policy[6])
    if abs(across) <= band and -(extent + 0.06) <= along <= -extent + 0.005:
        vx = ux * speed - (0.5 / dt) * across * px         # push, staying on the line
        vy = uy * speed - (0.5 / dt) * across * py
    elif along > -extent - 0.005 and abs(across) < radius + 0.04:
        side = 1.0 if across >= 0 else -1.0                # go round it, on the tool's side
        vx = (cx + px * side * (radius + 0.07) - ux * (extent + 0.03) - tool_x) / dt
        vy = (cy + py * side * (radius + 0.07) - uy * (extent + 0.03) - tool_y) / dt
    else:                                                  # line up behind it
        vx = (cx - ux * (extent + 0.025) - tool_x) / dt
        vy = (cy - uy * (extent + 0.025) - tool_y) / dt
    norm = math.hypot(vx, vy)
    if norm > speed:
        vx, vy = vx * (speed / norm), vy * (speed / norm)
    rate = 0.0
    if policy[18] > 0.0:
        error = (math.atan2(uy, ux) - tool_yaw + 0.5 * math.pi) % math.pi - 0.5 * math.pi
        rate = max(-policy[18], min(policy[18], 0.5 * error / dt))
    out[0], out[1], out[2] = vx, vy, rate
    return True


@njit(cache=True)
def _tool_planar(pose: np.ndarray, policy: np.ndarray) -> tuple[float, float, float]:
    """`manifold.tool_planar_pose` compiled, of the tool at `pose`: its (x, y) and the yaw of
    R R0^T."""
    r0 = policy[9:18]                                       # R0, row-major
    m00 = pose[0, 0] * r0[0] + pose[0, 1] * r0[1] + pose[0, 2] * r0[2]
    m10 = pose[1, 0] * r0[0] + pose[1, 1] * r0[1] + pose[1, 2] * r0[2]
    return pose[0, 3], pose[1, 3], math.atan2(m10, m00)


@njit(cache=True)
def propagate_kernel(q: np.ndarray, objects: np.ndarray, held: np.ndarray,
                      policy: np.ndarray, nullspace: np.ndarray, steps: int, dt: float,
                      goal: np.ndarray, project: tuple, world: tuple, arm: np.ndarray,
                      out: np.ndarray, flags: np.ndarray) -> tuple[int, int, int]:
    """Up to `steps` steps of Project and the physics step from (q, objects), the tool velocity
    `held` or, for policy[0] >= 0, the push policy's; the valid ones into arm[i], out[i], the
    pushing shapes and moved objects OR-ed into `flags`. Returns (valid steps, 0 | the invalid
    step's code | -GOAL when the goal test held after the last valid step | -ARRIVED when
    the pushed object reached its target, the first index the invalid step names (the object
    of a tipping or turning push) or -1).

    One forward kinematics per step: the tool's pose and Jacobian that the push policy and
    Project read at a step's q are those of the joints' poses the last physics step computed
    at its q1, the same q (`step.WORK_JOINTS`, `kernels.tool_from_joints`); only the first
    step computes them, at q."""
    info = np.zeros(4 + flags.shape[0], dtype=np.int64)
    work = step_workspace(world, q, objects)
    projecting = project_workspace(q.shape[0], project[0][0].shape[0])
    return _steps(q, objects, held.copy(), policy, nullspace, steps, dt, goal, project, world,
                  arm, out, flags, info, np.zeros(1), work, projecting, np.empty(q.shape[0]))


@kernels.njit_bare
def _steps(q: np.ndarray, objects: np.ndarray, velocity: np.ndarray, policy: np.ndarray,
           nullspace: np.ndarray, steps: int, dt: float, goal: np.ndarray, project: tuple,
           world: tuple, arm: np.ndarray, out: np.ndarray, flags: np.ndarray, info: np.ndarray,
           value: np.ndarray, work: tuple, projecting: tuple,
           q_new: np.ndarray) -> tuple[int, int, int]:
    """`propagate_kernel`'s steps, in the buffers it made: compiled without reference counting
    (`kernels.njit_bare`), which the tuples and rows a step reads would otherwise count up and
    down at every step."""
    g, pushed = int(goal[0]), int(policy[0])
    chain, limits = project[0], project[5]
    pose, jac = projecting[1], projecting[2]
    for i in range(steps):
        # The tool at q, for the push and for Project. Project reads it at q held in its
        # limits: from the second step on q is Project's own output, inside them; a first q
        # outside them leaves Project to compute it there (`known` False).
        known = i > 0 or _within(q, limits)
        if i > 0:
            tool_from_joints(work[WORK_JOINTS], chain[0], chain[2], chain[3], project[1],
                             project[2], pose, jac)
        elif known or pushed >= 0:
            tool_kinematics_into(q, chain[0], chain[1], chain[2], chain[3], project[1],
                                 project[2], pose, jac, projecting[9], projecting[10])
        if pushed >= 0:
            x, y, tool_yaw = _tool_planar(pose, policy)
            if not _push_velocity(x, y, tool_yaw, objects[pushed, 0], objects[pushed, 1],
                                  objects[pushed, 2], policy, dt, velocity):
                return i, -ARRIVED, -1
        project_into(q, velocity, dt, nullspace, chain, project[1], project[2], project[3],
                     project[4], limits, project[6], 0.5, 1.0, 1.0, q_new, projecting, known)
        info[:] = 0
        code = step_kernel(q, q_new, objects, world, out[i], info, value, work)
        if code != 0:
            return i, code, info[1]
        for j in range(q_new.shape[0]):
            arm[i, j] = q_new[j]
        for k in range(flags.shape[0]):
            flags[k] |= info[4 + k]
        q, objects = arm[i], out[i]
        if g >= 0 and math.hypot(objects[g, 0] - goal[1], objects[g, 1] - goal[2]) <= goal[3]:
            return i + 1, -GOAL, -1
    return steps, 0, -1


@njit(cache=True)
def _within(q: np.ndarray, limits: np.ndarray) -> bool:
    """q inside its joint limits (lower, upper), bounds included."""
    for j in range(q.shape[0]):
        if not limits[0, j] <= q[j] <= limits[1, j]:
            return False
    return True


def replay(physics: Physics, start: State, arm_path: np.ndarray | Sequence[np.ndarray],
           until: Stops | None = None) -> tuple[list[State], str]:
    """Re-simulate the objects along a sequence of arm configurations (the first equal to
    start.q), in one compiled call (`_replay_kernel`). Returns the states (one per
    configuration, up to the first state where `until`'s goal test holds, when given) and ''
    or the first invalid reason (with its detail)."""
    arm = np.array(arm_path, dtype=float)
    objects = np.empty((len(arm), *start.objects.shape))
    objects[0] = start.objects
    goal = (np.array([until.goal_index, *until.goal_xy, until.goal_radius]) if until is not None
            else np.array([-1.0, 0.0, 0.0, 0.0]))
    info = np.zeros(4 + physics.flag_count, dtype=np.int64)
    value = np.zeros(1)
    count, code = _replay_kernel(arm, objects, goal, physics.arrays, info, value)
    states = [start, *State.rows(arm[1:count], objects[1:count])]
    if code > 0:
        reason = physics.reason(code)
        return states, f"{reason.value}: {physics.describe(code, info, value, arm[count])}"
    return states, ""


@njit(cache=True)
def _replay_kernel(arm: np.ndarray, objects: np.ndarray, goal: np.ndarray, world: tuple,
                   info: np.ndarray, value: np.ndarray) -> tuple[int, int]:
    """Physics steps from arm[i - 1] to arm[i], objects[i - 1] -> objects[i], from i = 1 on.
    Returns (states filled, 0 | the invalid step's code | -GOAL when the goal test of `goal`
    (object, x, y, radius; object -1: none) held at the last state filled)."""
    g = int(goal[0])
    work = step_workspace(world, arm[0], objects[0])
    for i in range(1, arm.shape[0]):
        info[:] = 0
        code = step_kernel(arm[i - 1], arm[i], objects[i - 1], world, objects[i], info, value, work)
        if code != 0:
            return i, code
        if g >= 0 and math.hypot(objects[i, g, 0] - goal[1],
                                 objects[i, g, 1] - goal[2]) <= goal[3]:
            return i + 1, -GOAL
    return arm.shape[0], 0
