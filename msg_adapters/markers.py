"""RViz markers of a plan (DESIGN §4, the `~/markers` topic).

One namespace per kind of thing, so each can be toggled in RViz: "table", "obstacles",
"objects", "goal", "ee_path" and "object_paths". The array starts with a DELETEALL marker, so
the markers of an earlier plan vanish. Heights follow DESIGN §3: the table's top face is at
`table.height`, and obstacles and objects stand on it.
"""

from __future__ import annotations

import numpy as np
from builtin_interfaces.msg import Time
from geometry_msgs.msg import Point, Pose, Quaternion, Vector3
from std_msgs.msg import ColorRGBA, Header
from visualization_msgs.msg import Marker, MarkerArray

from rearrangement_planner.model.scene import Scene

from .conversions import yaw_to_quaternion

TABLE_THICKNESS = 0.02
"""Drawn thickness of the table top below `table.height`, m."""
GOAL_DISC_THICKNESS = 0.004
"""Thickness of the goal disc lying on the table, m."""
LINE_WIDTH = 0.005
"""Width of the path line strips, m."""
PATH_LIFT = 0.003
"""Height of the object paths above the table top (so they are not hidden in it), m."""

_TABLE = ColorRGBA(r=0.55, g=0.45, b=0.35, a=1.0)
_OBSTACLE = ColorRGBA(r=0.4, g=0.4, b=0.4, a=1.0)
_OBJECT = ColorRGBA(r=0.2, g=0.45, b=0.85, a=1.0)
_GOAL_OBJECT = ColorRGBA(r=0.9, g=0.5, b=0.1, a=1.0)
_GOAL = ColorRGBA(r=0.1, g=0.8, b=0.2, a=0.35)
_EE_PATH = ColorRGBA(r=0.9, g=0.1, b=0.1, a=1.0)
_OBJECT_PATH = ColorRGBA(r=0.2, g=0.2, b=0.9, a=0.8)


def _marker(header: Header, ns: str, marker_id: int, kind: int, pose: Pose, scale: Vector3,
            color: ColorRGBA) -> Marker:
    return Marker(header=header, ns=ns, id=marker_id, type=kind, action=Marker.ADD, pose=pose,
                  scale=scale, color=color)


def _pose(x: float, y: float, z: float, yaw: float = 0.0) -> Pose:
    return Pose(position=Point(x=float(x), y=float(y), z=float(z)),
                orientation=yaw_to_quaternion(float(yaw)))


def _line_strip(header: Header, ns: str, marker_id: int, points: np.ndarray,
                color: ColorRGBA) -> Marker:
    """A LINE_STRIP through `points` (N, 3) (m); the marker pose is the identity."""
    marker = _marker(header, ns, marker_id, Marker.LINE_STRIP,
                     Pose(orientation=Quaternion(w=1.0)), Vector3(x=LINE_WIDTH), color)
    marker.points = [Point(x=float(x), y=float(y), z=float(z)) for x, y, z in points]
    return marker


def plan_markers(scene: Scene, object_paths: np.ndarray | None, ee_path: np.ndarray | None,
                 frame: str, stamp: Time | None = None) -> MarkerArray:
    """The markers of `scene` and a plan in it.

    object_paths: (T, M, 3) predicted object poses (x, y, yaw) along the plan (m, rad), one
    column per scene object; the objects are drawn at their final poses `object_paths[-1]`, or
    at the scene's poses when None. ee_path: (N, 3) tool positions along the plan (m), or None.
    Paths with fewer than two points draw no line. `frame` is the frame of all of it (the
    planning frame).
    """
    header = Header(stamp=stamp if stamp is not None else Time(), frame_id=frame)
    table = scene.table
    top = table.height
    poses = scene.object_poses
    if object_paths is not None:
        object_paths = np.asarray(object_paths, dtype=float)
        if object_paths.ndim != 3 or object_paths.shape[1:] != (len(scene.objects), 3):
            raise ValueError(f"object_paths has shape {object_paths.shape}, expected "
                             f"(T, {len(scene.objects)}, 3): poses (x, y, yaw) of every object")
        if len(object_paths):
            poses = object_paths[-1]
    if ee_path is not None:
        ee_path = np.asarray(ee_path, dtype=float)
        if ee_path.ndim != 2 or ee_path.shape[1] != 3:
            raise ValueError(f"ee_path has shape {ee_path.shape}, expected (N, 3): tool "
                             f"positions x, y, z")

    markers = [Marker(header=header, ns="", id=0, action=Marker.DELETEALL)]
    markers.append(_marker(header, "table", 0, Marker.CUBE,
                           _pose(table.center[0], table.center[1],
                                 top - 0.5 * TABLE_THICKNESS),
                           Vector3(x=float(table.size[0]), y=float(table.size[1]),
                                   z=TABLE_THICKNESS), _TABLE))
    for i, box in enumerate(scene.obstacles):
        x, y, yaw = box.pose
        markers.append(_marker(header, "obstacles", i, Marker.CUBE,
                               _pose(x, y, top + 0.5 * box.height, yaw),
                               Vector3(x=float(box.size[0]), y=float(box.size[1]),
                                       z=float(box.size[2])), _OBSTACLE))
    goal_index = scene.goal_index
    for i, (obj, (x, y, yaw)) in enumerate(zip(scene.objects, poses, strict=True)):
        kind = Marker.CYLINDER if obj.shape == "cylinder" else Marker.CUBE
        markers.append(_marker(header, "objects", i, kind,
                               _pose(x, y, top + 0.5 * obj.height, yaw),
                               Vector3(x=float(obj.size[0]), y=float(obj.size[1]),
                                       z=float(obj.size[2])),
                               _GOAL_OBJECT if i == goal_index else _OBJECT))
    goal = scene.goal
    markers.append(_marker(header, "goal", 0, Marker.CYLINDER,
                           _pose(goal.position[0], goal.position[1],
                                 top + 0.5 * GOAL_DISC_THICKNESS),
                           Vector3(x=2.0 * goal.radius, y=2.0 * goal.radius,
                                   z=GOAL_DISC_THICKNESS), _GOAL))
    if ee_path is not None and len(ee_path) >= 2:
        markers.append(_line_strip(header, "ee_path", 0, ee_path, _EE_PATH))
    if object_paths is not None and len(object_paths) >= 2:
        for i in range(object_paths.shape[1]):
            xy = object_paths[:, i, :2]
            points = np.column_stack([xy, np.full(len(xy), top + PATH_LIFT)])
            markers.append(_line_strip(header, "object_paths", i, points, _OBJECT_PATH))
    return MarkerArray(markers=markers)
