"""Fixtures of the execution tests: a straight push along the pushing manifold and the scene,
trajectory and quasistatic prediction of pushing given objects along it."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from rearrangement_planner.execution.open_loop import Command, OpenLoopExecution
from rearrangement_planner.physics.options import PhysicsOptions, simulation_options
from rearrangement_planner.physics.step import Physics
from rearrangement_planner.physics.validation import parse_scene
from rearrangement_planner.planning.machinery.manifold import (
    default_push_configuration,
    ik_on_manifold,
)
from rearrangement_planner.planning.requests.trajectory import Trajectory


@pytest.fixture(scope="module")
def push_path(panda):
    """The tool on the pushing manifold moving along +x from 0.40 to 0.55 m at 5 cm/s (IK
    every 5 mm), after a 1 s hold: times and positions."""
    xs = np.arange(0.40, 0.55 + 1e-9, 0.005)
    q = default_push_configuration(panda, 0.0)
    path = []
    for x in xs:
        q = ik_on_manifold(panda, float(x), 0.0, 0.0, 0.0, q)
        path.append(q)
    positions = np.vstack([path[:1], path])
    times = np.concatenate([[0.0], 1.0 + np.arange(len(xs)) * 0.1])
    return times, positions


@pytest.fixture(scope="module")
def pushed(panda, push_path):
    """pushed(objects, options=None): (scene, trajectory, final state), as below."""
    return lambda objects, options=None: _pushed(panda, push_path, objects, options)


def _pushed(panda, push_path, objects, options: PhysicsOptions | None = None):
    """The scene with `objects` on the table, the push as a trajectory, and the quasistatic
    prediction (world_sim's physics with `options`, 1 mm substeps)."""
    times, positions = push_path
    data = {"table": {"center": [0.55, 0.0], "size": [0.8, 1.2], "height": 0.0},
            "start_configuration": positions[0].tolist(), "objects": objects,
            "goal": {"object": objects[0]["name"], "position": [0.59, 0.0], "radius": 0.02}}
    scene = parse_scene(data, robot=panda)
    trajectory = Trajectory(panda.joint_names, times, positions, np.zeros_like(positions))
    options = dataclasses.replace(options or simulation_options(), max_substep=0.001)
    execution = OpenLoopExecution(Physics(scene, options),
                                  scene.initial_state(), Command(times, positions), period=0.01)
    execution.run()
    assert execution.invalid is None
    return scene, trajectory, execution.state
