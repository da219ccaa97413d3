"""The pushing manifold: error, IK onto it, and the Project step (King et al. 2015, §III-C, §V).

Property tests over seeded random targets and actions: the laws are "IK lands on the manifold
at the asked pose", "Project keeps the tool on the manifold and moves it by action·dt", "the
nullspace term never changes the task motion", "same seed, same steps"."""

import math

import numpy as np
import pytest

from rearrangement_planner.planning.machinery import manifold as mf

TABLE = 0.0
DT = 0.02


@pytest.fixture(scope="module")
def q_push(panda):
    return mf.default_push_configuration(panda, TABLE)


def random_targets(rng, count):
    """Planar tool poses over the table area, pointing roughly away from the base."""
    for _ in range(count):
        x, y = rng.uniform(0.35, 0.7), rng.uniform(-0.35, 0.35)
        yield x, y, math.atan2(y, x) + rng.uniform(-0.4, 0.4)


def tilt(err):
    return float(np.hypot(err[1], err[2]))


# -- the manifold and IK ---------------------------------------------------------------------


def test_default_push_configuration_is_on_manifold_clear_of_table_and_limits(panda, q_push):
    assert np.abs(mf.manifold_error(panda, q_push, TABLE)).max() < 1e-6
    assert np.allclose(mf.tool_planar_pose(panda, q_push), mf.DEFAULT_PUSH_TARGET, atol=1e-5)
    assert mf.lowest_point(panda, q_push)[0] >= TABLE
    margin = np.minimum(q_push - panda.lower, panda.upper - q_push)
    assert margin.min() > 0.1  # the nullspace settling moved it off the joint limits
    assert not q_push.flags.writeable
    assert mf.default_push_configuration(panda, TABLE) is q_push  # cached


def test_manifold_error_rate_is_the_tool_twist(panda, q_push):
    """d/dt (height error, tilt_x, tilt_y) = (v_z, w_x, w_y) of J qdot, by finite differences."""
    rng = np.random.default_rng(7)
    jac = panda.frame_jacobian(q_push, panda.tool_frame_id)
    eps = 1e-6
    for _ in range(5):
        qdot = rng.normal(size=7)
        rate = (mf.manifold_error(panda, q_push + eps * qdot, TABLE)
                - mf.manifold_error(panda, q_push, TABLE)) / eps
        assert np.allclose(rate, (jac @ qdot)[2:5], atol=1e-4)


def test_manifold_error_measures_height_and_tilt(panda, q_push):
    q = q_push.copy()
    q[5] += 0.1  # joint 6 tilts the hand
    err = mf.manifold_error(panda, q, TABLE)
    assert 0.05 < tilt(err) < 0.15
    assert not mf.on_manifold(panda, q, TABLE, tol=1e-3)
    assert mf.on_manifold(panda, q_push, TABLE, tol=1e-6)
    assert mf.manifold_error(panda, q_push, TABLE + 0.01)[0] == pytest.approx(-0.01, abs=1e-6)


def test_ik_reaches_random_targets_on_the_manifold(panda):
    rng = np.random.default_rng(1)
    for x, y, yaw in random_targets(rng, 12):
        q = mf.ik_on_manifold(panda, x, y, yaw, TABLE, panda.home, rng)
        assert q is not None, f"IK failed at ({x:.3f}, {y:.3f}, {yaw:.3f})"
        assert panda.within_limits(q)
        pose = panda.tool_pose(q)
        assert np.allclose(pose[:3, 3], [x, y, TABLE + panda.config.push_posture.height],
                           atol=1e-4)
        assert np.allclose(pose[:3, :3], mf.target_rotation(panda, yaw), atol=1e-4)
        assert np.abs(mf.manifold_error(panda, q, TABLE)).max() < 1e-4
        planar = mf.tool_planar_pose(panda, q)
        assert np.allclose(planar[:2], [x, y], atol=1e-4)
        assert abs(math.remainder(planar[2] - yaw, 2 * math.pi)) < 1e-4


