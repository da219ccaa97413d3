"""Training data for the learned oracle (Haustein et al. 2018, §II "Learning the Policy"): single
object pushes in an obstacle-free world, simulated by the planner's own compiled physics and
Project step (`planning.machinery.propagation`), under noise in the object's pose and physical
properties.

One sample is a tuple (x_r, ν_o, u) and the successor object states of `noise_draws`
executions of u, each from a perturbed object. Everything is expressed in the object's frame
(its start pose is the origin, yaw 0), so that the models learn one push for every place on the
table:

- x_r (3,): the tool's planar pose (x, y, yaw) relative to the object, m and rad;
- ν_o (7,): `oracle_models.PROPERTY_NAMES` (cylinder flag, full extents, mass, frictions);
- u (3,): the tool's planar velocity (v_x, v_y) in the object frame (m/s) and its duration (s);
- x_o' (K, 3): where the object came to rest, (x, y, yaw) in its start frame.

The arm starts from a few resting configurations on the pushing manifold with the tool at
different places and yaws over the table (`_arm_states`); for each sample the object is put
where x_r says relative to one of them. A sample whose start is invalid (the object would
overlap the arm or leave the table) is drawn again.

The object is drawn from the benchmark's distribution (`tools.bench.trials`: box sides, cylinder
radii, heights, masses and frictions), the goal object's size included.
"""

from __future__ import annotations

import dataclasses
import math
import multiprocessing
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import cast

import numpy as np

from rearrangement_planner.model.resources import scenes_dir
from rearrangement_planner.model.scene import Goal, MovableObject, Scene
from rearrangement_planner.model.state import State
from rearrangement_planner.physics.step import OBJ_PUSHER_MU, OBJ_SUPPORT_MU, Physics
from rearrangement_planner.physics.validation import load_scene
from rearrangement_planner.planning.machinery.approach import approach_path
from rearrangement_planner.planning.machinery.manifold import tool_planar_pose
from rearrangement_planner.planning.machinery.propagation import Action, constrained_prop
from rearrangement_planner.planning.planners.learned_oracle import (
    PROPERTY_NAMES,
    object_properties,
    to_base,
    to_local,
)
from rearrangement_planner.tools.bench import trials as benchmark

DT = 0.1
"""s: the planner's step (PlannerOptions.dt)."""


@dataclass(frozen=True)
class DataOptions:
    """How the pushes are drawn."""

    max_speed: float = 0.10
    """m/s: the largest tool speed of a push (the planners' `max_speed`)."""
    max_duration: float = 4.0
    """s: the longest push (the slice-based RRT's `max_push`)."""
    reach: float = 0.14
    """m: the tool is drawn within this distance of the object's footprint circle."""
    noise_draws: int = 6
    """Executions per sample, each from a perturbed object."""
    pose_noise: float = 0.005
    """m: the standard deviation of the object's position noise (as `model.perturbation`)."""
    yaw_noise: float = math.radians(2.0)
    """rad: the standard deviation of the object's yaw noise."""
    friction_noise: float = 0.3
    """Frictions are scaled by U(1 - this, 1 + this)."""
    aimed: float = 0.8
    """Share of pushes that head at the object's centre (within N(0, 0.35) rad)."""
    arm_states: int = 12
    """Resting arm configurations the pushes start from."""


@dataclass(frozen=True)
class PushData:
    """Samples: `tool` (N, 3), `properties` (N, 7), `action` (N, 3), `successors` (N, K, 3)."""

    tool: np.ndarray
    properties: np.ndarray
    action: np.ndarray
    successors: np.ndarray

    def save(self, path: str | Path, stamp: str = "") -> None:
        """Write the samples (and `stamp`, what made them) as an .npz."""
        np.savez_compressed(path, stamp=np.array(stamp), **dataclasses.asdict(self))

    @classmethod
    def load(cls, path: str | Path) -> PushData:
        with np.load(path) as data:
            return cls(*(data[f.name] for f in dataclasses.fields(cls)))


def draw_object(rng: np.random.Generator) -> MovableObject:
    """An object from the benchmark's distribution (a quarter of them the goal object's box)."""
    mass = rng.uniform(*benchmark.MASS)
    frictions = dict(mass=mass, support_friction=rng.uniform(*benchmark.SUPPORT_FRICTION),
                     pusher_friction=rng.uniform(*benchmark.PUSHER_FRICTION))
    height = rng.uniform(*benchmark.HEIGHT)
    kind = rng.random()
    if kind < 0.25:
        size = cast(Sequence[float], benchmark.GOAL_OBJECT["size"])
        return MovableObject.box("object", size, (0.0, 0.0, 0.0), **frictions)
    if kind < 0.65:
        return MovableObject.box("object", (*rng.uniform(*benchmark.BOX_SIDE, 2), height),
                                 (0.0, 0.0, 0.0), **frictions)
    return MovableObject.cylinder("object", rng.uniform(*benchmark.CYLINDER_RADIUS), height,
                                  (0.0, 0.0, 0.0), **frictions)


