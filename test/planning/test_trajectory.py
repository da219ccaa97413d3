"""Time parameterization for the joint trajectory controller (docs/design.md): every limit is
checked by recomputing it from the output (FK for the tool speed), on dense paths made by the
Project step like the planner's."""

import numpy as np
import pytest

from rearrangement_planner.planning.machinery import manifold as mf
from rearrangement_planner.planning.requests.trajectory import (
    TimingOptions,
    Trajectory,
    remove_duplicates,
    time_parameterize,
)

RTOL = 1e-9  # limits hold up to rounding


def dense_path(panda, seed, actions=4, steps=30, noise=True):
    """A planner-like path: piecewise-constant random actions, Project steps of 0.05 s."""
    rng = np.random.default_rng(seed)
    q = np.array(mf.default_push_configuration(panda, 0.0))
    path = [q]
    for _ in range(actions):
        action = rng.uniform([-0.1, -0.1, -0.5], [0.1, 0.1, 0.5])
        for _ in range(steps):
            q = mf.project_step(panda, q, action, 0.05, 0.0, 0.5, rng if noise else None)
            path.append(q)
    return np.array(path)


def tool_positions(panda, positions):
    return np.array([panda.tool_pose(q)[:3, 3] for q in positions])


OPTIONS = [
    TimingOptions(),
    TimingOptions(velocity_scale=0.2, max_tool_speed=0.5),
    TimingOptions(velocity_scale=1.0, max_tool_speed=0.05, max_joint_acceleration=1.5),
    TimingOptions(velocity_scale=0.8, max_tool_speed=1.0,
                  joint_accelerations=(3.0, 3.0, 3.0, 3.0, 5.0, 5.0, 5.0)),
]


@pytest.mark.parametrize("options", OPTIONS)
@pytest.mark.parametrize("seed", [0, 1])
def test_limits_hold_on_every_point_and_segment(panda, seed, options):
    path = dense_path(panda, seed)
    traj = time_parameterize(panda, path, options)
    vmax = options.velocity_scale * np.asarray(panda.velocity_limits)
    dt = np.diff(traj.times)

    assert traj.joint_names == panda.joint_names
    assert traj.times[0] == 0.0 and np.all(dt > 0)
    assert np.array_equal(traj.positions, path)  # no duplicates in a Project path
    assert np.all(traj.velocities[0] == 0.0) and np.all(traj.velocities[-1] == 0.0)
    # joint velocity: reported on the points and the mean over every segment
    assert np.all(np.abs(traj.velocities) <= vmax * (1 + RTOL))
    assert np.all(np.abs(np.diff(traj.positions, axis=0)) / dt[:, None] <= vmax * (1 + RTOL))
    # tool speed: FK chord over every segment, and J v on the points
    tool = tool_positions(panda, traj.positions)
    chord_speed = np.linalg.norm(np.diff(tool, axis=0), axis=1) / dt
    assert np.all(chord_speed <= options.max_tool_speed * (1 + RTOL))
    for q, v in zip(traj.positions, traj.velocities, strict=True):
        jac = panda.frame_jacobian(q, panda.tool_frame_id)
        assert np.linalg.norm(jac[:3] @ v) <= options.max_tool_speed * (1 + RTOL)
    # acceleration: the reported velocities, differenced over time
    amax = options.acceleration_limits(panda.nq)
    if amax is not None:
        accel = np.diff(traj.velocities, axis=0) / dt[:, None]
        assert np.all(np.abs(accel) <= amax * (1 + RTOL))
    # the binding limit is actually reached somewhere (the parameterization is not lazy)
    assert (chord_speed.max() > 0.9 * options.max_tool_speed
            or (np.abs(traj.velocities) / vmax).max() > 0.9
            or amax is not None)