def test_ik_respects_table_height_and_clearance(panda):
    q = mf.ik_on_manifold(panda, 0.55, 0.1, 0.2, 0.05, panda.home, np.random.default_rng(2),
                          min_clearance=0.0)
    assert q is not None
    assert panda.tool_pose(q)[2, 3] == pytest.approx(0.05 + panda.config.push_posture.height,
                                                     abs=1e-5)
    assert mf.lowest_point(panda, q)[0] >= 0.05


def test_ik_returns_none_out_of_reach(panda):
    assert mf.ik_on_manifold(panda, 1.5, 0.0, 0.0, TABLE, panda.home,
                             np.random.default_rng(0), restarts=5) is None


def test_lowest_point_matches_capsule_end_points(panda, q_push):
    poses = panda.shape_poses(q_push)
    expected = []
    for i, (shape, pose) in enumerate(zip(panda.contact_shapes, poses, strict=True)):
        if shape.link == panda.config.base_frame:
            continue
        radius, length = shape.dims
        ends = [pose[:3, 3] + sign * 0.5 * length * pose[:3, 2] for sign in (-1, 1)]
        expected.append((min(e[2] for e in ends) - radius, i))
    assert mf.lowest_point(panda, q_push) == pytest.approx(min(expected))


# -- Project ---------------------------------------------------------------------------------


def run_steps(panda, q, action, steps, **kwargs):
    for _ in range(steps):
        q = mf.project_step(panda, q, action, DT, TABLE, **kwargs)
    return q


def test_project_step_moves_tool_by_action_on_manifold(panda, q_push):
    rng = np.random.default_rng(3)
    steps = 25
    for _ in range(8):
        action = rng.uniform([-0.1, -0.1, -0.4], [0.1, 0.1, 0.4])
        q = q_push
        start = mf.tool_planar_pose(panda, q)
        for _ in range(steps):
            q = mf.project_step(panda, q, action, DT, TABLE, 0.5, rng)
            assert panda.within_limits(q)
            err = mf.manifold_error(panda, q, TABLE)
            assert abs(err[0]) < 1e-3 and tilt(err) < 1e-3
        moved = mf.tool_planar_pose(panda, q) - start
        expected = action * DT * steps
        assert np.allclose(moved[:2], expected[:2], atol=0.03 * np.linalg.norm(expected[:2]))
        assert moved[2] == pytest.approx(expected[2], abs=0.03 * abs(expected[2]) + 1e-3)


def test_project_step_is_deterministic_under_a_seed(panda, q_push):
    action = np.array([0.05, -0.03, 0.2])
    a = run_steps(panda, q_push, action, 20, rng=np.random.default_rng(11))
    b = run_steps(panda, q_push, action, 20, rng=np.random.default_rng(11))
    c = run_steps(panda, q_push, action, 20, rng=np.random.default_rng(12))
    assert np.array_equal(a, b)
    assert not np.allclose(a, c)


def test_nullspace_term_does_not_change_task_motion(panda, q_push):
    action = np.array([0.04, 0.02, -0.1])
    jac = panda.frame_jacobian(q_push, panda.tool_frame_id)
    plain = mf.project_step(panda, q_push, action, DT, TABLE, nullspace_gain=0.0)
    rng = np.random.default_rng(5)
    for _ in range(5):
        extra = mf.project_step(panda, q_push, action, DT, TABLE, nullspace_gain=1.0, rng=rng,
                                nullspace_noise=0.5)
        assert np.abs(extra - plain).max() > 1e-4  # the term does move the arm...
        # ...but only along the self-motion: the tool twist is the same to first order.
        assert np.allclose(jac @ (extra - q_push), jac @ (plain - q_push), atol=1e-12)


def test_solve_task_nullspace_projection_is_exact():
    rng = np.random.default_rng(6)
    for rows, cols in ((6, 7), (6, 6), (6, 5), (3, 7)):
        jac = rng.normal(size=(rows, cols))
        xdot, h = rng.normal(size=rows), rng.normal(size=cols)
        diff = mf.solve_task(jac, xdot, h) - mf.solve_task(jac, xdot, np.zeros(cols))
        assert np.allclose(jac @ diff, 0.0, atol=1e-10)
        if rows < cols:  # full row rank: the task is met exactly (away from singularities)
            assert np.allclose(jac @ mf.solve_task(jac, xdot, h), xdot, atol=1e-8)


