"""Symmetric conversions between the node's messages (docs/design.md) and the core's types.

Each `x_to_msg` / `msg_to_x` pair round-trips: `msg_to_x(x_to_msg(x))` gives back `x` (angles
wrapped to (-pi, pi], times to the nanosecond). The `msg_to_x` direction reads untrusted input
and rejects anything unusable with one `InputError` whose `field` names the offending entry
(``joint_states.position[joint3]``, ``object_poses.poses[2].orientation``) and whose
`problem` says what is wrong and what would be right. The `x_to_msg` direction takes the core's
own values; a wrongly shaped one is a programming error and raises `ValueError`.

Frames and units: poses are in the planning frame (the robot base frame, docs/design.md); metres,
radians, seconds. An object's planar pose (x, y, yaw) is the pose of its centre; the yaw is a
rotation about the frame's z axis.
"""

from __future__ import annotations

import math
import sys
from collections.abc import Sequence
from fractions import Fraction

import numpy as np
from builtin_interfaces.msg import Duration, Time
from geometry_msgs.msg import PoseArray, PoseStamped, Quaternion
from sensor_msgs.msg import JointState
from std_msgs.msg import Header
from trajectory_msgs.msg import JointTrajectory

from rearrangement_planner.io import messages
from rearrangement_planner.model.errors import InputError, ObjectTilted
from rearrangement_planner.planning.requests.trajectory import Trajectory

from .plain import from_plain, time_to_plain

_NANOSECONDS = 1_000_000_000
_MIN_QUATERNION_NORM = 1e-6


# --------------------------------------------------------------------------------------------
# Small pieces
# --------------------------------------------------------------------------------------------


def _header(frame_id: str, stamp: Time | None) -> Header:
    return Header(stamp=stamp if stamp is not None else Time(), frame_id=frame_id)


def _finite(*values: float) -> bool:
    return all(math.isfinite(v) for v in values)


def _listing(names: Sequence[str], limit: int = 10) -> str:
    """At most `limit` of `names`, each cut to 40 characters: an error names the input, it does
    not copy it."""
    shown = ", ".join(n if len(n) <= 40 else f"{n[:40]}..." for n in names[:limit])
    more = f" and {len(names) - limit} more" if len(names) > limit else ""
    return f"{shown}{more}" if names else "none"


def _wrap(angle: float) -> float:
    """`angle` (rad) wrapped to (-pi, pi]."""
    angle = math.remainder(angle, 2.0 * math.pi)  # exact, in [-pi, pi]
    return math.pi if angle <= -math.pi else angle


def yaw_to_quaternion(yaw: float) -> Quaternion:
    """The unit quaternion of a rotation by `yaw` (rad) about z: (0, 0, sin(yaw/2), cos(yaw/2))."""
    return from_plain(messages.yaw_to_quaternion(yaw), Quaternion)


def _check_frame(frame_id: str, planning_frame: str, field: str, what: str) -> None:
    if frame_id == planning_frame:
        return
    got = "is empty" if not frame_id else f"is '{frame_id}'"
    raise InputError(field, f"{got}; {what} must be given in the planning frame "
                            f"'{planning_frame}' (transform them first)")


def _duration(t: float) -> Duration:
    """`t` (s, >= 0) as a Duration rounded to the nearest nanosecond, with nanosec < 1e9.

    Exact: the float is converted to a Fraction (exactly its binary value) before rounding, so
    no product t * 1e9 rounds first; 1.9999999999 s becomes (2 s, 0 ns), never (1 s, 1e9 ns).
    """
    sec, nanosec = divmod(round(Fraction(t) * _NANOSECONDS), _NANOSECONDS)
    return Duration(sec=sec, nanosec=nanosec)


def _seconds(d: Duration) -> float:
    return d.sec + d.nanosec * 1e-9


# --------------------------------------------------------------------------------------------
# Joint states
# --------------------------------------------------------------------------------------------


