"""The Static RRT baseline of King et al. 2015, §V-A: PC-RRT in which only the goal object may move;
every other movable object is a static obstacle ("All movable objects are treated as static
obstacles"). It is PC-RRT with `PhysicsOptions.static_objects` = every non-goal object, so any
arm contact with one of them ends the propagation as invalid.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from rearrangement_planner.model.scene import Scene
from rearrangement_planner.physics.step import Physics
from rearrangement_planner.planning.machinery.interface import PlannerOptions
from rearrangement_planner.planning.planners.pcrrt import PCRRT


def static_physics(scene: Scene, physics: Physics | None = None) -> Physics:
    """The Static RRT's world: `physics` (default the scene's own) with every object but the
    goal object static, so that touching one is invalid. Whatever re-simulates a Static RRT
    path (shortcutting) must use it too, or it could push the objects the planner may not."""
    static = frozenset(o.name for o in scene.objects if o.name != scene.goal.object)
    base = physics or Physics(scene)
    return Physics(scene, dataclasses.replace(base.options, static_objects=static), base.robot)


class StaticRRT(PCRRT):
    """PC-RRT where only the goal object may move (King et al. 2015, §V-A)."""

    name = "static-rrt"

    def __init__(self, scene: Scene, options: PlannerOptions | None = None,
                 physics: Physics | None = None):
        super().__init__(scene, options, static_physics(scene, physics))
        # Objects that cannot move add the same distance to every node: leave them out.
        weights = np.zeros(len(scene.objects))
        weights[scene.goal_index] = self.options.goal_weight
        self._weights = weights