def _scratch(jac):
    return np.empty(mf.solver_scratch_size(*jac.shape))


def _svd_solution(jac, xdot, h):
    """`solve_task`'s equation by LAPACK's SVD: the reference the compiled solvers meet."""
    u, s, vt = np.linalg.svd(jac)
    damping2 = mf._damping2(s[-1])
    rank = int(np.sum(s > mf.RANK_TOLERANCE))
    gains = s[:rank] / (s[:rank] ** 2 + damping2)
    null = vt[rank:]
    return vt[:rank].T @ (gains * (u[:, :rank].T @ xdot)) + null.T @ (null @ h)


def _svd(jac, xdot, h):
    qdot = np.empty(jac.shape[1])
    mf._solve_svd(jac, xdot, h, qdot, _scratch(jac))
    return qdot


def test_one_sided_jacobi_gives_the_svd_solution_near_and_at_singularities():
    """The last resort of Project's solve, for J near an exact singularity: its rotations
    find the singular values that the Gram matrix loses to rounding, and give LAPACK's
    solution (damping, rank and nullspace alike) without allocating."""
    rng = np.random.default_rng(9)
    for k in range(300):
        rows, cols = (6, 6, 6, 6, 3)[k % 5], (7, 6, 5, 3, 7)[k % 5]
        u, s, vt = np.linalg.svd(rng.normal(size=(rows, cols)), full_matrices=False)
        s[-1] = (0.0, 1e-12, 1e-7, 1e-5, 0.02, 0.5)[k % 6]   # a lost rank to well conditioned
        jac = (u * s) @ vt
        xdot, h = rng.normal(size=rows), rng.normal(size=cols)
        assert np.allclose(_svd(jac, xdot, h), _svd_solution(jac, xdot, h), rtol=0.0,
                           atol=1e-8), (k, s[-1])
    jac = rng.normal(size=(6, 7))
    jac[5] = jac[4]                                      # rank 5, two rows alike
    qdot = _svd(jac, np.ones(6), np.zeros(7))
    assert np.allclose(qdot, _svd_solution(jac, np.ones(6), np.zeros(7)), atol=1e-10)
    assert abs(mf._kth_largest(np.array([3.0, 1.0, 3.0, 2.0]), 3) - 2.0) < 1e-15


def test_the_normal_equations_give_the_svd_solution_where_they_are_used(panda, q_push):
    """Project solves by a Cholesky factor of J Jᵀ where J is well conditioned (a fifth of the
    SVD's cost) and by the SVD elsewhere: where the fast path answers, the two agree to
    rounding; a rank-deficient J or one near a singularity (damped) is left to the SVD."""
    rng = np.random.default_rng(7)
    answered = 0
    for k in range(400):
        jac = rng.normal(size=(6, (7, 6, 5)[k % 3])) * (1.0, 0.3, 0.05)[k % 4 % 3]
        xdot, h = rng.normal(size=6), rng.normal(size=jac.shape[1])
        qdot, svd = np.empty(jac.shape[1]), _svd_solution(jac, xdot, h)
        fast = mf._solve_normal(jac, xdot, h, qdot, _scratch(jac))
        if fast:
            answered += 1
            assert np.linalg.svd(jac, compute_uv=False)[-1] >= mf.SINGULAR_THRESHOLD
            assert np.allclose(qdot, svd, rtol=0, atol=1e-10)
        if not fast and not mf._solve_damped(jac, xdot, h, qdot, _scratch(jac)):
            qdot = _svd(jac, xdot, h)           # below the Gram matrix's floor
        assert np.array_equal(mf._solve(jac, xdot, h), qdot)
    assert 100 < answered < 400                 # 6 x 5 Jacobians never take the fast path
    jac = rng.normal(size=(6, 7))
    jac[5] = jac[4] * (1.0 + 1e-6)              # nearly rank 5: damped, by the SVD
    assert not mf._solve_normal(jac, np.ones(6), np.zeros(7), np.empty(7), _scratch(jac))
    # The Panda's own task Jacobian at the pushing posture takes the fast path.
    jac, xdot = mf.build_task(panda, q_push, np.array([0.05, 0.0, 0.1]), DT, TABLE)
    assert mf._solve_normal(jac, xdot, np.zeros(7), np.empty(7), _scratch(jac))


