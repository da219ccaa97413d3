"""The messages the planner sends, as plain data in the ROS message layouts: dicts whose keys are
the message fields (builtin_interfaces/Time is {"sec", "nanosec"}, a Pose is {"position",
"orientation"}, ...). No ROS import: the MCAP recorder (`io.recording`) encodes these dicts to
CDR directly, and `msg_adapters` turns them into rclpy message objects for the node's
publishers (`msg_adapters.from_plain`). One builder per message, so the recording and the topics
say the same thing.

Frames and units: poses in the planning frame, m and rad; times as {"sec", "nanosec"}.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from fractions import Fraction
from typing import Any

import numpy as np

from rearrangement_planner.model.scene import Scene
from rearrangement_planner.planning.requests.trajectory import Trajectory

Plain = dict[str, Any]
_NANOSECONDS = 1_000_000_000

# visualization_msgs/Marker constants
CUBE, SPHERE, CYLINDER, LINE_STRIP = 1, 2, 3, 4
ADD, DELETEALL = 0, 3

TABLE_THICKNESS = 0.02
"""Drawn thickness of the table top below `table.height`, m."""
GOAL_DISC_THICKNESS = 0.004
"""Thickness of the goal disc lying on the table, m."""
LINE_WIDTH = 0.005
"""Width of the path line strips, m."""
PATH_LIFT = 0.003
"""Height of the object paths above the table top (so they are not hidden in it), m."""

_TABLE = (0.55, 0.45, 0.35, 1.0)
_OBSTACLE = (0.4, 0.4, 0.4, 1.0)
_OBJECT = (0.2, 0.45, 0.85, 1.0)
_GOAL_OBJECT = (0.9, 0.5, 0.1, 1.0)
_GOAL = (0.1, 0.8, 0.2, 0.35)
_EE_PATH = (0.9, 0.1, 0.1, 1.0)
_OBJECT_PATH = (0.2, 0.2, 0.9, 0.8)


def time(ns: int = 0) -> Plain:
    """builtin_interfaces/Time of `ns` nanoseconds."""
    return {"sec": int(ns) // _NANOSECONDS, "nanosec": int(ns) % _NANOSECONDS}


def duration(t: float) -> Plain:
    """`t` (s, >= 0) as a builtin_interfaces/Duration rounded to the nearest nanosecond, with
    nanosec < 1e9. Exact: the float is converted to a Fraction (exactly its binary value)
    before rounding, so 1.9999999999 s becomes (2 s, 0 ns), never (1 s, 1e9 ns)."""
    sec, nanosec = divmod(round(Fraction(t) * _NANOSECONDS), _NANOSECONDS)
    return {"sec": sec, "nanosec": nanosec}


def nanoseconds(t: Mapping[str, int]) -> int:
    return t["sec"] * _NANOSECONDS + t["nanosec"]


def header(frame_id: str, stamp: Plain | None = None) -> Plain:
    return {"stamp": stamp if stamp is not None else time(), "frame_id": frame_id}


def yaw_to_quaternion(yaw: float) -> Plain:
    """The rotation about z by `yaw` (rad) as a geometry_msgs/Quaternion."""
    return {"x": 0.0, "y": 0.0, "z": math.sin(0.5 * yaw), "w": math.cos(0.5 * yaw)}


def pose(x: float, y: float, z: float, yaw: float = 0.0) -> Plain:
    return {"position": point(x, y, z), "orientation": yaw_to_quaternion(float(yaw))}


def point(x: float, y: float, z: float) -> Plain:
    return {"x": float(x), "y": float(y), "z": float(z)}


def joint_state(q: Sequence[float] | np.ndarray, joint_names: Sequence[str],
                stamp: Plain | None = None) -> Plain:
    """sensor_msgs/JointState with the positions `q` (rad) of `joint_names`."""
    q = np.asarray(q, dtype=float)
    if q.shape != (len(joint_names),):
        raise ValueError(f"q has shape {q.shape}, expected ({len(joint_names)},): one position "
                         f"per joint name")
    return {"header": header("", stamp), "name": list(joint_names),
            "position": [float(v) for v in q]}


def pose_array(objects: np.ndarray, frame: str, z: Sequence[float] | np.ndarray | None = None,
               stamp: Plain | None = None) -> Plain:
    """geometry_msgs/PoseArray of the planar poses `objects` (M, 3) (x, y, yaw); `z` gives each
    pose's height (m), default 0."""
    objects = np.asarray(objects, dtype=float)
    if objects.size == 0:
        objects = objects.reshape(0, 3)
    if objects.ndim != 2 or objects.shape[1] != 3:
        raise ValueError(f"objects has shape {objects.shape}, expected (M, 3): x, y, yaw")
    heights = np.zeros(len(objects)) if z is None else np.asarray(z, dtype=float)
    if heights.shape != (len(objects),):
        raise ValueError(f"z has shape {heights.shape}, expected ({len(objects)},): one height "
                         f"per object")
    return {"header": header(frame, stamp),
            "poses": [pose(x, y, h, yaw) for (x, y, yaw), h in zip(objects, heights,
                                                                   strict=True)]}


def goal_pose(xy: Sequence[float] | np.ndarray, frame: str, z: float = 0.0,
              stamp: Plain | None = None) -> Plain:
    """geometry_msgs/PoseStamped at the goal point `xy` (m), height `z`, identity rotation."""
    xy = np.asarray(xy, dtype=float)
    if xy.shape != (2,):
        raise ValueError(f"xy has shape {xy.shape}, expected (2,): x, y")
    return {"header": header(frame, stamp), "pose": pose(xy[0], xy[1], z)}