def joint_state_to_configuration(msg: JointState, joint_names: Sequence[str]) -> np.ndarray:
    """The configuration q (n,) (rad) of the planning joints `joint_names`, taken from `msg` by
    name; other joints in `msg` are ignored (docs/design.md "The ROS 2 node")."""
    names = list(msg.name)
    positions = list(msg.position)
    if len(positions) != len(names):
        raise InputError("joint_states.position",
                         f"has {len(positions)} values for {len(names)} names in "
                         f"joint_states.name; give one position per name, in the same order")
    index: dict[str, int] = {}
    for i, name in enumerate(names):
        if name in index and name in joint_names:
            raise InputError("joint_states.name",
                             f"joint '{name}' appears twice (entries {index[name]} and {i}); "
                             f"give each joint once")
        index.setdefault(name, i)
    missing = [name for name in joint_names if name not in index]
    if missing:
        raise InputError("joint_states.name",
                         f"planning joint{'s' if len(missing) > 1 else ''} "
                         f"{', '.join(repr(n) for n in missing)} missing; the planning joints "
                         f"are {', '.join(joint_names)} (got {_listing(names)})")
    q = np.array([positions[index[name]] for name in joint_names], dtype=float)
    for name, value in zip(joint_names, q, strict=True):
        if not math.isfinite(value):
            raise InputError(f"joint_states.position[{name}]",
                             f"is {value}; joint positions must be finite numbers (rad or m)")
    return q


def configuration_to_joint_state(q: Sequence[float] | np.ndarray, joint_names: Sequence[str],
                                 stamp: Time | None = None) -> JointState:
    """A JointState with the positions `q` (rad) of `joint_names` (no velocities or efforts);
    stamp zero unless given."""
    return from_plain(messages.joint_state(q, joint_names, time_to_plain(stamp)), JointState)


# --------------------------------------------------------------------------------------------
# Object poses
# --------------------------------------------------------------------------------------------


def pose_array_to_objects(msg: PoseArray, object_ids: Sequence[str], planning_frame: str,
                          max_tilt: float = 0.05) -> np.ndarray:
    """The planar object poses (M, 3) (x, y, yaw) in the planning frame (m, rad, yaw in
    (-pi, pi]); the i-th pose of `msg` belongs to `object_ids[i]` (docs/design.md). The poses' z is
    ignored (objects stand on the table); an object tilted more than `max_tilt` (rad) from
    upright is rejected (`ObjectTilted`), because the planner models only upright prisms
    (docs/design.md).
    """
    _check_frame(msg.header.frame_id, planning_frame, "object_poses.header.frame_id",
                 "object poses")
    if len(msg.poses) != len(object_ids):
        raise InputError("object_poses.poses",
                         f"has {len(msg.poses)} poses for {len(object_ids)} objects "
                         f"({', '.join(object_ids)}); give one pose per object id, in the order "
                         f"of the parameter object_ids")
    objects = np.empty((len(object_ids), 3))
    for i, (pose, object_id) in enumerate(zip(msg.poses, object_ids, strict=True)):
        field = f"object_poses.poses[{i}]"
        p, o = pose.position, pose.orientation
        if not _finite(p.x, p.y, p.z):
            raise InputError(f"{field}.position",
                             f"of object '{object_id}' is ({p.x}, {p.y}, {p.z}); positions must "
                             f"be finite numbers (m)")
        if not _finite(o.x, o.y, o.z, o.w):
            raise InputError(f"{field}.orientation",
                             f"of object '{object_id}' is ({o.x}, {o.y}, {o.z}, {o.w}); "
                             f"quaternions must be finite numbers")
        norm = math.hypot(o.x, o.y, o.z, o.w)       # no overflow for huge components
        if not math.isfinite(norm):
            raise InputError(f"{field}.orientation",
                             f"of object '{object_id}' is too large to normalise (norm beyond "
                             f"{sys.float_info.max:.3g}); give a unit quaternion")
        if norm <= _MIN_QUATERNION_NORM:
            raise InputError(f"{field}.orientation",
                             f"of object '{object_id}' is a zero quaternion (norm {norm:.3g}); "
                             f"give a unit quaternion (x=y=z=0, w=1 for no rotation)")
        x, y, z, w = o.x / norm, o.y / norm, o.z / norm, o.w / norm
        # Swing-twist split q = swing * twist (twist about z, swing about a horizontal axis):
        # |(x, y)| = sin(theta/2), |(z, w)| = cos(theta/2), theta = the angle between the
        # object's z axis and the frame's z axis.
        tilt = 2.0 * math.atan2(math.hypot(x, y), math.hypot(z, w))
        if tilt > max_tilt:
            raise ObjectTilted(f"{field}.orientation", object_id, tilt, max_tilt)
        # Yaw = heading of the object's x axis projected on the table: atan2(R10, R00) of the
        # rotation matrix of a unit quaternion (the z of a ZYX Euler decomposition, as tf2).
        yaw = math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))
        objects[i] = (p.x, p.y, _wrap(yaw))
    return objects