def test_the_damped_solve_gives_the_svd_solution_without_lapack():
    """Where the normal equations do not answer (a damped, near-singular J, or fewer free
    joints than rows), a Cholesky factor of the smaller Gram matrix and the damping of its
    least eigenvalue give the SVD's solution to rounding (2e-15 / s_min², at most 2e-7 rad/s),
    damping and nullspace included; J's with a singular value below 1e-4 (near an exact
    singularity, a lost rank) are left to the SVD."""
    rng = np.random.default_rng(8)
    for k in range(600):
        rows, cols = 6, (7, 6, 5, 3)[k % 4]
        u, s, vt = np.linalg.svd(rng.normal(size=(rows, cols)), full_matrices=False)
        s[-1] = 10.0 ** rng.uniform(-3.9, 0.0)          # from damped to well conditioned
        if k % 8 == 1:
            s[-2] = s[-1] * (1.0 + 1e-9)                 # two least singular values alike
        jac = (u * s) @ vt
        xdot, h = rng.normal(size=rows), rng.normal(size=cols)
        qdot, svd = np.empty(cols), _svd_solution(jac, xdot, h)
        assert mf._solve_damped(jac, xdot, h, qdot, _scratch(jac))
        assert np.allclose(qdot, svd, rtol=0.0, atol=1e-6), (k, s[-1])
    jac = rng.normal(size=(6, 7))
    jac[5] = jac[4]                                      # rank 5: the SVD's
    assert not mf._solve_damped(jac, np.ones(6), np.zeros(7), np.empty(7), _scratch(jac))
    assert np.array_equal(mf._solve(jac, np.ones(6), np.zeros(7)),
                          _svd(jac, np.ones(6), np.zeros(7)))
    a = rng.normal(size=(6, 6))
    a = a @ a.T + 1e-3 * np.eye(6)
    x, y = np.empty(6), np.empty(6)
    least = mf._least_eigenvalue(np.linalg.cholesky(a), x, y)
    assert abs(least - np.linalg.eigvalsh(a)[0]) <= 1e-12 * np.linalg.eigvalsh(a)[-1]


def test_project_step_returns_to_the_manifold(panda, q_push):
    q = q_push + np.array([0.0, 0.03, 0.0, -0.03, 0.0, 0.05, 0.0])
    assert not mf.on_manifold(panda, q, TABLE, tol=1e-3)
    q = run_steps(panda, q, np.zeros(3), 10)
    assert mf.on_manifold(panda, q, TABLE, tol=1e-5)


def test_project_step_respects_joint_and_velocity_limits(panda, q_push):
    # A fast yaw turns the wrist into its limits; a huge action saturates joint velocities.
    q = q_push
    for action, scale in (([0.0, 0.0, 1.0], 1.0), ([2.0, -2.0, 0.0], 0.3)):
        for _ in range(150):
            q_next = mf.project_step(panda, q, np.array(action), DT, TABLE, velocity_scale=scale)
            assert panda.within_limits(q_next)
            assert np.all(np.abs(q_next - q) <= scale * panda.velocity_limits * DT * (1 + 1e-9))
            q = q_next
    assert np.any(np.isclose(q, panda.lower) | np.isclose(q, panda.upper))


def test_project_step_rejects_bad_input(panda, q_push):
    with pytest.raises(ValueError, match="expected 3"):
        mf.project_step(panda, q_push, np.zeros(2), DT, TABLE)
    with pytest.raises(ValueError, match="dt must be positive"):
        mf.project_step(panda, q_push, np.zeros(3), 0.0, TABLE)