def test_velocities_are_consistent_with_the_motion(panda):
    """On a smooth path the velocities integrate (trapezoidal rule) to the position steps and
    point the way the path goes."""
    path = dense_path(panda, 3, actions=1, steps=30, noise=False)  # no joint reaches a limit
    traj = time_parameterize(panda, path, TimingOptions(max_joint_acceleration=2.0))
    dt = np.diff(traj.times)
    steps = np.diff(traj.positions, axis=0)
    integrated = 0.5 * (traj.velocities[:-1] + traj.velocities[1:]) * dt[:, None]
    assert np.allclose(integrated, steps, atol=0.05 * np.abs(steps).max())
    interior = traj.velocities[1:-1]
    assert np.all(np.einsum("ij,ij->i", interior, steps[1:]) > 0)
    # it starts from rest and ramps up: the first segments are slower than the middle ones
    assert dt[0] > dt[len(dt) // 2]


def test_duplicates_are_removed(panda):
    path = dense_path(panda, 4, actions=1, steps=10)
    doubled = np.repeat(path, [1, 3, 1, 1, 2, 1, 1, 1, 1, 1, 4], axis=0)
    traj = time_parameterize(panda, doubled)
    assert np.array_equal(traj.positions, path)
    assert np.all(np.diff(traj.times) > 0)
    assert np.array_equal(remove_duplicates(doubled), path)


def test_waypoints_nanoradians_apart_are_a_microsecond_apart(panda):
    """Waypoints 1e-10 rad apart (above the duplicate tolerance; three in a row, so that the
    middle segment's rates are bounded by tiny steps alone and it would take under a
    nanosecond) are timed at least MIN_SEGMENT apart, so the controller command's
    time_from_start, in whole nanoseconds, strictly increases (a closed-loop re-plan once
    ended INTERNAL on points 0.5 ns apart)."""
    from rearrangement_planner.io.messages import joint_trajectory
    from rearrangement_planner.planning.requests.trajectory import MIN_SEGMENT

    path = dense_path(panda, 5, actions=1, steps=10)
    nudged = np.insert(path, 6, [path[5] + 1e-10 * (i + 1) for i in range(3)], axis=0)
    traj = time_parameterize(panda, nudged)
    assert len(traj) == len(nudged)
    assert np.min(np.diff(traj.times)) >= 0.999 * MIN_SEGMENT       # up to rounding
    times = [p["time_from_start"] for p in joint_trajectory(traj)["points"]]
    assert all(b["sec"] * 10**9 + b["nanosec"] > a["sec"] * 10**9 + a["nanosec"]
               for a, b in zip(times, times[1:], strict=False))


def test_sample_hits_waypoints_at_their_times(panda):
    traj = time_parameterize(panda, dense_path(panda, 5, actions=2, steps=10))
    for t, q in zip(traj.times, traj.positions, strict=True):
        assert np.allclose(traj.sample(t), q, atol=1e-12)
    mid = 0.5 * (traj.times[3] + traj.times[4])
    assert np.allclose(traj.sample(mid), 0.5 * (traj.positions[3] + traj.positions[4]))
    assert np.array_equal(traj.sample(-1.0), traj.positions[0])
    assert np.array_equal(traj.sample(traj.duration + 1.0), traj.positions[-1])
    assert traj.duration == traj.times[-1] and len(traj) == traj.positions.shape[0]


def test_two_and_one_point_paths(panda):
    q0 = np.array(mf.default_push_configuration(panda, 0.0))
    q1 = q0 + 0.2
    options = TimingOptions(velocity_scale=0.5, max_tool_speed=10.0, max_joint_acceleration=1.0)
    traj = time_parameterize(panda, np.array([q0, q1]), options)
    assert len(traj) == 2 and np.all(traj.velocities == 0.0)
    # rest to rest over 0.2 rad with a <= 1 rad/s²: at least 2 sqrt(0.2 / 1) s (triangular)
    assert traj.duration == pytest.approx(2 * np.sqrt(0.2 / 1.0))
    single = time_parameterize(panda, np.array([q0, q0, q0]))
    assert len(single) == 1 and single.duration == 0.0 and np.all(single.velocities == 0.0)


def test_trajectory_is_frozen_and_validated(panda):
    traj = time_parameterize(panda, dense_path(panda, 6, actions=1, steps=5))
    with pytest.raises(ValueError):
        traj.positions[0, 0] = 1.0  # read-only array
    with pytest.raises(AttributeError):
        traj.times = np.zeros(3)  # frozen dataclass
    names = panda.joint_names
    with pytest.raises(ValueError, match="strictly increasing"):
        Trajectory(names, [0.0, 1.0, 1.0], np.zeros((3, 7)), np.zeros((3, 7)))
    with pytest.raises(ValueError, match="start at 0"):
        Trajectory(names, [0.5, 1.0], np.zeros((2, 7)), np.zeros((2, 7)))
    with pytest.raises(ValueError, match="positions has shape"):
        Trajectory(names, [0.0, 1.0], np.zeros((2, 6)), np.zeros((2, 7)))


def test_bad_input_is_rejected(panda):
    with pytest.raises(ValueError, match="expected \\(N, 7\\)"):
        time_parameterize(panda, np.zeros((4, 6)))
    with pytest.raises(ValueError, match="NaN"):
        time_parameterize(panda, np.full((2, 7), np.nan))
    with pytest.raises(ValueError, match="velocity_scale"):
        TimingOptions(velocity_scale=1.5)
    with pytest.raises(ValueError, match="max_tool_speed"):
        TimingOptions(max_tool_speed=0.0)