def objects_to_pose_array(objects: np.ndarray, planning_frame: str,
                          z: Sequence[float] | np.ndarray | None = None,
                          stamp: Time | None = None) -> PoseArray:
    """A PoseArray of the planar poses `objects` (M, 3) (x, y, yaw) in `planning_frame`; `z`
    gives each pose's height (m), default 0."""
    return from_plain(messages.pose_array(objects, planning_frame, z, time_to_plain(stamp)),
                      PoseArray)


# --------------------------------------------------------------------------------------------
# Goal
# --------------------------------------------------------------------------------------------


def pose_stamped_to_goal(msg: PoseStamped, planning_frame: str) -> np.ndarray:
    """The goal point (2,) (x, y) (m) in the planning frame. The pose's z and orientation are
    ignored: the goal is a point on the table (docs/design.md "The world model")."""
    _check_frame(msg.header.frame_id, planning_frame, "goal.header.frame_id", "goal poses")
    p = msg.pose.position
    if not _finite(p.x, p.y, p.z):
        raise InputError("goal.pose.position",
                         f"is ({p.x}, {p.y}, {p.z}); the goal point must be finite numbers (m)")
    return np.array([p.x, p.y], dtype=float)


def goal_to_pose_stamped(xy: Sequence[float] | np.ndarray, planning_frame: str, z: float = 0.0,
                         stamp: Time | None = None) -> PoseStamped:
    """A PoseStamped at the goal point `xy` (m) and height `z` (m), identity orientation."""
    return from_plain(messages.goal_pose(xy, planning_frame, z, time_to_plain(stamp)),
                      PoseStamped)


# --------------------------------------------------------------------------------------------
# Trajectory
# --------------------------------------------------------------------------------------------


def trajectory_to_msg(trajectory: Trajectory) -> JointTrajectory:
    """The controller command of docs/design.md: header.stamp zero ("start now"), empty frame_id,
    positions and velocities on every point, time_from_start rounded to the nanosecond."""
    return from_plain(messages.joint_trajectory(trajectory), JointTrajectory)


def msg_to_trajectory(msg: JointTrajectory) -> Trajectory:
    """The Trajectory of `msg`; every point needs positions and velocities for all joints, and
    time_from_start must start at 0 and strictly increase."""
    names = tuple(msg.joint_names)
    if len(set(names)) != len(names):
        raise InputError("trajectory.joint_names",
                         f"lists a joint twice ({', '.join(names)}); name each joint once")
    if not msg.points:
        raise InputError("trajectory.points", "is empty; give at least one point")
    times = np.empty(len(msg.points))
    positions = np.empty((len(msg.points), len(names)))
    velocities = np.empty((len(msg.points), len(names)))
    for i, point in enumerate(msg.points):
        field = f"trajectory.points[{i}]"
        for values, out, what in ((point.positions, positions, "positions"),
                                  (point.velocities, velocities, "velocities")):
            if len(values) != len(names):
                raise InputError(f"{field}.{what}",
                                 f"has {len(values)} values for {len(names)} joints; give one "
                                 f"per name in joint_names on every point")
            if not _finite(*values):
                raise InputError(f"{field}.{what}", "must be finite numbers")
            out[i] = values
        d = point.time_from_start
        if not 0 <= d.nanosec < _NANOSECONDS or d.sec < 0:
            raise InputError(f"{field}.time_from_start",
                             f"is ({d.sec} s, {d.nanosec} ns); need sec >= 0 and "
                             f"0 <= nanosec < 1e9")
        times[i] = _seconds(d)
        if i == 0 and times[i] != 0.0:
            raise InputError(f"{field}.time_from_start",
                             f"is {times[i]!r} s; the first point must be at 0 s")
        if i > 0 and times[i] <= times[i - 1]:
            raise InputError(f"{field}.time_from_start",
                             f"is {times[i]!r} s, not after point {i - 1} ({times[i - 1]!r} s); "
                             f"times must strictly increase")
    return Trajectory(names, times, positions, velocities)
