"""world_sim's MuJoCo engine (`engine:=mujoco`, the world of `make demo`): a controller command
executed in the product's 3D world (`world3d`), one controller update at a time, behind
`open_loop.OpenLoopExecution`'s interface."""

from __future__ import annotations

import math

from rearrangement_planner.execution.open_loop import InvalidStep, Updates
from rearrangement_planner.model.command import Command
from rearrangement_planner.model.scene import Scene
from rearrangement_planner.model.state import State
from rearrangement_planner.world3d.execution import Execution, tilt
from rearrangement_planner.world3d.mujoco_model import ExecutionOptions, build_model


class MujocoExecution(Updates):
    """`open_loop.OpenLoopExecution`'s interface over MuJoCo: world_sim's `engine:=mujoco`
    executes a controller command here, one controller update at a time. An object that
    topples ends the execution (`invalid`, reason 'object_toppled')."""

    def __init__(self, world: Scene, start: State, command: Command, period: float,
                 options: ExecutionOptions | None = None):
        self.options = options or ExecutionOptions(settle=0.0, hold=0.0)
        scene = world.with_start(start.q, start.objects)
        self.command, self.period, self.start, self.state = command, float(period), start, start
        self.t, self.updates, self.steps = 0.0, 0, 0
        self.invalid: InvalidStep | None = None
        self._run = Execution(build_model(scene, self.options), scene, command, None,
                              self.options)
        self._run.begin()

    def update(self) -> None:
        if self.done:
            return
        t_end = self.next_end()
        self.steps += self._run.advance(t_end)
        self.t = t_end
        self.updates += 1
        run = self._run
        self.state = State(run.data.qpos[run.qadr].copy(), run.poses())
        for i, body in enumerate(run.bodies):
            angle = tilt(run.data, body)
            if angle > self.options.tip_angle:
                self.invalid = InvalidStep("object_toppled", f"'{run.scene.objects[i].name}' "
                                           f"tilted {math.degrees(angle):.0f} deg", t_end)
                return
