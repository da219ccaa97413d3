"""The scene, the arm, the search, the answer and the execution as Foxglove's 3D messages
(`foxglove.SceneUpdate`, protobuf): what the live view streams (`io.live`) and what every
recording carries beside its ROS messages (`io.plan_record`), so that Foxglove shows the 3D
scene with no extra step (docs/design.md, "Live view").

    update = scene_update(scene, q)                       # table, obstacles, objects, goal, arm
    update = paths_update(scene, object_paths, tool_path) # the answer's predicted paths

Entities are in the planning frame (`FRAME`, the robot base), metres. Objects stand on the
table: a prism's centre is half its height above the table top. The arm is drawn from its
contact shapes (capsules as a cylinder between two spheres), which is what the planner's model
pushes with.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from foxglove import messages as fg

from rearrangement_planner.model.scene import Scene

FRAME = "world"
TABLE_THICKNESS = 0.05
GREY, DARK = (0.75, 0.75, 0.75, 1.0), (0.35, 0.35, 0.4, 1.0)
GOAL_OBJECT, OBJECT = (0.95, 0.55, 0.1, 1.0), (0.25, 0.5, 0.85, 1.0)
GOAL_REGION, ARM = (0.2, 0.8, 0.3, 0.35), (0.9, 0.9, 0.95, 0.8)
TREE, BEST, TOOL = (0.6, 0.6, 0.6, 0.6), (0.9, 0.1, 0.1, 1.0), (0.1, 0.1, 0.1, 1.0)
OBSERVED, STRAYED = (0.2, 0.9, 0.9, 0.6), (0.9, 0.2, 0.2, 0.8)


def color(rgba: Sequence[float]) -> fg.Color:
    r, g, b, a = rgba
    return fg.Color(r=r, g=g, b=b, a=a)


def pose(x: float, y: float, z: float, yaw: float = 0.0) -> fg.Pose:
    return fg.Pose(position=fg.Vector3(x=float(x), y=float(y), z=float(z)),
                   orientation=fg.Quaternion(x=0.0, y=0.0, z=math.sin(yaw / 2),
                                             w=math.cos(yaw / 2)))


def matrix_pose(transform: np.ndarray) -> fg.Pose:
    """The pose of a 4x4 homogeneous transform."""
    w, x, y, z = _quaternion(transform[:3, :3])
    t = transform[:3, 3]
    return fg.Pose(position=fg.Vector3(x=float(t[0]), y=float(t[1]), z=float(t[2])),
                   orientation=fg.Quaternion(x=x, y=y, z=z, w=w))


def entity(entity_id: str, **primitives) -> fg.SceneEntity:
    return fg.SceneEntity(frame_id=FRAME, id=entity_id, **primitives)


def object_entities(scene: Scene, objects: np.ndarray, prefix: str = "object",
                    colors: Sequence[Sequence[float]] | None = None) -> list[fg.SceneEntity]:
    """The movable objects at planar poses `objects` (M, 3): one entity `prefix/name` each."""
    top = scene.table.height
    entities = []
    for i, (obj, (x, y, yaw)) in enumerate(zip(scene.objects, objects, strict=True)):
        rgba = (colors[i] if colors is not None
                else GOAL_OBJECT if i == scene.goal_index else OBJECT)
        size = fg.Vector3(x=float(obj.size[0]), y=float(obj.size[1]), z=float(obj.size[2]))
        at = pose(x, y, top + obj.height / 2, yaw)
        shape = ({"cubes": [fg.CubePrimitive(pose=at, size=size, color=color(rgba))]}
                 if obj.shape == "box" else
                 {"cylinders": [fg.CylinderPrimitive(pose=at, size=size, bottom_scale=1.0,
                                                     top_scale=1.0, color=color(rgba))]})
        entities.append(entity(f"{prefix}/{obj.name}", **shape))
    return entities


def arm_entity(scene: Scene, q: np.ndarray) -> fg.SceneEntity:
    """The arm at configuration `q` (rad), drawn from its contact shapes."""
    robot = scene.robot
    spheres, cylinders, cubes = [], [], []
    for shape, transform in zip(robot.config.contact_shapes, robot.shape_poses(q),
                                strict=True):
        if shape.kind == "sphere":
            d = 2 * shape.dims[0]
            spheres.append(fg.SpherePrimitive(pose=matrix_pose(transform),
                                              size=fg.Vector3(x=d, y=d, z=d),
                                              color=color(ARM)))
        elif shape.kind == "box":
            cubes.append(fg.CubePrimitive(pose=matrix_pose(transform),
                                          size=fg.Vector3(x=shape.dims[0], y=shape.dims[1],
                                                          z=shape.dims[2]),
                                          color=color(ARM)))
        else:                                  # capsule or cylinder: along the shape's z axis
            radius, length = shape.dims
            cylinders.append(fg.CylinderPrimitive(
                pose=matrix_pose(transform), size=fg.Vector3(x=2 * radius, y=2 * radius,
                                                             z=length),
                bottom_scale=1.0, top_scale=1.0, color=color(ARM)))
            if shape.kind == "capsule":
                for end in (-0.5 * length, 0.5 * length):
                    cap = transform.copy()
                    cap[:3, 3] = transform[:3, 3] + end * transform[:3, 2]
                    spheres.append(fg.SpherePrimitive(
                        pose=matrix_pose(cap), size=fg.Vector3(x=2 * radius, y=2 * radius,
                                                               z=2 * radius),
                        color=color(ARM)))
    return entity("arm", spheres=spheres, cylinders=cylinders, cubes=cubes)


def scene_update(scene: Scene, q: np.ndarray | None = None) -> fg.SceneUpdate:
    """The table, the obstacles, the objects at their poses, the goal region (a disc on the
    table) and the arm at `q` (default the scene's start)."""
    table, top = scene.table, scene.table.height
    entities = [entity("table", cubes=[fg.CubePrimitive(
        pose=pose(table.center[0], table.center[1], top - TABLE_THICKNESS / 2),
        size=fg.Vector3(x=float(table.size[0]), y=float(table.size[1]), z=TABLE_THICKNESS),
        color=color(GREY))])]
    for box in scene.obstacles:
        entities.append(entity(f"obstacle/{box.name}", cubes=[fg.CubePrimitive(
            pose=pose(box.pose[0], box.pose[1], top + box.height / 2, box.pose[2]),
            size=fg.Vector3(x=float(box.size[0]), y=float(box.size[1]), z=float(box.size[2])),
            color=color(DARK))]))
    entities += object_entities(scene, scene.object_poses)
    d = 2 * scene.goal.radius
    entities.append(entity("goal", cylinders=[fg.CylinderPrimitive(
        pose=pose(scene.goal.position[0], scene.goal.position[1], top + 0.001),
        size=fg.Vector3(x=d, y=d, z=0.002), bottom_scale=1.0, top_scale=1.0,
        color=color(GOAL_REGION))]))
    entities.append(arm_entity(scene, scene.start_configuration if q is None else q))
    return fg.SceneUpdate(entities=entities)


def paths_update(scene: Scene, object_paths: np.ndarray, tool_path: np.ndarray,
                 prefix: str = "plan") -> fg.SceneUpdate:
    """`paths_entities` as one update."""
    return fg.SceneUpdate(entities=paths_entities(scene, object_paths, tool_path, prefix))


def paths_entities(scene: Scene, object_paths: np.ndarray, tool_path: np.ndarray,
                   prefix: str = "plan") -> list[fg.SceneEntity]:
    """Lines: each object's predicted path `object_paths` (T, M, 3) on the table top and the
    tool's path `tool_path` (T, 3)."""
    top = scene.table.height + 0.002
    entities = []
    for i, obj in enumerate(scene.objects):
        track = object_paths[:, i, :2]
        if np.max(np.linalg.norm(track - track[0], axis=1), initial=0.0) < 1e-3:
            continue                              # an object the plan does not move
        entities.append(entity(f"{prefix}/path/{obj.name}", lines=[_line(
            [(x, y, top) for x, y in track],
            GOAL_OBJECT if i == scene.goal_index else OBJECT)]))
    entities.append(entity(f"{prefix}/tool", lines=[_line(tool_path, TOOL)]))
    return entities


def search_update(scene: Scene, goal_positions: np.ndarray, best: np.ndarray | None,
                  iterations: int) -> fg.SceneUpdate:
    """The search so far: the goal object's position at the tree's nodes (points, at most
    SEARCH_POINTS of them), the best node's, and the iteration count as text over the table."""
    top = scene.table.height + 0.003
    step = max(1, len(goal_positions) // SEARCH_POINTS)
    dot = fg.Vector3(x=0.006, y=0.006, z=0.006)
    spheres = [fg.SpherePrimitive(pose=pose(x, y, top), size=dot, color=color(TREE))
               for x, y in goal_positions[::step]]
    if best is not None:
        spheres.append(fg.SpherePrimitive(pose=pose(best[0], best[1], top),
                                          size=fg.Vector3(x=0.02, y=0.02, z=0.02),
                                          color=color(BEST)))
    text = fg.TextPrimitive(pose=pose(scene.table.center[0], scene.table.center[1], top + 0.3),
                            billboard=True, font_size=14.0, scale_invariant=True,
                            color=color(TOOL), text=f"{iterations} iterations")
    return fg.SceneUpdate(entities=[entity("search", spheres=spheres, texts=[text])])


SEARCH_POINTS = 1000
"""The most tree nodes a search update draws (evenly picked)."""


def _line(points, rgba: Sequence[float]) -> fg.LinePrimitive:
    return fg.LinePrimitive(type=fg.LinePrimitiveLineType.LineStrip, thickness=0.004,
                            points=[fg.Point3(x=float(p[0]), y=float(p[1]), z=float(p[2]))
                                    for p in points], color=color(rgba))


def _quaternion(rotation: np.ndarray) -> tuple[float, float, float, float]:
    """(w, x, y, z) of a rotation matrix (Shepperd's method)."""
    m = rotation
    trace = m[0, 0] + m[1, 1] + m[2, 2]
    if trace > 0:
        s = 2.0 * math.sqrt(trace + 1.0)
        return (0.25 * s, (m[2, 1] - m[1, 2]) / s, (m[0, 2] - m[2, 0]) / s,
                (m[1, 0] - m[0, 1]) / s)
    i = int(np.argmax(np.diag(m)))
    j, k = (i + 1) % 3, (i + 2) % 3
    s = 2.0 * math.sqrt(1.0 + m[i, i] - m[j, j] - m[k, k])
    q = [0.0, 0.0, 0.0]
    q[i] = 0.25 * s
    q[j] = (m[j, i] + m[i, j]) / s
    q[k] = (m[k, i] + m[i, k]) / s
    return (m[k, j] - m[j, k]) / s, q[0], q[1], q[2]
