"""Perturbed copies of a scene: the world an open-loop plan meets is never exactly the one it
was planned in (docs/design.md, robust plans of §6; Koval, King et al. 2015). Used by the
robustness rollouts in the planner's physics and by the perturbed executions in MuJoCo."""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from rearrangement_planner.model.scene import MovableObject, Scene, SupportPressure


@dataclass(frozen=True)
class Perturbation:
    """What the model cannot know, drawn per object: its frictions scaled by U(1 - friction,
    1 + friction), its mass by U(1 - mass, 1 + mass), its pose offset by N(0, pose_noise) m in
    x and y and N(0, yaw_noise) rad in yaw; and how its weight rests on the table
    (`SupportPressure`, Lynch, Maekawa & Tanie 1992): the limit surface's c scaled by
    U(pressure) (from centre-loaded, 0.8, to rim- or corner-loaded, 1.5-1.85) and the centre of
    friction offset uniformly within `centre_offset` of the footprint's half extents (a box)
    or radius (a cylinder). Friction that varies from place to place on one surface (Yu et al.
    2016) moves the centre of friction as an off-centre load does. The pressure decides how a
    pushed object turns, which is what the quasistatic model predicts worst.

    Also the arm's contact shapes all grown by one U(-contact_offset, contact_offset) m: where
    the real links and finger pads meet an object is known to a few mm only (the shapes are
    fitted to the meshes, the arm tracks its trajectory to a few mm). The offset acts on the
    planner's physics only: the MuJoCo check always uses the real meshes, and moves the
    object's centre of mass over the drawn centre of friction instead
    (`world3d.execution.check_perturbed`)."""

    friction: float = 0.3
    mass: float = 0.2
    pose_noise: float = 0.005
    yaw_noise: float = math.radians(2.0)
    contact_offset: float = 0.005
    pressure: tuple[float, float] = (0.8, 1.8)
    centre_offset: float = 0.25

    def __post_init__(self) -> None:
        if len(self.pressure) != 2:
            raise ValueError(f"pressure must be a range (low, high) of c scales, got "
                             f"{self.pressure}")
        lo, hi = (float(v) for v in self.pressure)
        if not 0.0 < lo <= hi or not math.isfinite(hi):
            raise ValueError(f"pressure must be a range 0 < low <= high of c scales, got "
                             f"{self.pressure}")
        if not 0.0 <= self.centre_offset < 1.0:
            raise ValueError(f"centre_offset must be a share of the footprint in [0, 1), got "
                             f"{self.centre_offset}")
        object.__setattr__(self, "pressure", (lo, hi))

    def apply(self, scene: Scene, rng: np.random.Generator) -> Scene:
        """A perturbed copy of `scene` (not checked: objects may now touch)."""
        objects = []
        for obj in scene.objects:
            offset = rng.normal(0.0, 1.0, 3) * [self.pose_noise, self.pose_noise, self.yaw_noise]
            scale = rng.uniform(1.0 - self.friction, 1.0 + self.friction, 2)
            mass = obj.mass * rng.uniform(1.0 - self.mass, 1.0 + self.mass)
            objects.append(dataclasses.replace(
                obj, pose=np.asarray(obj.pose) + offset, mass=mass,
                support_friction=obj.support_friction * scale[0],
                pusher_friction=obj.pusher_friction * scale[1],
                support=self.support(obj, rng)))
        perturbed = dataclasses.replace(scene, objects=tuple(objects))
        if self.contact_offset > 0.0:
            grow = rng.uniform(-self.contact_offset, self.contact_offset)
            perturbed = dataclasses.replace(perturbed, robot=scene.robot.grown(grow))
        return perturbed

    def support(self, obj: MovableObject, rng: np.random.Generator) -> SupportPressure:
        """A support pressure for `obj`: c scale from `pressure`, centre of friction within
        `centre_offset` of the footprint (uniform over the scaled rectangle, or disk). A
        perturbation that varies neither draws nothing: the nominal support."""
        if self.pressure == (1.0, 1.0) and self.centre_offset == 0.0:
            return obj.support
        c_scale = rng.uniform(*self.pressure)
        u = rng.uniform(-1.0, 1.0, 2)
        if obj.shape == "cylinder":
            # uniform in the disk of radius centre_offset R: radius sqrt(U), angle U
            radius = self.centre_offset * 0.5 * float(obj.size[0]) * math.sqrt(0.5 * (u[0] + 1))
            angle = math.pi * u[1]
            centre = (radius * math.cos(angle), radius * math.sin(angle))
        else:
            centre = (u[0] * self.centre_offset * 0.5 * float(obj.size[0]),
                      u[1] * self.centre_offset * 0.5 * float(obj.size[1]))
        return SupportPressure(c_scale, centre)
