"""Perturbed copies of a scene: the world an open-loop plan meets is never exactly the one it
was planned in (docs/design.md, robust plans of §6; Koval, King et al. 2015). Used by the
robustness rollouts in the planner's physics and by the perturbed executions in MuJoCo."""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from rearrangement_planner.model.scene import Scene


@dataclass(frozen=True)
class Perturbation:
    """Each object's frictions scaled by U(1 - friction, 1 + friction), its mass by
    U(1 - mass, 1 + mass), its pose offset by N(0, pose_noise) m in x and y and N(0, yaw_noise)
    rad in yaw (defaults: docs/design.md, friction x0.7-1.3, mass x0.8-1.2, 5 mm / 2 deg); and
    the arm's contact shapes all grown by one U(-contact_offset, contact_offset) m: where the
    real links and finger pads meet an object is known to a few mm only (the shapes are fitted
    to the meshes, the arm tracks its trajectory to a few mm). The offset acts on the planner's
    physics only: the MuJoCo check always uses the real meshes."""

    friction: float = 0.3
    mass: float = 0.2
    pose_noise: float = 0.005
    yaw_noise: float = math.radians(2.0)
    contact_offset: float = 0.005

    def apply(self, scene: Scene, rng: np.random.Generator) -> Scene:
        """A perturbed copy of `scene` (not checked: objects may now touch)."""
        objects = []
        for obj in scene.objects:
            offset = rng.normal(0.0, 1.0, 3) * [self.pose_noise, self.pose_noise, self.yaw_noise]
            scale = rng.uniform(1.0 - self.friction, 1.0 + self.friction, 2)
            objects.append(dataclasses.replace(
                obj, pose=np.asarray(obj.pose) + offset,
                mass=obj.mass * rng.uniform(1.0 - self.mass, 1.0 + self.mass),
                support_friction=obj.support_friction * scale[0],
                pusher_friction=obj.pusher_friction * scale[1]))
        perturbed = dataclasses.replace(scene, objects=tuple(objects))
        if self.contact_offset > 0.0:
            grow = rng.uniform(-self.contact_offset, self.contact_offset)
            perturbed = dataclasses.replace(perturbed, robot=scene.robot.grown(grow))
        return perturbed
