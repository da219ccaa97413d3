"""The finishing push: a found plan pushes its goal object on to the goal point.

A search stops at the first state whose goal object is within radius - goal_margin of the goal
point (the goal test of King et al. 2015, with our margin): it is stopped by the very push step
that crosses that circle. So every plan ends with the goal object on the margin's edge, 4-5 cm
from the goal point in every solved request of the benchmark (docs/benchmark.md), and the open-
loop execution has only the margin for the model's error. A larger margin makes the search's
target smaller and the search slower and rarer to succeed (docs/experiments.md, 2026-11-23).

So after the search, and after shortcutting (which keeps any end inside radius - goal_margin),
`finish` adds one more closed-loop push of the goal object towards the goal point
(`push_policy.push_policy_prop`, the greedy goal push of PC-RRT, which already pushes from the
side the plan ended on), simulated in the planner's own physics like every edge, until the
object's centre is within `finish_radius`. The push is kept, as far as its steps stay valid,
up to its step nearest the goal point, and only when that is at least FINISH_GAIN closer.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np

from rearrangement_planner.model.settings import Settings, setting
from rearrangement_planner.model.state import State, wrap_angle
from rearrangement_planner.physics.step import Physics
from rearrangement_planner.planning.machinery.interface import PushingPlannerOptions
from rearrangement_planner.planning.machinery.propagation import (
    Action,
    Propagation,
    Stops,
    constrained_prop,
)
from rearrangement_planner.planning.machinery.push_policy import push_policy_prop
from rearrangement_planner.planning.machinery.termination import Termination

FINISH_STEPS = 60
"""The finishing push takes at most this many steps of dt (6 s at the default 0.1 s: the tool
travels at most 0.6 m, enough to go round the goal object and push it the margin's 5 cm)."""
FINISH_TIME = 1.0
"""s the finishing push may run past the request's budget (it takes milliseconds)."""
FINISH_GAIN = 0.005
"""m: a finishing push that brings the goal object less than this much closer is not kept."""
TAIL_STEPS = (0, 3, 10)
"""The finishing pushes start from the plan's end and from these many steps before it (the
turn limit refuses many pushes in their first step from where the search stopped)."""
DIRECTIONS = (0.0, 0.25, 0.5, 0.75, 1.0)
"""Straight finishing pushes: from the goal object's last heading (0) to the goal point (1)."""
MOTION_STEPS = 5
"""The goal object's heading is its motion over this many steps."""


@dataclass(frozen=True)
class FinishOptions(Settings):
    """The finishing push after the search (a plan request's; `pipeline.Candidates`)."""

    finish_radius: float = setting(0.01, low=0.0, high=0.5)
    """After the search and shortcutting, push the goal object on towards the goal point until
    its centre is within this (m) of it; kept when it brings the object at least 5 mm closer.
    A search stops on the goal_margin's edge, which leaves open-loop execution only the margin.
    0 = the plan ends where the search reached the goal. Measured: docs/experiments.md."""


NO_FINISH = FinishOptions(finish_radius=0.0)
"""A request whose plan ends where its search reached the goal."""


def finish(physics: Physics, states: tuple[State, ...], options: PushingPlannerOptions,
           finish_radius: float, stop: Termination) -> tuple[State, ...]:
    """`states` (a plan: one physics step apart, the start first) with its tail replaced by the
    best finishing push (module doc): the one whose goal object comes nearest the goal point,
    kept up to that step, when it is at least FINISH_GAIN nearer than the plan's end; else
    unchanged, as when `finish_radius` is 0 or the plan already ends within it. `stop` may cut
    the pushes (its cancel and deadline)."""
    scene = physics.scene
    g, goal_xy = scene.goal_index, np.asarray(scene.goal.position, dtype=float)
    before = _distances(np.array([states[-1].objects]), g, goal_xy)[0]
    if finish_radius <= 0 or before <= finish_radius:
        return states
    stops = Stops(g, (float(goal_xy[0]), float(goal_xy[1])), finish_radius, stop)
    best: tuple[float, int, Propagation] | None = None     # distance, tail index, push
    for back in TAIL_STEPS:
        if back >= len(states) - 1:
            break
        i = len(states) - 1 - back
        for push in _pushes(physics, states, i, goal_xy, options, stops):
            if not push.count:
                continue
            d = float(_distances(push.objects, g, goal_xy).min())
            if best is None or d < best[0] - 1e-9:
                best = (d, i, push)
    if best is None or best[0] > before - FINISH_GAIN:
        return states
    _, i, push = best
    closest = int(np.argmin(_distances(push.objects, g, goal_xy)))
    return states[:i + 1] + push.states[:closest + 1]


def _pushes(physics: Physics, states: tuple[State, ...], i: int, goal_xy: np.ndarray,
            options: PushingPlannerOptions, stops: Stops) -> Iterator[Propagation]:
    """The finishing pushes from states[i]: the closed-loop goal push of PC-RRT, then straight
    pushes of the tool (an action of Algorithm 2, no yaw, no self-motion) in DIRECTIONS
    between the way the goal object was last moving and the way to the goal point (a push
    already in contact goes on along its line, where the turn limit lets it)."""
    g, x = physics.scene.goal_index, states[i]
    nullspace = np.zeros(physics.robot.nq)
    yield push_policy_prop(physics, x, g, goal_xy, FINISH_STEPS, options.dt, options.max_speed,
                           nullspace, stops, facing=True)
    here = x.objects[g, :2]
    moving = here - states[max(0, i - MOTION_STEPS)].objects[g, :2]
    to_goal = math.atan2(goal_xy[1] - here[1], goal_xy[0] - here[0])
    heading = math.atan2(moving[1], moving[0]) if np.hypot(*moving) > 1e-4 else to_goal
    turn = wrap_angle(to_goal - heading)
    duration = min(FINISH_STEPS * options.dt,
                   2.0 * float(np.hypot(*(goal_xy - here))) / options.max_speed)
    for share in DIRECTIONS:
        angle = heading + share * turn
        velocity = options.max_speed * np.array([math.cos(angle), math.sin(angle), 0.0])
        yield constrained_prop(physics, x, Action(velocity, duration, nullspace), options.dt,
                               stops)


def _distances(objects: np.ndarray, g: int, goal_xy: np.ndarray) -> np.ndarray:
    """The goal object's distance from the goal point in each of `objects` (steps, n, 3)."""
    return np.hypot(objects[:, g, 0] - goal_xy[0], objects[:, g, 1] - goal_xy[1])
