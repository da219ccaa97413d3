"""Closed-loop pushes: the heuristics PC-RRT adds to the paper's random actions.

- `push_policy_prop`: one feedback push of an object towards a point, propagated exactly like
  an action of Algorithm 2 (every step through Project and the physics; valid prefix kept).
- `PushPolicy`: what PC-RRT does with it (`PCRRTOptions`):
  - *push bias*: in a share of the iterations one of the k actions is a push of one object
    towards its position in the sample (`sample_push`);
  - *greedy goal push*: from every new best node, a push of the goal object straight for the
    goal centre (`goal_push`, like the Connect step of RRT-Connect). A push of the goal object
    that meets another object pushes it along (`PhysicsOptions.object_contact`).

The push itself is in the spirit of the pushing policy of Haustein et al. (002, §IV) but
analytic: bring the tool behind the object on the line through the object and the target
(going round the object when it is on the wrong side), then push along the line with a lateral
correction. Every step goes through the physics, so these edges replay like any other.
"""

from __future__ import annotations

import math
from typing import Protocol

import numpy as np

from rearrangement_planner.model.scene import MovableObject
from rearrangement_planner.model.state import State
from rearrangement_planner.physics.step import Physics
from rearrangement_planner.planning.machinery.propagation import (
    Propagation,
    PushTarget,
    Stops,
    propagate,
)

GREEDY_STEPS = 3
"""The greedy goal push may take this many times `push_steps` (it has to go round the goal
object and then push it all the way)."""


class PushSettings(Protocol):
    """The settings the pushes read (`pcrrt.PCRRTOptions` has them; see there)."""

    @property
    def dt(self) -> float: ...
    @property
    def max_speed(self) -> float: ...
    @property
    def nullspace_speed(self) -> float: ...
    @property
    def push_goal_share(self) -> float: ...
    @property
    def push_steps(self) -> int: ...
    @property
    def face_push(self) -> bool: ...


def support_distance(obj: MovableObject, yaw: float, u: np.ndarray) -> float:
    """How far the footprint of `obj` at heading `yaw` reaches from its centre along the unit
    vector u (the support function), m."""
    if obj.shape == "cylinder":
        return float(obj.footprint_radius)       # the radius
    c, s = math.cos(yaw), math.sin(yaw)
    ux, uy = c * u[0] + s * u[1], -s * u[0] + c * u[1]
    return 0.5 * (abs(ux) * float(obj.size[0]) + abs(uy) * float(obj.size[1]))


def push_policy_prop(physics: Physics, state: State, obj: int, target: np.ndarray,
                     max_steps: int, dt: float, speed: float, nullspace: np.ndarray,
                     stop: Stops | None = None, facing: bool = False) -> Propagation:
    """The feedback push of object `obj` from `state` towards `target` (x, y), at most
    `max_steps` steps of `dt`, the tool at most `speed` m/s per component, compiled
    (`propagation.propagate` with a `PushTarget`). The policy: from the tool's planar position
    and the object's pose, in the push band behind the object push along the line through
    object and target with a lateral correction; beside or in front of it, go round it on the
    tool's side; else go to the place behind it; done once the object is within 1 cm of the
    target. The hand keeps its yaw, or with `facing` turns to face the push (`PushTarget`),
    and steers by the tool point (the finger pads, `tool_reach` past it, make the contact:
    the feedback closes the gap)."""
    push = PushTarget(int(obj), (float(target[0]), float(target[1])), float(speed), facing)
    return propagate(physics, state, max_steps, dt, nullspace, stop, push=push)


class PushPolicy:
    """The closed-loop actions of PC-RRT on one scene (module doc)."""

    def __init__(self, physics: Physics, options: PushSettings, pushable: np.ndarray):
        """`pushable`: indices of the objects the push bias may aim at besides the goal object
        (the Static RRT: none)."""
        self.physics = physics
        self.options = options
        self.scene = physics.scene
        self.goal_xy = np.asarray(self.scene.goal.position, dtype=float)
        self.pushable = pushable

    def sample_push(self, x_near: State, sample_objects: np.ndarray, rng: np.random.Generator,
                    stop: Stops) -> Propagation:
        """The push-bias action: push one object from x_near towards its position in the
        sample: the goal object with probability `push_goal_share`, else another at random."""
        opts, g = self.options, self.scene.goal_index
        if (len(self.scene.objects) == 1 or rng.random() < opts.push_goal_share
                or self.pushable.size <= 1):
            obj = g
        else:
            others = self.pushable[self.pushable != g]
            obj = int(others[rng.integers(others.size)])
        nullspace = self._nullspace(rng)
        return self.push(x_near, obj, sample_objects[obj, :2], opts.push_steps, nullspace,
                         stop)

    def goal_push(self, x: State, rng: np.random.Generator, stop: Stops) -> Propagation:
        """The greedy extension: push the goal object from x towards the goal centre."""
        nullspace = self._nullspace(rng)
        return self.push(x, self.scene.goal_index, self.goal_xy,
                         GREEDY_STEPS * self.options.push_steps, nullspace, stop)

    def push(self, x: State, obj: int, where: np.ndarray, steps: int, nullspace: np.ndarray,
             stop: Stops) -> Propagation:
        """One closed-loop push of `obj` from x towards `where` (`push_policy_prop`)."""
        opts = self.options
        return push_policy_prop(self.physics, x, obj, where, steps, opts.dt, opts.max_speed,
                                nullspace, stop, opts.face_push)

    def _nullspace(self, rng: np.random.Generator) -> np.ndarray:
        speed = self.options.nullspace_speed
        return rng.uniform(-speed, speed, self.physics.robot.nq)