def joint_trajectory(trajectory: Trajectory) -> Plain:
    """The controller command of docs/design.md (trajectory_msgs/JointTrajectory): header.stamp zero
    ("start now"), empty frame_id, positions and velocities on every point, time_from_start
    rounded to the nanosecond (ValueError if two points round to the same time)."""
    points: list[Plain] = [
        {"positions": [float(a) for a in q], "velocities": [float(a) for a in v],
         "time_from_start": duration(float(t))}
        for t, q, v in zip(trajectory.times, trajectory.positions, trajectory.velocities,
                           strict=True)]
    for i in range(1, len(points)):
        if nanoseconds(points[i]["time_from_start"]) \
                <= nanoseconds(points[i - 1]["time_from_start"]):
            raise ValueError(f"points {i - 1} and {i} are less than 1 ns apart "
                             f"({trajectory.times[i - 1]!r} s, {trajectory.times[i]!r} s); "
                             f"time_from_start could not strictly increase")
    return {"header": header(""), "joint_names": list(trajectory.joint_names), "points": points}


def _marker(head: Plain, ns: str, marker_id: int, kind: int, at: Plain,
            scale: Sequence[float] | np.ndarray, color: Sequence[float]) -> Plain:
    return {"header": head, "ns": ns, "id": marker_id, "type": kind, "action": ADD, "pose": at,
            "scale": dict(zip("xyz", map(float, scale), strict=True)),
            "color": dict(zip("rgba", color, strict=True))}


def _line_strip(head: Plain, ns: str, marker_id: int, points: np.ndarray,
                color: Sequence[float]) -> Plain:
    """A LINE_STRIP through `points` (N, 3) (m); the marker pose is the identity."""
    marker = _marker(head, ns, marker_id, LINE_STRIP, pose(0.0, 0.0, 0.0),
                     (LINE_WIDTH, 0.0, 0.0), color)
    marker["points"] = [point(x, y, z) for x, y, z in points]
    return marker


def _checked_paths(scene: Scene, object_paths: np.ndarray | None, ee_path: np.ndarray | None
                   ) -> tuple[np.ndarray | None, np.ndarray | None]:
    if object_paths is not None:
        object_paths = np.asarray(object_paths, dtype=float)
        if object_paths.ndim != 3 or object_paths.shape[1:] != (len(scene.objects), 3):
            raise ValueError(f"object_paths has shape {object_paths.shape}, expected "
                             f"(T, {len(scene.objects)}, 3): poses (x, y, yaw) of every object")
    if ee_path is not None:
        ee_path = np.asarray(ee_path, dtype=float)
        if ee_path.ndim != 2 or ee_path.shape[1] != 3:
            raise ValueError(f"ee_path has shape {ee_path.shape}, expected (N, 3): tool "
                             f"positions x, y, z")
    return object_paths, ee_path


def plan_markers(scene: Scene, object_paths: np.ndarray | None, ee_path: np.ndarray | None,
                 frame: str, stamp: Plain | None = None) -> Plain:
    """visualization_msgs/MarkerArray of `scene` and a plan in it (docs/design.md `~/markers`).

    One namespace per kind of thing, so each can be toggled in RViz: "table", "obstacles",
    "objects", "goal", "ee_path" and "object_paths"; the array starts with a DELETEALL marker
    so the markers of an earlier plan vanish. object_paths: (T, M, 3) predicted object poses
    along the plan; the objects are drawn at their final poses, or at the scene's when None.
    ee_path: (N, 3) tool positions (m), or None. Paths of fewer than two points draw no line.
    """
    object_paths, ee_path = _checked_paths(scene, object_paths, ee_path)
    head = header(frame, stamp)
    table, top = scene.table, scene.table.height
    poses = object_paths[-1] if object_paths is not None and len(object_paths) \
        else scene.object_poses
    markers = [{"header": head, "ns": "", "id": 0, "action": DELETEALL},
               _marker(head, "table", 0, CUBE,
                       pose(table.center[0], table.center[1], top - 0.5 * TABLE_THICKNESS),
                       (table.size[0], table.size[1], TABLE_THICKNESS), _TABLE)]
    for i, box in enumerate(scene.obstacles):
        x, y, yaw = box.pose
        markers.append(_marker(head, "obstacles", i, CUBE, pose(x, y, top + 0.5 * box.height,
                                                                yaw), box.size, _OBSTACLE))
    for i, (obj, (x, y, yaw)) in enumerate(zip(scene.objects, poses, strict=True)):
        markers.append(_marker(head, "objects", i, CYLINDER if obj.shape == "cylinder" else CUBE,
                               pose(x, y, top + 0.5 * obj.height, yaw), obj.size,
                               _GOAL_OBJECT if i == scene.goal_index else _OBJECT))
    goal = scene.goal
    markers.append(_marker(head, "goal", 0, CYLINDER,
                           pose(goal.position[0], goal.position[1],
                                top + 0.5 * GOAL_DISC_THICKNESS),
                           (2.0 * goal.radius, 2.0 * goal.radius, GOAL_DISC_THICKNESS), _GOAL))
    if ee_path is not None and len(ee_path) >= 2:
        markers.append(_line_strip(head, "ee_path", 0, ee_path, _EE_PATH))
    if object_paths is not None and len(object_paths) >= 2:
        for i in range(object_paths.shape[1]):
            xy = object_paths[:, i, :2]
            points = np.column_stack([xy, np.full(len(xy), top + PATH_LIFT)])
            markers.append(_line_strip(head, "object_paths", i, points, _OBJECT_PATH))
    return {"markers": markers}
