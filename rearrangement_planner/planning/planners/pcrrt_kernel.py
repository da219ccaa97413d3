"""PC-RRT's iterations compiled: Algorithm 1 of King et al. 2015, from the sample to adding
the chosen edge to the tree, for many iterations in one call (`iterations`, each one
`iteration`).

Why: a search spent 42 % of its time in Python around the compiled physics step (sampling,
Nearest, the action, the propagation's wrapper, the metric; docs/benchmark.md "Where a PC-RRT
iteration goes"), and a compiled call that takes the search's Generator costs about 16 µs, so
one call runs iterations for a slice of time. `PCRRT` keeps in Python what happens rarely: an
edge that reached the goal or a new best goal distance (it adds it and pushes greedily on,
`PCRRT._extend`), growing the tree's arrays, and, between calls, the cancel, the race's gate
and the progress report.

The same plans: the call draws from the search's own NumPy Generator (Numba shares its state),
in the order and with the arithmetic of the Python it replaces, so a search makes the same
iterations and returns the same plan (the golden plans check it). The deadline is read
between batches of `propagation.CHECK_EVERY` steps, as in `propagation.propagate`
(`termination.monotonic`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numba import njit

from rearrangement_planner.physics.kernels import any_prism_overlap, tool_kinematics
from rearrangement_planner.planning.machinery.propagation import (
    ARRIVED,
    CHECK_EVERY,
    GOAL,
    propagate_kernel,
)
from rearrangement_planner.planning.machinery.termination import monotonic
from rearrangement_planner.planning.machinery.tree import (
    metric,
    nearest_kernel,
    set_arrangement,
)

TIMED_OUT = -3
"""The code of a propagation cut by the deadline (`iteration`'s results)."""
GO_ON, PAST_DEADLINE, HAND_OVER, NO_ROOM = 0, 1, 2, 3
"""Why `iterations` returned: its slice of time or its iterations ran out; the deadline
passed; an iteration chose a propagation that reached the goal or a new best goal distance
(`PCRRT._extend` adds it and pushes greedily on); the tree's arrays are full."""


@dataclass(frozen=True)
class IterationArrays:
    """What `iteration` reads of a planner and its scene, made once per plan, and the buffers
    it writes: the k propagations' steps (`arm`, `objects`, `flags`), each one's (steps, code,
    named object) in `results` (steps -1: not propagated) and its end's metric feature in
    `features`, and the sample (`sample_arm`, `sample_objects`)."""

    ints: np.ndarray        # objects, goal index, k, uniform sampler (0/1), push steps, pushable,
    #                         greedy goal push (0/1)
    reals: np.ndarray       # goal bias, goal sampling radius, arm weight, push bias,
    #                         push goal share, dt, nullspace speed
    goal_xy: np.ndarray     # (2,)
    table: np.ndarray       # (2, 2): lower, upper corner of the table
    limits: np.ndarray      # (2, nq): the joints' lower, upper limits
    weights: np.ndarray     # (objects,) the metric's object weights
    others: np.ndarray      # the objects besides the goal object a push may aim at
    action: np.ndarray      # (2, 4): the action's lower bound and span
    pushes: np.ndarray      # (objects, 19): `propagation.policy_array` of a push of each
    held: np.ndarray        # (19,): `propagation.policy_array` of a held velocity
    overlap: tuple          # `CollisionWorld.overlap_arrays`
    goal: np.ndarray        # `Stops.packed`
    project: tuple          # `manifold.project_arrays`
    world: tuple            # `Physics.arrays`
    arm: np.ndarray         # (k, steps, nq)
    objects: np.ndarray     # (k, steps, objects, 3)
    flags: np.ndarray       # (k, `Physics.flag_count`)
    results: np.ndarray     # (k, 3) int64
    features: np.ndarray    # (k, feature)
    sample_arm: np.ndarray  # (feature,)
    sample_objects: np.ndarray  # (objects, 3)
    clock: np.ndarray       # (2,) int64, `termination.monotonic`'s buffer
    counters: np.ndarray    # (7,) int64, `iterations`'
    best: np.ndarray        # (1,)
    refused: np.ndarray     # (codes, 2) int64
    naming: np.ndarray      # (codes,) int64


@njit(cache=True)
def iterations(rng: np.random.Generator, clock: Any, deadline: float, until: float,
               most: int, tree: tuple, counters: np.ndarray, best: np.ndarray,
               refused: np.ndarray, naming: np.ndarray, ints: np.ndarray, reals: np.ndarray,
               goal_xy: np.ndarray, table: np.ndarray, limits: np.ndarray,
               weights: np.ndarray, others: np.ndarray, action: np.ndarray,
               pushes: np.ndarray, held: np.ndarray, overlap: tuple, goal: np.ndarray,
               project: tuple, world: tuple, arm: np.ndarray, objects: np.ndarray,
               flags: np.ndarray, results: np.ndarray, features: np.ndarray,
               sample_arm: np.ndarray, sample_objects: np.ndarray,
               clock_buffer: np.ndarray) -> None:
    """Up to `most` iterations (`iteration`), each chosen edge added to the tree (`Tree`'s
    arrays: q, arm, objects, parent, spans, step q, step objects, Nearest's), until the clock passes
    `until` (the caller then asks the cancel, the race's gate and the progress report) or an
    iteration needs Python. counters: [nodes, steps held, iterations, propagation steps,
    why it returned (GO_ON ...), the nearest node and chosen propagation of HAND_OVER], the
    first two read and written, the others written; best: [the best goal distance];
    refused[code, named the goal object] counts the propagations the model cut short,
    naming[code] whether that rule names an object."""
    tree_q, tree_arm, tree_objects, parent, spans, step_q, step_objects, nearest = tree
    g, greedy, room = ints[1], ints[6], arm.shape[1]
    counters[2:] = 0
    for _ in range(most):
        n, used = counters[0], counters[1]
        if n == tree_q.shape[0] or used + room > step_q.shape[0]:
            counters[4] = NO_ROOM
            return
        counters[2] += 1
        near, chosen, timed_out = iteration(
            rng, clock, deadline, tree_q, tree_arm, tree_objects, n, nearest, ints, reals,
            goal_xy, table, limits, weights, others, action, pushes, held, overlap, goal, project,
            world, arm, objects, flags, results, features, sample_arm, sample_objects,
            clock_buffer)
        for k in range(results.shape[0]):
            done, code = results[k, 0], results[k, 1]
            if done < 0:
                break
            counters[3] += done
            if code > 0:
                refused[code, 1 if naming[code] and results[k, 2] == g else 0] += 1
        if timed_out:
            counters[4] = PAST_DEADLINE
            return
        if chosen >= 0:
            done = results[chosen, 0]
            end = objects[chosen, done - 1]
            distance = math.hypot(end[g, 0] - goal_xy[0], end[g, 1] - goal_xy[1])
            if results[chosen, 1] == -GOAL or (greedy and distance < best[0] - 1e-3):
                counters[4], counters[5], counters[6] = HAND_OVER, near, chosen
                return
            tree_q[n], tree_arm[n], tree_objects[n] = arm[chosen, done - 1], features[chosen], end
            parent[n], spans[n, 0], spans[n, 1] = near, used, used + done
            set_arrangement(tree_objects, nearest, n, near)
            step_q[used:used + done] = arm[chosen, :done]
            step_objects[used:used + done] = objects[chosen, :done]
            counters[0], counters[1] = n + 1, used + done
            best[0] = min(best[0], distance)
        if monotonic(clock, clock_buffer) > until:
            break
    counters[4] = GO_ON


@njit(cache=True)
def iteration(rng: np.random.Generator, clock: Any, deadline: float,
              tree_q: np.ndarray, tree_arm: np.ndarray, tree_objects: np.ndarray, n: int,
              nearest: tuple, ints: np.ndarray, reals: np.ndarray, goal_xy: np.ndarray,
              table: np.ndarray, limits: np.ndarray, weights: np.ndarray, others: np.ndarray,
              action: np.ndarray, pushes: np.ndarray, held: np.ndarray, overlap: tuple,
              goal: np.ndarray, project: tuple, world: tuple, arm: np.ndarray,
              objects: np.ndarray, flags: np.ndarray, results: np.ndarray,
              features: np.ndarray, sample_arm: np.ndarray, sample_objects: np.ndarray,
              clock_buffer: np.ndarray) -> tuple[int, int, bool]:
    """Algorithm 1's iteration up to the choice (`IterationArrays` for the arguments): sample
    x_rand (`_sample`), Nearest, then k propagations from it (`_draw`), and the one ending
    nearest x_rand by the metric (one that reached the goal first). Returns (the nearest
    node, the chosen propagation or -1, whether the deadline passed)."""
    k_actions, uniform, arm_weight = ints[2], ints[3], reals[2]
    _sample(rng, ints, reals, goal_xy, table, limits, overlap, sample_arm, sample_objects)
    near = nearest_kernel(tree_arm, n, nearest, sample_arm, sample_objects, arm_weight,
                          weights)
    policy = reals[3] > 0 and rng.random() < reals[3]
    results[:, 0] = -1
    chosen, chosen_cost = -1, math.inf
    pose, jac = np.empty((4, 4)), np.empty((6, tree_q.shape[1]))
    for k in range(k_actions):
        law, velocity, nullspace, steps = _draw(rng, policy and k == 0, ints, reals, others,
                                                action, pushes, held, sample_objects,
                                                tree_q.shape[1])
        done, code, named = _propagate(tree_q[near], tree_objects[near], steps, velocity, law,
                                       nullspace, reals[5], goal, project, world, arm[k],
                                       objects[k], flags[k], clock, clock_buffer, deadline)
        results[k, 0], results[k, 1], results[k, 2] = done, code, named
        if code == TIMED_OUT:
            return near, chosen, True
        if done == 0:
            continue
        cost = -math.inf                                   # the goal reached comes first
        if code != -GOAL:
            if uniform:
                features[k] = arm[k, done - 1]
            else:                                          # the tool's (x, y)
                chain = project[0]
                tool_kinematics(arm[k, done - 1], chain[0], chain[1], chain[2], chain[3],
                                project[1], project[2], pose, jac)
                features[k, 0], features[k, 1] = pose[0, 3], pose[1, 3]
            cost = metric(features[k], objects[k, done - 1], sample_arm, sample_objects,
                          arm_weight, weights)
        if cost < chosen_cost:
            chosen, chosen_cost = k, cost
    return near, chosen, False


@njit(cache=True)
def _sample(rng: np.random.Generator, ints: np.ndarray, reals: np.ndarray,
            goal_xy: np.ndarray, table: np.ndarray, limits: np.ndarray, overlap: tuple,
            sample_arm: np.ndarray, sample_objects: np.ndarray) -> None:
    """SampleConfiguration (§III-B) into sample_arm, sample_objects: `pcrrt.sample_arrangement`
    draw for draw, then the arm (its joints, or its tool's (x, y) over the table)."""
    m, g, goal_bias, goal_radius = ints[0], ints[1], reals[0], reals[1]
    for _ in range(100):
        sample_objects[:, 0] = rng.uniform(table[0, 0], table[1, 0], m)
        sample_objects[:, 1] = rng.uniform(table[0, 1], table[1, 1], m)
        sample_objects[:, 2] = rng.uniform(-math.pi, math.pi, m)
        if rng.random() < goal_bias:
            r = goal_radius * math.sqrt(rng.random())
            a = rng.uniform(-math.pi, math.pi)
            sample_objects[g, 0] = goal_xy[0] + r * math.cos(a)
            sample_objects[g, 1] = goal_xy[1] + r * math.sin(a)
        if not any_prism_overlap(overlap[0], overlap[1], sample_objects, overlap[2], overlap[3],
                                 overlap[4], 0.0):
            break
    if ints[3]:          # NumPy's uniform(low, high) is low + (high - low) u, u = random()
        sample_arm[:] = limits[0] + (limits[1] - limits[0]) * rng.random(limits.shape[1])
    else:
        sample_arm[0] = rng.uniform(table[0, 0], table[1, 0])
        sample_arm[1] = rng.uniform(table[0, 1], table[1, 1])


@njit(cache=True)
def _draw(rng: np.random.Generator, push: bool, ints: np.ndarray, reals: np.ndarray,
          others: np.ndarray, action: np.ndarray, pushes: np.ndarray, held: np.ndarray,
          sample_objects: np.ndarray, nq: int
          ) -> tuple[np.ndarray, np.ndarray, np.ndarray, int]:
    """One of the k actions, drawn as the Python drew it: the push bias's push of an object
    towards its place in the sample (`PushPolicy.sample_push`) or a random action
    (`PCRRT`'s SampleAction). Returns (the push law, the held velocity, the nullspace
    velocity, the steps)."""
    m, g, pushable, dt, speed = ints[0], ints[1], ints[5], reals[5], reals[6]
    if push:
        obj = g
        if not (m == 1 or rng.random() < reals[4] or pushable <= 1):
            obj = others[rng.integers(0, others.shape[0])]
        nullspace = rng.uniform(-speed, speed, nq)
        law = pushes[obj].copy()
        law[1], law[2] = sample_objects[obj, 0], sample_objects[obj, 1]
        return law, np.zeros(3), nullspace, ints[4]
    drawn = action[0] + action[1] * rng.random(4)
    duration = max(1.0, np.rint(drawn[3] / dt)) * dt
    nullspace = rng.uniform(-speed, speed, nq)
    return held, drawn[:3].copy(), nullspace, int(np.rint(duration / dt))


@njit(cache=True)
def _propagate(q: np.ndarray, objects: np.ndarray, steps: int,
               velocity: np.ndarray, law: np.ndarray, nullspace: np.ndarray, dt: float,
               goal: np.ndarray, project: tuple, world: tuple, arm: np.ndarray,
               out: np.ndarray, flags: np.ndarray, clock: Any, clock_buffer: np.ndarray,
               deadline: float) -> tuple[int, int, int]:
    """`propagation.propagate` compiled: up to `steps` steps in batches of CHECK_EVERY, the
    deadline read after each. Returns (valid steps, 0 | the invalid step's code | -GOAL |
    -ARRIVED | TIMED_OUT, the object the invalid step names or -1)."""
    flags[:] = 0
    done = 0
    while done < steps:
        batch = min(CHECK_EVERY, steps - done)
        if done == 0:
            q0, objects0 = q.copy(), objects.copy()
        else:
            q0, objects0 = arm[done - 1].copy(), out[done - 1].copy()
        count, code, named = propagate_kernel(q0, objects0, velocity, law, nullspace, batch,
                                              dt, goal, project, world, arm[done:],
                                              out[done:], flags)
        done += count
        if code == -ARRIVED:
            return done, code, named
        if monotonic(clock, clock_buffer) > deadline:
            return done, TIMED_OUT, -1
        if code != 0:
            return done, code, named
    return done, 0, -1
