"""Open-loop execution of a joint trajectory in the planner's quasistatic physics, the way a
joint trajectory controller plays it (positions interpolated linearly between the points), and
the outcome a user cares about: did the goal object end in its goal region, what moved, what
stopped the execution. ROS-free: `ros/sim/world_sim.py` drives it from a ROS topic, tests and tools
call it directly.

    command = Command(times, positions)
    execution = OpenLoopExecution(Physics(world, simulation_options(max_substep=0.001)), start,
                                  command, period=0.01)
    execution.run()
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Protocol

import numpy as np

from rearrangement_planner.model.command import Command
from rearrangement_planner.model.errors import InputError, SceneError
from rearrangement_planner.model.scene import Scene
from rearrangement_planner.model.state import State, wrap_angle
from rearrangement_planner.physics.step import Physics
from rearrangement_planner.physics.validation import parse_scene

MOVED_DISTANCE = 1e-3
"""An object counts as moved when its centre moved more than this (m) ..."""
MOVED_ROTATION = 1e-2
"""... or it turned more than this (rad)."""

# Outcome statuses (the "status" of ~/outcome)
SUCCEEDED = "SUCCEEDED"              # executed to the end, goal object in the goal region
GOAL_NOT_REACHED = "GOAL_NOT_REACHED"  # executed to the end, goal object outside the region
ABORTED = "ABORTED"                  # an invalid physics step stopped the execution
PREEMPTED = "PREEMPTED"              # replaced by a newer trajectory
CANCELLED = "CANCELLED"              # stopped by an empty trajectory or ~/reset
REJECTED = "REJECTED"                # not executed: the command is unusable (field named)


@dataclass(frozen=True)
class InvalidStep:
    """An invalid physics step met during an execution."""

    reason: str
    detail: str
    time_from_start: float
    """Trajectory time (s) of the configuration the arm could not move to."""


class Execution(Protocol):
    """What world_sim needs of an execution engine (`OpenLoopExecution` here, or
    `mujoco_engine.MujocoExecution`)."""

    command: Command
    start: State
    state: State
    t: float
    steps: int
    invalid: InvalidStep | None

    @property
    def done(self) -> bool: ...

    def update(self) -> None: ...


class Updates:
    """The controller-update clock shared by the execution engines: `update()` advances the
    trajectory time `t` by `period` s (the last update to the command's end); `run()` executes
    to the end, or to the first invalid step, at once."""

    command: Command
    period: float
    t: float
    updates: int
    invalid: InvalidStep | None

    @property
    def done(self) -> bool:
        return self.invalid is not None or self.t >= self.command.duration

    def next_end(self) -> float:
        """The trajectory time the next update ends at."""
        return min((self.updates + 1) * self.period, self.command.duration)

    def update(self) -> None:
        raise NotImplementedError

    def run(self) -> None:
        while not self.done:
            self.update()


class OpenLoopExecution(Updates):
    """One command executed open loop on the simulated world, one controller update at a time.

    `update()` advances the trajectory time by `period` s: the arm moves through every point
    the command crosses in that interval, then to the interpolated position at its end, each
    move stepped through `physics` (the objects follow). The first invalid step ends the
    execution (`invalid`); the state stays the last valid one.
    """

    def __init__(self, physics: Physics, start: State, command: Command, period: float):
        self.physics = physics
        self.command = command
        self.period = float(period)
        self.start = start
        self.state = start
        self.t = 0.0
        self.updates = 0
        self.steps = 0
        self.invalid: InvalidStep | None = None
        self.moved: set[int] = set()

    def update(self) -> None:
        if self.done:
            return
        times = self.command.times
        t_end = self.next_end()
        crossed = np.flatnonzero((times > self.t) & (times < t_end))
        targets = [(float(times[k]), self.command.positions[k]) for k in crossed]
        targets.append((t_end, self.command.sample(t_end)))
        for t, q in targets:
            result = self.physics.step(self.state, q)
            self.steps += 1
            if not result.valid:
                assert result.reason is not None  # Physics.step gives a reason for every failure
                self.invalid = InvalidStep(result.reason.value, result.detail, t)
                return
            self.state = result.state
            self.moved |= set(result.moved_objects)
            self.t = t
        self.updates += 1



@dataclass(frozen=True)
class Goal:
    """What the outcome is judged against: object index and name, goal point (m), radius."""

    index: int
    name: str
    position: np.ndarray
    radius: float


@dataclass
class ExecutionRecord:
    """The path of one execution (one entry per controller update) and its outcome."""

    number: int
    command: Command
    objects: list[np.ndarray] = field(default_factory=list)   # (M, 3) per update
    tool: list[np.ndarray] = field(default_factory=list)      # tool (x, y) per update
    outcome: dict[str, Any] | None = None


def execution_outcome(status: str, execution: Execution, goal: Goal,
                      names: tuple[str, ...], number: int, wall_time: float,
                      settings: dict[str, Any]) -> dict[str, Any]:
    """The ~/outcome JSON object of a finished (or stopped) execution."""
    start, final = execution.start.objects, execution.state.objects
    objects = {}
    for i, name in enumerate(names):
        displacement = float(np.hypot(*(final[i, :2] - start[i, :2])))
        rotation = abs(float(wrap_angle(final[i, 2] - start[i, 2])))
        objects[name] = {"start": [float(v) for v in start[i]],
                         "final": [float(v) for v in final[i]],
                         "displacement_m": displacement, "rotation_rad": rotation,
                         "moved": displacement > MOVED_DISTANCE or rotation > MOVED_ROTATION}
    distance = float(np.hypot(*(final[goal.index, :2] - goal.position)))
    reached = distance <= goal.radius
    if status == "":   # ran to its end
        status = SUCCEEDED if reached else GOAL_NOT_REACHED
    invalid = execution.invalid
    moved = [f"{n} {o['displacement_m']:.3f} m" for n, o in objects.items() if o["moved"]]
    message = (f"execution {number}: {status}: '{goal.name}' is {distance:.3f} m from the goal "
               f"({'inside' if reached else 'outside'} radius {goal.radius:.3f} m) after "
               f"{execution.t:.2f} of {execution.command.duration:.2f} s of trajectory "
               f"({wall_time:.2f} s wall); moved: {', '.join(moved) or 'nothing'}")
    if invalid is not None:
        message += (f"; invalid step at t = {invalid.time_from_start:.2f} s: {invalid.reason}: "
                    f"{invalid.detail} (arm and objects stopped at the last valid state)")
    return {
        "status": status, "execution": number, "message": message,
        "goal": {"object": goal.name, "position": [float(v) for v in goal.position],
                 "radius_m": goal.radius, "distance_m": distance, "reached": reached},
        "objects": objects,
        "moved_objects": [n for n, o in objects.items() if o["moved"]],
        "invalid": None if invalid is None else {
            "reason": invalid.reason, "detail": invalid.detail,
            "time_from_start_s": invalid.time_from_start},
        "duration_s": execution.command.duration, "executed_s": execution.t,
        "wall_time_s": wall_time, "physics_steps": execution.steps,
        "final_configuration": [float(v) for v in execution.state.q],
        **settings,
    }




def perturbed_world(scene: Scene, start_configuration: np.ndarray | None, pose_noise: float,
                    yaw_noise: float, friction_scale: float, seed: int
                    ) -> tuple[Scene, np.ndarray]:
    """The true world of the simulation and the perception offset.

    Returns the scene whose objects are at their TRUE initial poses (the scene's plus a normal
    offset of std dev `pose_noise` m in x and y and `yaw_noise` rad in yaw, drawn from `seed`)
    with frictions scaled by `friction_scale`, and the offsets (M, 3): published pose = true
    pose - offset. Raises InputError (naming the parameter) when the result is not a valid
    world, e.g. noise that pushes an object into another or off the table.
    """
    offsets = np.zeros((len(scene.objects), 3))
    if pose_noise > 0 or yaw_noise > 0:
        rng = np.random.default_rng(seed)
        offsets = rng.normal(0.0, 1.0, size=offsets.shape) * [pose_noise, pose_noise, yaw_noise]
    data = scene.to_dict()
    if start_configuration is not None:
        data["start_configuration"] = [float(v) for v in start_configuration]
    for entry, offset in zip(data["objects"], offsets, strict=True):
        x, y, yaw = np.asarray(entry["pose"]) + offset
        entry["pose"] = [float(x), float(y), float(wrap_angle(yaw))]
        entry["support_friction"] = float(entry["support_friction"]) * friction_scale
        entry["pusher_friction"] = float(entry["pusher_friction"]) * friction_scale
    try:
        world = parse_scene(data, base_dir=Path(scene.source).parent, name=scene.source,
                            robot=scene.robot)
    except SceneError as exc:
        if exc.field.startswith("start_configuration"):
            raise InputError("parameter start_configuration", str(exc)) from None
        raise InputError("parameters pose_noise/yaw_noise/friction_scale/seed",
                         f"pose_noise {pose_noise:g} m, yaw_noise {yaw_noise:g} rad, "
                         f"friction_scale {friction_scale:g}, seed {seed} give no valid world: "
                         f"{exc}; choose smaller noise or another seed") from None
    return world, offsets
