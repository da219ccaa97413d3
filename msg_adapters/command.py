"""The controller command (trajectory_msgs/JointTrajectory) checked and converted to an
`execution.open_loop.Command`, as a joint trajectory controller would accept it."""

from __future__ import annotations

import math

import numpy as np
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

from rearrangement_planner.model.command import Command
from rearrangement_planner.model.errors import InputError
from rearrangement_planner.model.robot import RobotModel


def _seconds(sec: int, nanosec: int) -> float:
    return sec + nanosec * 1e-9


def command_from_msg(msg: JointTrajectory, robot: RobotModel, current: np.ndarray,
                     start_tolerance: float) -> Command:
    """Check a non-empty controller command against the arm and return it as a `Command`.

    Joints may come in any order but must be exactly the planning joints. Points need finite
    positions for every joint (velocities and accelerations are optional, as for
    joint_trajectory_controller, but finite when given), strictly increasing time_from_start
    and positions within the joint limits. header.stamp must be zero ("start now"). A first
    point at time 0 must be within `start_tolerance` (rad, per joint; 0 = no check) of the
    current position `current`, since the arm would have to jump there; a first point later
    than 0 is reached by interpolating from `current`. Raises InputError naming the field
    (``joint_trajectory.points[3].time_from_start``) and the problem.
    """
    expected = list(robot.joint_names)
    _check_header_and_names(msg, expected)
    names = list(msg.joint_names)
    order = [names.index(n) for n in expected]
    count = len(msg.points)
    times = np.empty(count)
    positions = np.empty((count, len(expected)))
    for i, point in enumerate(msg.points):
        positions[i] = _point_positions(point, i, names, order, robot)
        times[i] = _point_time(point, i, times[i - 1] if i > 0 else None)
    return _from_current(times, positions, np.asarray(current, dtype=float), start_tolerance,
                         expected)


def _check_header_and_names(msg: JointTrajectory, expected: list[str]) -> None:
    """header.stamp zero ("start now"); joint names exactly the planning joints, any order."""
    names = list(msg.joint_names)
    stamp = msg.header.stamp
    if stamp.sec != 0 or stamp.nanosec != 0:
        raise InputError("joint_trajectory.header.stamp",
                         f"is {stamp.sec} s {stamp.nanosec} ns; this controller starts "
                         f"trajectories on arrival: send stamp 0 (start now)")
    duplicates = sorted({n for n in names if names.count(n) > 1})
    missing = [n for n in expected if n not in names]
    unknown = [n for n in names if n not in expected]
    problems = [f"{what} {', '.join(which)}" for what, which in
                (("missing", missing), ("unknown", unknown), ("repeated", duplicates)) if which]
    if problems:
        raise InputError("joint_trajectory.joint_names",
                         f"{'; '.join(problems)}; name each of the arm's joints "
                         f"{', '.join(expected)} once (any order)")


def _point_positions(point: JointTrajectoryPoint, i: int, names: list[str], order: list[int],
                     robot: RobotModel) -> np.ndarray:
    """Point i's positions in planning-joint order: one per joint, finite, within the limits;
    velocities and accelerations none or one per joint, finite."""
    where = f"joint_trajectory.points[{i}]"
    if len(point.positions) != len(names):
        raise InputError(f"{where}.positions",
                         f"has {len(point.positions)} values for {len(names)} joint names; "
                         f"give one position per joint")
    for what in ("velocities", "accelerations"):
        values = getattr(point, what)
        if len(values) not in (0, len(names)):
            raise InputError(f"{where}.{what}",
                             f"has {len(values)} values for {len(names)} joint names; give "
                             f"none or one per joint")
        bad = [names[j] for j, v in enumerate(values) if not math.isfinite(v)]
        if bad:
            raise InputError(f"{where}.{what}[{bad[0]}]",
                             f"is {values[names.index(bad[0])]}; must be a finite number")
    q = np.array([point.positions[j] for j in order], dtype=float)
    for name, value, lo, hi in zip(robot.joint_names, q, robot.lower, robot.upper, strict=True):
        if not math.isfinite(value):
            raise InputError(f"{where}.positions[{name}]",
                             f"is {value}; joint positions must be finite numbers (rad)")
        if not lo - 1e-9 <= value <= hi + 1e-9:
            raise InputError(f"{where}.positions[{name}]",
                             f"is {value:.4f} rad, outside the joint limits "
                             f"[{lo:.4f}, {hi:.4f}]")
    return q


def _point_time(point: JointTrajectoryPoint, i: int, previous: float | None) -> float:
    """Point i's time_from_start (s): a valid Duration, after the previous point's."""
    where = f"joint_trajectory.points[{i}]"
    d = point.time_from_start
    if d.sec < 0 or not 0 <= d.nanosec < 1_000_000_000:
        raise InputError(f"{where}.time_from_start",
                         f"is ({d.sec} s, {d.nanosec} ns); need sec >= 0 and "
                         f"0 <= nanosec < 1e9")
    t = _seconds(d.sec, d.nanosec)
    if previous is not None and t <= previous:
        raise InputError(f"{where}.time_from_start",
                         f"is {t:.9f} s, not after point {i - 1} ({previous:.9f} s); times "
                         f"must strictly increase")
    return t


def _from_current(times: np.ndarray, positions: np.ndarray, current: np.ndarray,
                  start_tolerance: float, expected: list[str]) -> Command:
    """The command from the arm's current position: a first point later than 0 is reached by
    interpolating from `current`; one at time 0 must be within `start_tolerance` of it."""
    if times[0] > 0.0:   # reach the first point from where the arm is (joint_trajectory_controller)
        times = np.concatenate([[0.0], times])
        positions = np.vstack([current, positions])
    elif start_tolerance > 0:
        gap = np.abs(positions[0] - current)
        j = int(np.argmax(gap))
        if gap[j] > start_tolerance:
            raise InputError(f"joint_trajectory.points[0].positions[{expected[j]}]",
                             f"is {positions[0, j]:.4f} rad at time 0 but the arm is at "
                             f"{current[j]:.4f} rad ({gap[j]:.4f} rad away, start_tolerance "
                             f"{start_tolerance:g} rad); start the trajectory at the current "
                             f"joint state")
    if len(times) < 2:
        raise InputError("joint_trajectory.points",
                         "has one point at time 0; give a point later than 0 to move to")
    times.setflags(write=False)
    positions.setflags(write=False)
    return Command(times, positions)