class PushSimulator:
    """Single-object pushes on the benchmark's table with the scene's robot."""

    def __init__(self, scene: Scene, options: DataOptions, rng: np.random.Generator):
        self.base = dataclasses.replace(scene, obstacles=())
        self.options = options
        self.arms = self._arm_states(rng)

    def _physics(self, obj: MovableObject) -> Physics:
        scene = dataclasses.replace(self.base, objects=(obj,),
                                    goal=Goal(obj.name, np.array([10.0, 10.0]), 0.01))
        return Physics(scene)

    def _arm_states(self, rng: np.random.Generator) -> list[State]:
        """Resting configurations on the manifold: the approach from the scene's start, then
        transits (no object) to random tool poses over the middle of the table."""
        corner = np.asarray(self.base.table.upper) - 0.03
        far = MovableObject.box("object", (0.04, 0.04, 0.1), (*corner, 0.0))
        physics = self._physics(far)
        start = State(self.base.start_configuration, np.array([far.pose]))
        path, why = approach_path(physics, start, rng)
        if path is None:
            raise RuntimeError(f"no approach onto the pushing manifold: {why}")
        states = [path[-1]]
        robot = physics.robot
        centre = np.asarray(self.base.table.center, dtype=float)
        while len(states) < self.options.arm_states:
            here = tool_planar_pose(robot, states[0].q)
            goal = np.array([*(centre + rng.uniform(-0.2, 0.2, 2)),
                             here[2] + rng.uniform(-1.2, 1.2)])
            steps = 40
            velocity = np.array([(goal[0] - here[0]), (goal[1] - here[1]),
                                 goal[2] - here[2]]) / (steps * DT)
            moved = constrained_prop(physics, states[0], Action(velocity, steps * DT,
                                                                np.zeros(robot.nq)), DT)
            if moved.stopped is None and moved.states:
                states.append(moved.states[-1])
        return states

    def sample(self, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray, np.ndarray,
                                                         np.ndarray]:
        """One sample (x_r, ν_o, u, successors), drawn until its start is valid."""
        opts = self.options
        obj = draw_object(rng)
        physics = self._physics(obj)
        props = physics.arrays.obj_props
        nominal = props[0].copy()
        table = self.base.table
        while True:
            arm = self.arms[rng.integers(len(self.arms))]
            tool = tool_planar_pose(physics.robot, arm.q)
            bearing = rng.uniform(-math.pi, math.pi)
            # mostly close enough for the push to reach the object
            near = opts.reach if rng.random() < 0.3 else 0.35 * opts.reach
            distance = obj.footprint_radius + rng.uniform(0.0, near)
            # the hand mostly faces the object (as it does when it pushes), sometimes not
            facing = bearing + math.pi + (rng.normal(0.0, 0.6) if rng.random() < 0.8
                                         else rng.uniform(-math.pi, math.pi))
            x_r = np.array([distance * math.cos(bearing), distance * math.sin(bearing),
                            math.atan2(math.sin(facing), math.cos(facing))])
            # The object's pose in the base frame: the tool's pose composed with x_r's inverse.
            object_pose = to_base(tool, to_local(x_r, np.zeros(3)))
            if not table.contains(object_pose[None, :2])[0]:
                continue
            if physics.check_state(State(arm.q, object_pose[None])) is not None:
                continue
            break
        # Most pushes head at the object (a push that misses teaches little).
        heading = (bearing + math.pi + rng.normal(0.0, 0.35) if rng.random() < opts.aimed
                   else rng.uniform(-math.pi, math.pi))
        speed = opts.max_speed * rng.uniform(0.3, 1.0)
        duration = DT * rng.integers(2, int(round(opts.max_duration / DT)) + 1)
        u = np.array([speed * math.cos(heading), speed * math.sin(heading), duration])
        c, s = math.cos(object_pose[2]), math.sin(object_pose[2])
        velocity = np.array([c * u[0] - s * u[1], s * u[0] + c * u[1], 0.0])
        action = Action(velocity, duration, np.zeros(physics.robot.nq))
        successors = np.empty((opts.noise_draws, 3))
        for k in range(opts.noise_draws):
            noisy = object_pose + rng.normal(0.0, 1.0, 3) * [opts.pose_noise, opts.pose_noise,
                                                              opts.yaw_noise]
            scale = rng.uniform(1.0 - opts.friction_noise, 1.0 + opts.friction_noise, 2)
            props[0, OBJ_SUPPORT_MU] = nominal[OBJ_SUPPORT_MU] * scale[0]
            props[0, OBJ_PUSHER_MU] = nominal[OBJ_PUSHER_MU] * scale[1]
            start = State(arm.q, noisy[None])
            end = noisy
            if physics.check_state(start) is None:
                result = constrained_prop(physics, start, action, DT)
                if result.states:
                    end = result.states[-1].objects[0]
            successors[k] = to_local(object_pose, end)
        props[0] = nominal
        return x_r, object_properties(obj), u, successors


CHUNK = 2000
"""Samples per independently seeded chunk: chunk i is drawn from SeedSequence([seed, i]), so
the data are the same whatever the number of worker processes."""


def _chunk(args: tuple[int, int, int, DataOptions, Scene | None]) -> PushData:
    samples, seed, index, options, scene = args
    rng = np.random.default_rng(np.random.SeedSequence([seed, index]))
    scene = scene or load_scene(scenes_dir() / "default.yaml")
    simulator = PushSimulator(scene, options, rng)
    rows = [simulator.sample(rng) for _ in range(samples)]
    tool, props, action, succ = (np.array(column) for column in zip(*rows, strict=True))
    assert props.shape[1] == len(PROPERTY_NAMES)
    return PushData(tool, props, action, succ)


def generate(samples: int, seed: int, options: DataOptions | None = None,
             scene: Scene | None = None, workers: int = 1) -> PushData:
    """`samples` pushes from seed `seed` (the same seed gives the same data, on any number of
    `workers` processes)."""
    options = options or DataOptions()
    jobs = [(min(CHUNK, samples - start), seed, i, options, scene)
            for i, start in enumerate(range(0, samples, CHUNK))]
    if workers > 1 and len(jobs) > 1:
        with multiprocessing.get_context("spawn").Pool(workers) as pool:
            parts = pool.map(_chunk, jobs)
    else:
        parts = [_chunk(job) for job in jobs]
    return PushData(*(np.concatenate([getattr(p, f.name) for p in parts])
                      for f in dataclasses.fields(PushData)))
