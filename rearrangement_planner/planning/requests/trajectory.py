"""Time parameterization of a joint path for a joint trajectory controller (docs/design.md).

The planner produces a dense path of joint configurations (one per propagation step). A
`joint_trajectory_controller` needs times and velocities on every point: strictly increasing
times from 0, zero velocity at the end, joint velocities within their limits and a tool speed
slow enough for the quasistatic pushing assumption (docs/design.md: objects stop the moment they
are no longer pushed, which needs slow pushing).

Model (a discrete version of time-optimal path parameterization along a piecewise-linear
path, e.g. Kunz & Stilman, RSS 2012, without their corner blends): the path is q(s) with
s ∈ [0, N-1], linear between waypoints (q(k) = q_k, dq/ds = Δq_k = q_{k+1} - q_k on segment k).
The path rate ṡ is chosen at every waypoint, ṡ_k, and varies linearly in time within a segment
(constant path acceleration), so segment k takes

    T_k = 2 / (ṡ_k + ṡ_{k+1})     and has   s̈_k = (ṡ_{k+1}² - ṡ_k²) / 2.

The rates are as large as these bounds allow, with v_max = velocity_scale · joint velocity
limits:
  * joint velocity on each segment:   |Δq_kj| ṡ <= v_max_j          for ṡ at both ends
  * tool speed on each segment:       |Δx_k| ṡ <= max_tool_speed     (Δx_k: FK chord of the tool)
  * tool speed at each waypoint:      |J_lin(q_k) t_k| ṡ_k <= max_tool_speed
  * joint acceleration (optional):    |Δq_kj| |s̈_k| <= a_max_j       (forward-backward passes),
    and at corners |v_{k+1} - v_k| / T_k <= a_max (the reported velocities, differenced)
  * ṡ = 0 at the first and the last waypoint (start and stop at rest).
A segment with both end rates zero (a two-point path) takes a triangular profile: accelerate to
the peak rate at its middle, decelerate to rest, T = 2 / peak.

Reported waypoint velocity: v_k = t_k ṡ_k with the tangent t_k = (Δq_{k-1} + Δq_k) / 2 (the mean
of the left and right derivatives; each |t_kj| <= max(|Δq_{k-1,j}|, |Δq_kj|), so v_k respects the
joint limits too). At a sharp corner of the path (an action switch, a joint reaching its
limit) that mean is small and the path slows there only if an acceleration limit is set, so
set one for execution on hardware. Positions are the waypoints; `Trajectory.sample`
interpolates them linearly in time, like a controller interpolating positions only.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from rearrangement_planner.model.robot import RobotModel
from rearrangement_planner.model.settings import Settings, internal, setting

# Consecutive waypoints closer than this (max over joints, rad) are duplicates: exact repeats,
# or repeats up to rounding, whose segment would take ~0 s and break strictly increasing times.
DUPLICATE_TOLERANCE = 1e-12
MIN_SEGMENT = 1e-6
"""s: the shortest segment a trajectory has. Two waypoints a few nanoradians apart (a step
that rounding left, a re-plan's first step) would otherwise be timed a fraction of a
nanosecond apart, and a JointTrajectory's time_from_start, in whole nanoseconds, could not
strictly increase (a re-plan of the closed loop once ended INTERNAL so)."""


def _readonly(a: np.ndarray) -> np.ndarray:
    a = np.array(a, dtype=float)
    a.setflags(write=False)
    return a


@dataclass(frozen=True)
class Trajectory:
    """A timed joint trajectory, as sent to a joint trajectory controller.

    joint_names: the planning joints, in the column order of positions and velocities.
    times: (N,) time from start of every point (s), strictly increasing, times[0] = 0.
    positions: (N, n) joint positions (rad). velocities: (N, n) joint velocities (rad/s).
    Arrays are stored read-only.
    """

    joint_names: tuple[str, ...]
    times: np.ndarray
    positions: np.ndarray
    velocities: np.ndarray

    def __post_init__(self) -> None:
        object.__setattr__(self, "joint_names", tuple(self.joint_names))
        for name in ("times", "positions", "velocities"):
            object.__setattr__(self, name, _readonly(getattr(self, name)))
        n, count = len(self.joint_names), self.times.shape[0] if self.times.ndim == 1 else -1
        if count < 1:
            raise ValueError(f"times must be a non-empty 1-D array, got shape {self.times.shape}")
        for name in ("positions", "velocities"):
            shape = getattr(self, name).shape
            if shape != (count, n):
                raise ValueError(f"{name} has shape {shape}, expected ({count}, {n}): one row per "
                                 f"time, one column per joint in joint_names")
        if self.times[0] != 0.0:
            raise ValueError(f"times must start at 0, got {self.times[0]}")
        if count > 1 and not np.all(np.diff(self.times) > 0):
            raise ValueError("times must be strictly increasing")
        if not (np.all(np.isfinite(self.positions)) and np.all(np.isfinite(self.velocities))):
            raise ValueError("positions and velocities must be finite")

    def __len__(self) -> int:
        return int(self.times.shape[0])

    @property
    def duration(self) -> float:
        """Time of the last point (s)."""
        return float(self.times[-1])

    def sample(self, t: float) -> np.ndarray:
        """Joint positions at time t (s), linearly interpolated between points; clamped to the
        first point before 0 and to the last after `duration`."""
        if t <= 0.0:
            return self.positions[0].copy()
        if t >= self.duration:
            return self.positions[-1].copy()
        i = int(np.searchsorted(self.times, t, side="right")) - 1
        t0, t1 = self.times[i], self.times[i + 1]
        alpha = (t - t0) / (t1 - t0)
        return (1.0 - alpha) * self.positions[i] + alpha * self.positions[i + 1]


@dataclass(frozen=True)
class TimingOptions(Settings):
    """Limits of the time parameterization."""

    velocity_scale: float = setting(0.5, low=0.01, high=1.0)
    """Fraction of each joint's velocity limit (URDF) the trajectory may use."""
    max_tool_speed: float = setting(0.1, low=0.001, high=10.0)
    """Largest tool (end-effector) speed, m/s: keeps pushing slow enough to be quasistatic."""
    max_joint_acceleration: float = setting(0.0, low=0.0, high=100.0)
    """Joint acceleration limit, rad/s^2, the same for every joint; 0 = none (the path rate
    still starts and ends at zero)."""
    joint_accelerations: tuple[float, ...] = internal(())
    """One acceleration limit per joint, rad/s^2, in place of `max_joint_acceleration` (for a
    caller of `time_parameterize`; no node parameter sets it)."""

    def __post_init__(self) -> None:
        super().__post_init__()
        if self.joint_accelerations and not all(a > 0.0 for a in self.joint_accelerations):
            raise ValueError(f"joint_accelerations must be positive (rad/s^2), got "
                             f"{self.joint_accelerations}")

    def acceleration_limits(self, nq: int) -> np.ndarray | None:
        """The acceleration limit of each of the `nq` joints, rad/s^2, or None for none."""
        if self.joint_accelerations:
            return np.broadcast_to(np.asarray(self.joint_accelerations, dtype=float), (nq,))
        if self.max_joint_acceleration > 0.0:
            return np.full(nq, self.max_joint_acceleration)
        return None


def remove_duplicates(path: np.ndarray, tol: float = DUPLICATE_TOLERANCE) -> np.ndarray:
    """The path without waypoints that repeat the previous kept one (max |Δq| <= tol)."""
    keep = [0]
    for k in range(1, path.shape[0]):
        if np.max(np.abs(path[k] - path[keep[-1]])) > tol:
            keep.append(k)
    return path[keep]


def time_parameterize(
    robot: RobotModel, path: np.ndarray, options: TimingOptions | None = None
) -> Trajectory:
    """Times and velocities for a dense joint path (N x nq waypoints, rad), within the joint
    velocity limits, the tool speed limit and the optional acceleration limit (module
    docstring). Duplicate consecutive waypoints are dropped; a path of one distinct waypoint
    gives a one-point trajectory of duration 0."""
    options = TimingOptions() if options is None else options
    path = np.asarray(path, dtype=float)
    if path.ndim != 2 or path.shape[0] < 1 or path.shape[1] != robot.nq:
        raise ValueError(f"path has shape {path.shape}, expected (N, {robot.nq}) with N >= 1: "
                         f"one row per waypoint, columns {list(robot.joint_names)}")
    if not np.all(np.isfinite(path)):
        raise ValueError("path contains NaN or infinite joint positions")
    positions = remove_duplicates(path)
    count = positions.shape[0]
    if count == 1:
        return Trajectory(robot.joint_names, np.zeros(1), positions, np.zeros_like(positions))

    steps = np.diff(positions, axis=0)  # Δq_k, (N-1, nq)
    segment_limits = _segment_rate_limits(robot, positions, steps, options)
    rates = _path_rates(robot, positions, steps, segment_limits, options)
    durations = np.empty(count - 1)
    for k in range(count - 1):
        if rates[k] + rates[k + 1] > 0.0:
            durations[k] = 2.0 / (rates[k] + rates[k + 1])
        else:  # rest to rest within one segment: triangular profile, peak² = 2 α · 1/2
            peak = min(segment_limits[k],
                       math.sqrt(_segment_acceleration_limit(steps[k], options, robot.nq)))
            durations[k] = 2.0 / peak
    times = np.concatenate([[0.0], np.cumsum(np.maximum(durations, MIN_SEGMENT))])

    velocities = np.zeros_like(positions)
    tangents = 0.5 * (steps[:-1] + steps[1:])  # interior waypoints 1 .. N-2
    velocities[1:-1] = tangents * rates[1:-1, None]
    return Trajectory(robot.joint_names, times, positions, velocities)


def _segment_rate_limits(robot: RobotModel, positions: np.ndarray, steps: np.ndarray,
                         options: TimingOptions) -> np.ndarray:
    """Largest path rate ṡ (1/s) on each segment from the joint velocity and tool chord limits."""
    vmax = options.velocity_scale * robot.velocity_limits
    tool = np.array([robot.tool_pose(q)[:3, 3] for q in positions])
    chords = np.linalg.norm(np.diff(tool, axis=0), axis=1)
    with np.errstate(divide="ignore"):
        joint = np.min(vmax / np.abs(steps), axis=1)
        tool_rate = options.max_tool_speed / chords  # inf for a pure tool rotation
    return np.minimum(joint, tool_rate)


def _segment_acceleration_limit(step: np.ndarray, options: TimingOptions, nq: int) -> float:
    """Largest |s̈| (1/s²) on a segment with Δq = step: min_j a_max_j / |Δq_j| (inf if none)."""
    amax = options.acceleration_limits(nq)
    if amax is None:
        return math.inf
    with np.errstate(divide="ignore"):
        return float(np.min(amax / np.abs(step)))


def _path_rates(robot: RobotModel, positions: np.ndarray, steps: np.ndarray,
                segment_limits: np.ndarray, options: TimingOptions) -> np.ndarray:
    """ṡ_k at every waypoint (1/s): zero at both ends; the segment bounds on both sides and the
    tool speed at the waypoint; then the acceleration bound by a forward pass
    (ṡ_{k+1}² <= ṡ_k² + 2 α_k: accelerating from rest) and a backward pass
    (ṡ_k² <= ṡ_{k+1}² + 2 α_k: stopping at rest), α_k the path acceleration bound of segment k
    (Δs = 1 per segment)."""
    count = positions.shape[0]
    rates = np.zeros(count)
    rates[1:-1] = np.minimum(segment_limits[:-1], segment_limits[1:])
    tangents = 0.5 * (steps[:-1] + steps[1:])
    for k in range(1, count - 1):  # tool speed at the waypoint itself: |J_lin(q_k) t_k| ṡ_k
        jac = robot.frame_jacobian(positions[k], robot.tool_frame_id)
        speed = float(np.linalg.norm(jac[:3] @ tangents[k - 1]))
        if speed > 0.0:
            rates[k] = min(rates[k], options.max_tool_speed / speed)
    if options.acceleration_limits(robot.nq) is not None:
        alpha = [_segment_acceleration_limit(step, options, robot.nq) for step in steps]
        for k in range(count - 1):
            rates[k + 1] = min(rates[k + 1], math.sqrt(rates[k] ** 2 + 2.0 * alpha[k]))
        for k in range(count - 2, -1, -1):
            rates[k] = min(rates[k], math.sqrt(rates[k + 1] ** 2 + 2.0 * alpha[k]))
        rates = _limit_corner_accelerations(steps, rates, options, robot.nq)
    return rates


def _limit_corner_accelerations(steps: np.ndarray, rates: np.ndarray, options: TimingOptions,
                                nq: int, max_rounds: int = 200) -> np.ndarray:
    """Slow down where the reported velocities, differenced over time, exceed the acceleration
    limit: a_k = (v_{k+1} - v_k) / T_k = (t_{k+1} ṡ_{k+1} - t_k ṡ_k)(ṡ_k + ṡ_{k+1}) / 2.

    The passes above bound the path acceleration; at a corner of the path the direction t_k
    turns too, which adds |t_{k+1} - t_k| ṡ² (the centripetal term of time-optimal path
    parameterization). Scaling both end rates of segment k by f scales a_k by f², so each
    violating segment gets f = sqrt(a_max / |a_k|); a neighbour may then need a round of its
    own. After `max_rounds`, all rates are scaled by one common factor, which bounds every
    a_k at once."""
    amax = options.acceleration_limits(nq)
    assert amax is not None
    tangents = np.zeros((rates.size, nq))
    tangents[1:-1] = 0.5 * (steps[:-1] + steps[1:])
    rates = rates.copy()

    def excess() -> np.ndarray:  # max_j |a_kj| / a_max_j per segment
        velocities = tangents * rates[:, None]
        accel = np.diff(velocities, axis=0) * (0.5 * (rates[:-1] + rates[1:]))[:, None]
        return np.max(np.abs(accel) / amax, axis=1)

    for _ in range(max_rounds):
        ratio = excess()
        bad = ratio > 1.0
        if not bad.any():
            return rates
        factor = np.ones(rates.size)
        shrink = 1.0 / np.sqrt(ratio[bad])
        idx = np.nonzero(bad)[0]
        np.minimum.at(factor, idx, shrink)
        np.minimum.at(factor, idx + 1, shrink)
        rates *= factor
    worst = float(np.max(excess()))
    if worst > 1.0:
        rates /= math.sqrt(worst)
    return rates


SPLICE_PAUSE = 0.5
"""s the arm rests between two spliced trajectories: the objects come to rest, as the closed
loop lets them before it observes (`retreat`, `judging.mend`)."""


def cut(trajectory: Trajectory, point: int) -> Trajectory:
    """The trajectory up to and including point `point`, the arm at rest there (its velocity
    zeroed, so that a controller's spline stops at the point instead of running on)."""
    if not 0 <= point < len(trajectory):
        raise ValueError(f"point {point} is not one of the trajectory's {len(trajectory)}")
    velocities = trajectory.velocities[:point + 1].copy()
    velocities[-1] = 0.0
    return Trajectory(trajectory.joint_names, trajectory.times[:point + 1],
                      trajectory.positions[:point + 1], velocities)


def splice(first: Trajectory, second: Trajectory, pause: float = SPLICE_PAUSE) -> Trajectory:
    """`second` after `first`, the arm resting `pause` s (> 0) between them: `second` starts
    where `first` ends (within 1 mrad per joint) and both end at rest. Its first point is
    repeated at the end of the pause, so the times increase strictly wherever the trajectories
    end."""
    if first.joint_names != second.joint_names:
        raise ValueError(f"cannot splice trajectories of joints {first.joint_names} and "
                         f"{second.joint_names}")
    if not pause > 0.0:
        raise ValueError(f"the pause between spliced trajectories must be > 0 s, got {pause}")
    gap = float(np.max(np.abs(second.positions[0] - first.positions[-1])))
    if gap > 1e-3:
        raise ValueError(f"the second trajectory starts {gap:.4f} rad from where the first ends")
    if np.any(first.velocities[-1] != 0.0) or np.any(second.velocities[-1] != 0.0):
        raise ValueError("spliced trajectories must end at rest")
    start = first.duration + pause
    return Trajectory(first.joint_names,
                      np.concatenate([first.times, start + second.times]),
                      np.vstack([first.positions, second.positions]),
                      np.vstack([first.velocities, second.velocities]))
