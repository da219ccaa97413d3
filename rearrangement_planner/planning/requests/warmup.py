"""Compile the fast core before the first plan: the Numba kernels of the physics
step, the Project step and the propagation are compiled on their first call, about half a
minute on this machine, and cached on disk (`rearrangement_planner._numba_cache_dir`), so a
later process only loads them (well under a second). `warm_up` makes that first call on a
small scene, outside every plan's clock: `plan_scene` calls it before it plans, the node at
start."""

from __future__ import annotations

import logging
import threading
import time

import numpy as np

_LOG = logging.getLogger(__name__)
_lock = threading.Lock()
_seconds: float | None = None


def warm_up() -> float:
    """Compile (or load from the disk cache) every compiled entry point once per process, by
    running each on the shipped easy_push scene. Returns the seconds it took the first time
    (0.0 afterwards); thread-safe."""
    global _seconds
    with _lock:
        if _seconds is not None:
            return 0.0
        start = time.perf_counter()
        _exercise()
        _seconds = time.perf_counter() - start
    if _seconds > 1.0:
        _LOG.info("compiled the physics core in %.1f s (cached for later runs)", _seconds)
    return _seconds


def _exercise() -> None:
    """One call of each compiled entry point, with the argument types the planners use."""
    from rearrangement_planner.model.state import State
    from rearrangement_planner.physics.collision import prism_penetration
    from rearrangement_planner.physics.step import Physics
    from rearrangement_planner.physics.validation import load_scene
    from rearrangement_planner.planning.machinery.manifold import (
        default_push_configuration,
        joint_limit_gradient,
        manifold_error,
        project_step,
    )
    from rearrangement_planner.planning.machinery.propagation import (
        Action,
        Stops,
        constrained_prop,
        replay,
    )
    from rearrangement_planner.planning.machinery.push_policy import push_policy_prop
    from rearrangement_planner.planning.machinery.tree import Tree, weighted_distance
    from rearrangement_planner.planning.planners.pcrrt import PCRRT, PCRRTOptions
    from rearrangement_planner.planning.requests.robustness import rollout, rollout_options

    scene = load_scene("easy_push")
    physics = Physics(scene)
    start = State(default_push_configuration(scene.robot, scene.table.height),
                  scene.initial_state().objects)
    physics.check_state(start)
    physics.world.objects_overlap(start.objects)
    physics.step(start, project_step(scene.robot, start.q, np.array([0.0, 0.1, 0.0]), 0.05,
                                     scene.table.height))
    manifold_error(scene.robot, start.q, scene.table.height)
    joint_limit_gradient(scene.robot, start.q, 0.5)
    prism_penetration("box", (0.1, 0.1, 0.1), (0.0, 0.0, 0.0), "cylinder", (0.1, 0.1, 0.1),
                      (0.05, 0.0, 0.0))
    stops = Stops(scene.goal_index, (0.0, 0.0), 0.0)
    push = Action(np.array([0.0, 0.1, 0.0]), 0.5, np.zeros(scene.robot.nq))
    constrained_prop(physics, start, push, 0.05, stops)
    replay(physics, start, [start.q, start.q], until=stops)
    rollout(scene, np.array([start.q, start.q]), rollout_options(physics.options))
    tree = Tree(start, np.zeros(2))
    tree.nearest(np.zeros(2), start.objects, 1.0, np.ones(len(scene.objects)))
    weighted_distance(np.zeros(2), start.objects, np.zeros(2), start.objects, 1.0,
                      np.ones(len(scene.objects)))
    push_policy_prop(physics, start, scene.goal_index, np.array([0.5, -0.1]), 2, 0.05, 0.1,
                     push.nullspace, stops)
    PCRRT(scene, PCRRTOptions(max_iterations=1), physics).plan(seed=0)   # its compiled iteration


def compile_seconds() -> float | None:
    """How long this process's `warm_up` took, None before it ran."""
    return _seconds
