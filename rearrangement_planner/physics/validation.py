"""Semantic validation of a scene (docs/design.md, §5 validity) and the validated loaders.

`model.scene` reads the scene format and checks structure, types and units; what needs the
geometry lives here, beside the collision checker it uses: objects on the table and apart, the
goal point on the table, a start configuration within its limits and clear of the table, the
obstacles and the objects.

    scene = load_scene("default")          # a shipped scene name or a .yaml path
    scene = parse_scene(mapping, name="generated")
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from rearrangement_planner.model.errors import SceneError
from rearrangement_planner.model.robot import RobotModel
from rearrangement_planner.model.scene import (
    TOUCH_TOLERANCE,
    Scene,
    check_goal_radius,
    read_scene,
    scene_from_dict,
)
from rearrangement_planner.physics.collision import CollisionWorld, prism_penetration


def load_scene(path: str | Path, robot: RobotModel | None = None) -> Scene:
    """Load a scene file (`model.scene.read_scene`) and check it (`check_scene`)."""
    scene = read_scene(path, robot)
    check_scene(scene)
    return scene


def parse_scene(data: Any, base_dir: Path | None = None, name: str = "<scene>",
                robot: RobotModel | None = None) -> Scene:
    """Build a scene from its YAML mapping (`model.scene.scene_from_dict`) and check it."""
    scene = scene_from_dict(data, base_dir, name, robot)
    check_scene(scene)
    return scene


def check_scene(scene: Scene, world: CollisionWorld | None = None) -> None:
    """Raise `SceneError` if `scene` is not a valid planning problem (docs/design.md, §5 validity):
    objects off the table (centre outside the rectangle), goal object unknown or goal point off
    the table, objects overlapping each other or an obstacle, and a start configuration of the
    wrong length, outside the joint limits or in collision with the table, an obstacle or an
    object. `world` may pass an existing `CollisionWorld` of this scene."""
    _check_placement(scene)
    world = world if world is not None else CollisionWorld(scene)
    _check_overlaps(scene, world)
    _check_start(scene, world)


def _check_placement(scene: Scene) -> None:
    table = scene.table
    for i, obj in enumerate(scene.objects):
        if not bool(table.contains(obj.pose[:2])):
            raise SceneError(f"objects[{i}].pose",
                             f"object '{obj.name}' at ({obj.pose[0]:.3f}, {obj.pose[1]:.3f}) is "
                             f"off the table; its centre must lie on the table top "
                             f"({table.describe()})")
    check_goal_radius(table, scene.goal)
    names = list(scene.object_names)
    if scene.goal.object not in names:
        raise SceneError("goal.object",
                         f"no object named '{scene.goal.object}'; objects are {names}")
    if not bool(table.contains(scene.goal.position)):
        raise SceneError("goal.position",
                         f"goal point ({scene.goal.position[0]:.3f}, "
                         f"{scene.goal.position[1]:.3f}) is off the table; it must lie on the "
                         f"table top ({table.describe()})")


def _check_overlaps(scene: Scene, world: CollisionWorld) -> None:
    names, poses = scene.object_names, scene.object_poses
    for i, j in world.object_overlaps(poses, tol=TOUCH_TOLERANCE):
        raise SceneError(f"objects[{j}].pose",
                         f"object '{names[j]}' overlaps object '{names[i]}' (objects[{i}]); "
                         f"movable objects must not overlap")
    for i, obstacle in world.object_obstacle_overlaps(poses, tol=TOUCH_TOLERANCE):
        raise SceneError(f"objects[{i}].pose",
                         f"object '{names[i]}' overlaps obstacle '{obstacle}'; objects must "
                         f"stand clear of obstacles")


def _check_start(scene: Scene, world: CollisionWorld) -> None:
    robot, q = scene.robot, scene.start_configuration
    if q.shape != (robot.nq,):
        raise SceneError("start_configuration",
                         f"expected {robot.nq} joint positions (rad), one per joint "
                         f"{list(robot.joint_names)}; got {q.size}")
    if not np.all(np.isfinite(q)):
        raise SceneError("start_configuration", f"{list(map(float, q))} has a non-finite entry")
    for k in range(robot.nq):
        if not robot.lower[k] <= q[k] <= robot.upper[k]:
            raise SceneError("start_configuration",
                             f"{robot.joint_names[k]} = {q[k]:.4f} rad (entry {k}) is outside "
                             f"its joint limits [{robot.lower[k]:.4f}, {robot.upper[k]:.4f}]")
    reason = world.arm_in_collision(q, scene.object_poses, tol=TOUCH_TOLERANCE)
    if reason is not None:
        raise SceneError("start_configuration",
                         f"the arm is in collision: {reason}; choose a configuration clear of "
                         f"the table, obstacles and objects")


SEPARATION_LIMIT = 0.03
"""m: the most `separate_objects` moves an observed object."""
SEPARATION_GAP = 1e-4
"""m: the gap it leaves between objects it moves apart."""


def separate_objects(scene: Scene, poses: np.ndarray,
                     limit: float = SEPARATION_LIMIT) -> np.ndarray | None:
    """Observed object poses (M, 3) with overlapping objects moved apart: objects that touch
    after a push overlap a little in observed poses (MuJoCo's soft contacts, a perception's
    error), and a planning start must not. Each overlapping pair moves apart along the line
    between their centres, half each, until none overlaps; None when that would move an object
    more than `limit` m (then the observation is not a state to plan from). The closed loop
    re-plans from these (docs/design.md "Closed loop")."""
    poses = np.array(poses, dtype=float)
    start = poses.copy()
    world = CollisionWorld(scene)
    objects = scene.objects
    for _ in range(20):
        pairs = world.object_overlaps(poses, tol=TOUCH_TOLERANCE)
        if not pairs:
            return poses
        for i, j in pairs:
            depth = prism_penetration(objects[i].shape, list(objects[i].size), poses[i].tolist(),
                                      objects[j].shape, list(objects[j].size),
                                      poses[j].tolist())
            line = poses[j, :2] - poses[i, :2]
            length = float(np.hypot(*line))
            direction = line / length if length > 1e-9 else np.array([1.0, 0.0])
            shift = 0.5 * (max(depth, 0.0) + SEPARATION_GAP) * direction
            poses[i, :2] -= shift
            poses[j, :2] += shift
        if np.max(np.hypot(*(poses[:, :2] - start[:, :2]).T)) > limit:
            return None
    return None

