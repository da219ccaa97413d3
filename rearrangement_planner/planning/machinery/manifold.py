"""The pushing manifold and the Jacobian projection onto it (King et al. 2015, §III-C, §V).

The manifold is the set of arm configurations whose tool frame is held "parallel to the table"
(the paper's constraint manifold, 8 cm above the table for HERB):

    p_z(q) = table_height + push_posture.height
    R(q)   = Rz(yaw) · R0,   R0 = push_posture.rotation = Ry(pitch) Rx(roll),  yaw free.

Equivalently, the tool-frame direction u0 = R0ᵀ e_z ("the tool's view of world up") must map to
world up: R(q) u0 = e_z. That is two orientation constraints (a unit vector on S²) plus one height
constraint, so the manifold has 7 - 3 = 4 dimensions: the planar tool pose (x, y, yaw) plus the
arm's one-dimensional self-motion.

`project_step` is one step of the paper's Project (King et al. 2015, §V):

    q_new = q + Δt (J⁺(q) a + h(q)),

extended, as in the constrained extension of Berenson et al. (ICRA 2009, CBiRRT, cited as [7]
in King et al. 2015, §III-C), with correction rows that pull the tool back onto the manifold, and a
nullspace term h projected into the nullspace of the task Jacobian.

Frames and units: everything in the robot base frame (metres, radians, seconds). The tool
Jacobian is `RobotModel.frame_jacobian` at the tool frame origin: 6 x 7, [linear; angular], in
base-frame axes.
"""

from __future__ import annotations

import functools
import math
import weakref

import numpy as np
import pinocchio as pin
from numba import njit

from rearrangement_planner.model.errors import RobotModelError
from rearrangement_planner.model.robot import PushPosture, RobotModel
from rearrangement_planner.physics import kernels

# Largest correction twist `project_step` commands to return onto the manifold (the correction is
# error / dt, which is huge for a large error and a short step).
MAX_CORRECTION_SPEED = 0.25  # m/s, height row
MAX_CORRECTION_RATE = 1.0  # rad/s, tilt rows

# Adaptive damping of the pseudoinverse (Nakamura & Hanafusa 1986 / Maciejewski & Klein 1988):
# below the singular value SINGULAR_THRESHOLD the damping grows smoothly to MAX_DAMPING.
SINGULAR_THRESHOLD = 0.04
MAX_DAMPING = 0.04
RANK_TOLERANCE = 1e-9  # singular values below this are treated as zero (nullspace directions)

# Where `default_push_configuration` puts the tool (base frame, m, m, rad).
DEFAULT_PUSH_TARGET = (0.5, 0.0, 0.0)
SETTLE_STEPS = 300  # nullspace steps (of 0.02 s) that move the default configuration off limits

_default_cache: weakref.WeakKeyDictionary[RobotModel, dict[float, np.ndarray]] = (
    weakref.WeakKeyDictionary())


# -- the manifold ----------------------------------------------------------------------------


def push_height(robot: RobotModel, table_height: float) -> float:
    """Tool height on the manifold (base frame z, m)."""
    return float(table_height) + robot.config.push_posture.height


def target_rotation(robot: RobotModel, yaw: float) -> np.ndarray:
    """Tool orientation on the manifold at `yaw`: Rz(yaw) · R0 (R0 = push_posture.rotation)."""
    c, s = math.cos(yaw), math.sin(yaw)
    rz = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    return rz @ _posture_rotation(robot.config.push_posture)


@functools.lru_cache(maxsize=32)
def _posture_rotation(posture: PushPosture) -> np.ndarray:
    rotation = posture.rotation
    rotation.setflags(write=False)
    return rotation


@functools.lru_cache(maxsize=32)
def _up_in_tool(posture: PushPosture) -> tuple[float, float, float]:
    """u0 = R0ᵀ e_z: the tool-frame direction that points to world up on the manifold."""
    row = posture.rotation[2, :]  # row 2 of R0 = R0ᵀ e_z
    return float(row[0]), float(row[1]), float(row[2])


def tool_planar_pose(robot: RobotModel, q: np.ndarray) -> np.ndarray:
    """(x, y, yaw) of the tool: base-frame position and the yaw of R R0ᵀ (= Rz(yaw) on the
    manifold; off the manifold the yaw of the nearest such rotation, to first order)."""
    pose = robot.tool_pose(q)
    m = pose[:3, :3] @ _posture_rotation(robot.config.push_posture).T
    return np.array([pose[0, 3], pose[1, 3], math.atan2(m[1, 0], m[0, 0])])


def manifold_error(robot: RobotModel, q: np.ndarray, table_height: float) -> np.ndarray:
    """(3,) residual of the manifold constraints at q, zero on the manifold:

    [0]    tool height error p_z - (table_height + push_posture.height)   (m)
    [1:3]  tilt error: x, y components (base frame) of the rotation vector phi that turns world
           up e_z into u = R(q) R0ᵀ e_z, the current direction of the tool axis that should point
           up (rad; |phi| is the tilt angle). For a small tilt, d(phi)/dt = (w_x, w_y), the tool's
           angular velocity about the base x and y axes — the rows `project_step` corrects with.
    """
    return np.array(_errors_from_pose(robot, robot.tool_pose(q), table_height))


def on_manifold(
    robot: RobotModel, q: np.ndarray, table_height: float, tol: float = 1e-3,
    angle_tol: float | None = None,
) -> bool:
    """Whether |height error| <= tol (m) and tilt angle <= angle_tol (rad, default: tol)."""
    dz, tilt_x, tilt_y = _errors_from_pose(robot, robot.tool_pose(q), table_height)
    angle_tol = tol if angle_tol is None else angle_tol
    return abs(dz) <= tol and math.hypot(tilt_x, tilt_y) <= angle_tol


def lowest_point(robot: RobotModel, q: np.ndarray, moving_only: bool = True) -> tuple[float, int]:
    """(z, index) of the lowest point of the robot's contact shapes at q (base frame, m) and the
    index of the shape it belongs to (in `robot.contact_shapes` order). Exact for every shape
    kind: a capsule's lowest point is the lower end of its axis segment minus the radius; a
    cylinder's is the lower end of its axis minus r·sqrt(1 - a_z²) (its rim); a box's is its
    centre minus the half extents projected on z.

    moving_only: skip shapes on links no joint moves (the base, which stands on the floor or
    the table top by construction)."""
    poses = robot.shape_poses(q)
    lowest, index = math.inf, -1
    for i, (shape, pose) in enumerate(zip(robot.contact_shapes, poses, strict=True)):
        if moving_only and robot.model.frames[robot.frame_id(shape.link)].parentJoint == 0:
            continue
        centre_z = pose[2, 3]
        axis_z = pose[2, 2]  # z component of the shape's z axis
        if shape.kind == "capsule":
            z = centre_z - 0.5 * shape.dims[1] * abs(axis_z) - shape.dims[0]
        elif shape.kind == "sphere":
            z = centre_z - shape.dims[0]
        elif shape.kind == "cylinder":
            radius, length = shape.dims
            z = (centre_z - 0.5 * length * abs(axis_z)
                 - radius * math.sqrt(max(0.0, 1.0 - axis_z * axis_z)))
        else:  # box
            z = centre_z - 0.5 * float(np.abs(pose[2, :3]) @ np.asarray(shape.dims))
        if z < lowest:
            lowest, index = float(z), i
    return lowest, index


# -- Project: one Jacobian step along the manifold -------------------------------------------


@njit(cache=True)
def _manifold_errors(pose: np.ndarray, up: np.ndarray, height: float) -> tuple[float, float,
                                                                                 float]:
    """`manifold_error` from the tool pose: (height error, tilt x, tilt y); `up` = u0 (the
    tool-frame direction that should point up), `height` the push height (base frame z)."""
    ux = pose[0, 0] * up[0] + pose[0, 1] * up[1] + pose[0, 2] * up[2]     # u = R u0 (world)
    uy = pose[1, 0] * up[0] + pose[1, 1] * up[1] + pose[1, 2] * up[2]
    uz = pose[2, 0] * up[0] + pose[2, 1] * up[1] + pose[2, 2] * up[2]
    # Tilt: the rotation vector phi that turns e_z into u: axis e_z x u = (-u_y, u_x, 0),
    # angle atan2(|e_z x u|, e_z . u).
    sin_angle = math.hypot(ux, uy)
    angle = math.atan2(sin_angle, uz)
    if sin_angle > 1e-15:
        scale = angle / sin_angle
        tilt_x, tilt_y = -uy * scale, ux * scale
    else:  # aligned (angle 0) or upside down (angle pi, about any horizontal axis)
        tilt_x, tilt_y = angle, 0.0
    return pose[2, 3] - height, tilt_x, tilt_y


def _errors_from_pose(
    robot: RobotModel, pose: np.ndarray, table_height: float
) -> tuple[float, float, float]:
    up = np.array(_up_in_tool(robot.config.push_posture))
    dz, tilt_x, tilt_y = _manifold_errors(np.array(pose, dtype=float), up,
                                          push_height(robot, table_height))
    return float(dz), float(tilt_x), float(tilt_y)


def build_task(
    robot: RobotModel, q: np.ndarray, action: np.ndarray, dt: float, table_height: float,
    correction_gain: float = 1.0,
) -> tuple[np.ndarray, np.ndarray]:
    """The 6-row velocity task (J, xdot) of one Project step, both in the base frame.

    Rows, in the order of the tool Jacobian [linear; angular] (all six rows of it):
        v_x, v_y   = action[0:2]                      planar tool velocity (m/s)
        v_z        = -k e_height / dt                 back to the push height (m/s)
        w_x, w_y   = -k phi / dt                      undo the tilt (rad/s)
        w_z        = action[2]                        yaw rate (rad/s)
    with k = `correction_gain` (1 closes the error in one step to first order), the correction
    clipped to MAX_CORRECTION_SPEED / MAX_CORRECTION_RATE. The first and last rows are the
    paper's end-effector velocity a (King et al. 2015, §V); the middle three are the projection back
    onto the constraint (King et al. 2015, §III-C, Alg. 2 line 5, after Berenson et al. 2009).
    Compiled (`_task`), with the tool's kinematics from `kernels.tool_kinematics`.
    """
    chain = kernels.compiled_chain(robot)
    pose, jac, xdot = np.empty((4, 4)), np.empty((6, robot.nq)), np.empty(6)
    up = np.array(_up_in_tool(robot.config.push_posture))
    _task(np.asarray(q, dtype=float), np.asarray(action, dtype=float), float(dt),
          chain.arrays[:4], chain.tool_joint, chain.tool_local, up,
          push_height(robot, table_height), float(correction_gain), pose, jac, xdot)
    return jac, xdot


@njit(cache=True)
def _task(q: np.ndarray, action: np.ndarray, dt: float, chain: tuple, tool_joint: int,
          tool_local: np.ndarray, up: np.ndarray, height: float, correction_gain: float,
          pose: np.ndarray, jac: np.ndarray, xdot: np.ndarray) -> None:
    """`build_task` compiled: the tool pose, its Jacobian and the task velocity."""
    kernels.tool_kinematics(q, chain[0], chain[1], chain[2], chain[3], tool_joint, tool_local,
                            pose, jac)
    _task_velocity(pose, action, dt, up, height, correction_gain, xdot)


@njit(cache=True)
def _task_velocity(pose: np.ndarray, action: np.ndarray, dt: float, up: np.ndarray,
                   height: float, correction_gain: float, xdot: np.ndarray) -> None:
    """The task velocity xdot (`build_task`) of the tool at `pose`."""
    dz, tilt_x, tilt_y = _manifold_errors(pose, up, height)
    k = -correction_gain / dt
    v_z = min(max(k * dz, -MAX_CORRECTION_SPEED), MAX_CORRECTION_SPEED)
    w_x, w_y = k * tilt_x, k * tilt_y
    rate = math.hypot(w_x, w_y)
    if rate > MAX_CORRECTION_RATE:
        w_x, w_y = w_x * MAX_CORRECTION_RATE / rate, w_y * MAX_CORRECTION_RATE / rate
    xdot[0], xdot[1], xdot[2] = action[0], action[1], v_z
    xdot[3], xdot[4], xdot[5] = w_x, w_y, action[2]


def joint_limit_gradient(robot: RobotModel, q: np.ndarray, gain: float) -> np.ndarray:
    """Joint-limit avoidance velocity (rad/s), the nullspace term h(q) of the Project equation:
    the negative gradient of H(q) = gain · Σ w_i⁶ / 6 with w_i = (q_i - mid_i) / half_range_i
    (per-joint gradient scaled by half_range_i so `gain` is in rad/s): h_i = -gain · w_i⁵.
    Gradient projection after Liegeois (1977); the sixth power makes H a soft maximum, so the
    joint nearest its limit dominates and mid-range joints are left alone (with the square, a
    joint can sit on its limit while the others pull the self-motion the other way). `gain` is
    the speed at which a joint at its limit is pulled back."""
    return _limit_gradient(np.array(q, dtype=float), np.array(robot.lower),
                           np.array(robot.upper), float(gain))


@njit(cache=True)
def _limit_gradient(q: np.ndarray, lower: np.ndarray, upper: np.ndarray,
                    gain: float) -> np.ndarray:
    h = np.empty(q.shape[0])
    for j in range(q.shape[0]):
        h[j] = _limit_pull(q[j], lower[j], upper[j], gain)
    return h


@njit(cache=True)
def _limit_pull(q: float, lower: float, upper: float, gain: float) -> float:
    """One joint's term of `joint_limit_gradient`: -gain · w⁵."""
    w = (q - 0.5 * (upper + lower)) / (0.5 * (upper - lower))
    return -gain * w**5


def solve_task(jac: np.ndarray, xdot: np.ndarray, h: np.ndarray) -> np.ndarray:
    """qdot = J⁺ xdot + (I - J⁺J) h (King et al. 2015, §V, the Project equation).

    J⁺ is the damped least-squares pseudoinverse from the SVD J = U S Vᵀ:
    J⁺ = V diag(s / (s² + λ²)) Uᵀ, with λ² = (1 - (s_min/ε)²) λ_max² when s_min < ε and 0
    otherwise (adaptive damping, Maciejewski & Klein 1988: exact away from singularities,
    bounded near them). With more joints than rows it is the minimum-norm solution; with
    fewer (joints locked at limits) the least-squares one. The nullspace projector is the
    exact I - V_r V_rᵀ over the nonzero singular values, so J (I - J⁺J) h = 0: h never
    changes the task-space motion (to first order). Compiled (`_solve`): where s_min ≥ ε
    is certain (no damping, full row rank) the same solution comes from the normal equations,
    a fifth of the SVD's cost (`_solve_normal`).
    """
    jac = np.ascontiguousarray(jac, dtype=float)
    if jac.shape[1] == 0:
        return np.zeros(0)
    return _solve(jac, np.asarray(xdot, dtype=float), np.asarray(h, dtype=float))


@njit(cache=True)
def _solve(jac: np.ndarray, xdot: np.ndarray, h: np.ndarray) -> np.ndarray:
    """`solve_task` compiled (`_solve_into` with arrays of its own)."""
    qdot = np.empty(jac.shape[1])
    _solve_into(jac, xdot, h, qdot, np.empty(solver_scratch_size(*jac.shape)))
    return qdot


@njit(cache=True)
def solver_scratch_size(m: int, n: int) -> int:
    """The scratch floats `_solve_into` needs for an m x n J."""
    k = max(m, n)
    return 3 * k * k + 3 * k


@njit(cache=True, inline="always")
def _carve(scratch: np.ndarray, start: int, rows: int, cols: int) -> np.ndarray:
    """A rows x cols array over scratch[start:] (no allocation). Inlined: kernels with and
    without reference counting carve (`kernels.njit_bare`)."""
    return scratch[start:start + rows * cols].reshape((rows, cols))


@kernels.njit_bare
def _solve_into(jac: np.ndarray, xdot: np.ndarray, h: np.ndarray, qdot: np.ndarray,
                scratch: np.ndarray) -> None:
    """qdot = `solve_task`, in `scratch` (`solver_scratch_size` floats): the normal equations
    where J is well conditioned (no damping, full row rank), else a Cholesky factor of its
    smaller Gram matrix with the damping of its least eigenvalue (`_solve_damped`), else,
    near an exact singularity, the SVD by one-sided Jacobi (`_solve_svd`)."""
    if _solve_normal(jac, xdot, h, qdot, scratch):
        return
    if _solve_damped(jac, xdot, h, qdot, scratch):
        return
    _solve_svd(jac, xdot, h, qdot, scratch)


GRAM_FLOOR = 1e-8
"""Below this least eigenvalue of the Gram matrix (a singular value of 1e-4), `_solve_damped`
leaves the solve to the SVD. The Gram matrix squares J's condition number: its solution
differs from the SVD's by about 2e-15 / s_min² (2e-7 rad/s at the floor, 3e-10 from s_min 0.01
up; test_manifold)."""


@njit(cache=True)
def _damping2(s_min: float) -> float:
    """λ², the adaptive damping of the pseudoinverse for the smallest singular value s_min
    (`solve_task`)."""
    if s_min < SINGULAR_THRESHOLD:
        return (1.0 - (s_min / SINGULAR_THRESHOLD) ** 2) * MAX_DAMPING**2
    return 0.0


@njit(cache=True)
def _gram(jac: np.ndarray, wide: bool, gram: np.ndarray) -> None:
    """gram = J Jᵀ (`wide`) or JᵀJ."""
    m, n = jac.shape
    k = m if wide else n
    for i in range(k):
        for j in range(i + 1):
            acc = 0.0
            if wide:
                for c in range(n):
                    acc += jac[i, c] * jac[j, c]
            else:
                for r in range(m):
                    acc += jac[r, i] * jac[r, j]
            gram[i, j] = gram[j, i] = acc


@njit(cache=True)
def _solve_normal(jac: np.ndarray, xdot: np.ndarray, h: np.ndarray, qdot: np.ndarray,
                  scratch: np.ndarray) -> bool:
    """qdot = J⁺ xdot + (I - J⁺J) h with J⁺ = Jᵀ (J Jᵀ)⁻¹, by a Cholesky factor of J Jᵀ; the
    same solution as `_solve_svd` (to rounding) where its smallest singular value is at least
    SINGULAR_THRESHOLD: then no damping applies, J has full row rank, and J⁺J = V_r V_rᵀ.
    Returns False, qdot unset, when that is not certain: a pivot of the factor not positive,
    or the bound 1 / ||(J Jᵀ)⁻¹||_F ≤ σ_min² below SINGULAR_THRESHOLD². Its arrays are carved
    from `scratch` (`solver_scratch_size`)."""
    m, n = jac.shape
    if n < m:
        return False
    a, low, inv = _carve(scratch, 0, m, m), _carve(scratch, m * m, m, m), _carve(
        scratch, 2 * m * m, m, m)
    base = 3 * m * m
    rhs, y = scratch[base + m:base + 2 * m], scratch[base + 2 * m:base + 3 * m]
    for i in range(m):
        for j in range(i + 1):
            acc = 0.0
            for c in range(n):
                acc += jac[i, c] * jac[j, c]
            a[i, j] = acc
    if not _cholesky(a, low) or not _certainly_undamped(low, inv):     # inv = (J Jᵀ)⁻¹
        return False
    # y = (J Jᵀ)⁻¹ (xdot - J h); qdot = h + Jᵀ y = J⁺ xdot + (I - J⁺J) h
    for i in range(m):
        acc = xdot[i]
        for c in range(n):
            acc -= jac[i, c] * h[c]
        rhs[i] = acc
    for i in range(m):
        acc = 0.0
        for j in range(m):
            acc += inv[i, j] * rhs[j]
        y[i] = acc
    for c in range(n):
        acc = h[c]
        for i in range(m):
            acc += jac[i, c] * y[i]
        qdot[c] = acc
    return True


@njit(cache=True)
def _cholesky(a: np.ndarray, low: np.ndarray) -> bool:
    """a = low lowᵀ from a's lower triangle, low lower triangular (its upper triangle neither
    written nor read); False when a pivot is not positive."""
    m = a.shape[0]
    for j in range(m):
        d = a[j, j]
        for c in range(j):
            d -= low[j, c] * low[j, c]
        if d <= 0.0:
            return False
        low[j, j] = math.sqrt(d)
        for i in range(j + 1, m):
            acc = a[i, j]
            for c in range(j):
                acc -= low[i, c] * low[j, c]
            low[i, j] = acc / low[j, j]
    return True


@njit(cache=True)
def _inverse_column(low: np.ndarray, col: int, inv: np.ndarray) -> None:
    """inv[:, col] = (low lowᵀ)⁻¹ e_col, low lower triangular, in place. Forward substitution
    with the unit vector e_col leaves zeros above row col, so it starts there: the terms it
    skips are products with those zeros, and the numbers are those of the full substitution."""
    m = low.shape[0]
    for i in range(col):
        inv[i, col] = 0.0
    for i in range(col, m):                   # low z = e_col
        acc = 1.0 if i == col else 0.0
        for c in range(col, i):
            acc -= low[i, c] * inv[c, col]
        inv[i, col] = acc / low[i, i]
    for i in range(m - 1, -1, -1):            # lowᵀ x = z
        acc = inv[i, col]
        for c in range(i + 1, m):
            acc -= low[c, i] * inv[c, col]
        inv[i, col] = acc / low[i, i]


@njit(cache=True)
def _solve_damped(jac: np.ndarray, xdot: np.ndarray, h: np.ndarray, qdot: np.ndarray,
                  scratch: np.ndarray) -> bool:
    """`_solve_svd`'s solution where the normal equations do not answer (a damped J, or fewer
    free joints than rows) and J still has full rank, from a Cholesky factor of its smaller
    Gram matrix A, J Jᵀ (m ≤ n) or JᵀJ. With λ² the damping of s_min² = A's least eigenvalue
    (`_least_eigenvalue`): J⁺ = Jᵀ (A + λ²I)⁻¹ and the nullspace projector I - Jᵀ A⁻¹ J
    (wide J), or J⁺ = (A + λ²I)⁻¹ Jᵀ and no nullspace (tall J: full column rank). The same
    equation as the SVD's V diag(s / (s² + λ²)) Uᵀ and I - V_r V_rᵀ, with no eigenvectors to
    find; a tall J's s_min is sought only where `_certainly_undamped` cannot rule damping out,
    as it mostly can (joints locked at their limits, not a singularity). Returns False, qdot
    unset, when A has no factor or s_min² is below GRAM_FLOOR. Its arrays are carved from
    `scratch` (`solver_scratch_size`)."""
    m, n = jac.shape
    wide = m <= n
    k = m if wide else n
    a, low, inv = _carve(scratch, 0, k, k), _carve(scratch, k * k, k, k), _carve(
        scratch, 2 * k * k, k, k)
    base = 3 * k * k
    x, y, rhs = (scratch[base:base + k], scratch[base + k:base + 2 * k],
                 scratch[base + 2 * k:base + 3 * k])
    _gram(jac, wide, a)
    if not _cholesky(a, low):
        return False
    damping2 = 0.0
    if wide or not _certainly_undamped(low, inv):      # a wide J here failed that bound
        smallest = _least_eigenvalue(low, x, y)
        if smallest < GRAM_FLOOR:
            return False
        damping2 = _damping2(math.sqrt(smallest))
    if wide:                                  # y = A⁻¹ J h, for the nullspace projector
        _multiply(jac, h, rhs, False)
        _cholesky_solve(low, rhs, y)
    if damping2 > 0.0:                        # else low is already A's factor
        for i in range(k):
            a[i, i] += damping2
        _cholesky(a, low)                     # A + λ²I: positive definite as A is
    if not wide:                              # qdot = (A + λ²I)⁻¹ Jᵀ xdot
        _multiply(jac, xdot, rhs, True)
        _cholesky_solve(low, rhs, qdot)
        return True
    _cholesky_solve(low, xdot, x)             # qdot = h + Jᵀ ((A + λ²I)⁻¹ xdot - A⁻¹ J h)
    for c in range(n):
        acc = h[c]
        for i in range(m):
            acc += jac[i, c] * (x[i] - y[i])
        qdot[c] = acc
    return True


@njit(cache=True)
def _multiply(jac: np.ndarray, v: np.ndarray, out: np.ndarray, transposed: bool) -> None:
    """out = J v, or Jᵀ v (`transposed`), each entry summed in index order."""
    m, n = jac.shape
    for i in range(n if transposed else m):
        acc = 0.0
        for j in range(m if transposed else n):
            acc += (jac[j, i] if transposed else jac[i, j]) * v[j]
        out[i] = acc


@njit(cache=True, inline="always")
def _certainly_undamped(low: np.ndarray, inv: np.ndarray) -> bool:
    """Whether A = low lowᵀ's least eigenvalue is at least SINGULAR_THRESHOLD², by the bound
    1 / ||A⁻¹||_F ≤ λ_min, A⁻¹ into `inv` (column by column)."""
    k = low.shape[0]
    for col in range(k):
        _inverse_column(low, col, inv)
    frobenius2 = 0.0
    for i in range(k):
        for j in range(k):
            frobenius2 += inv[i, j] * inv[i, j]
    return frobenius2 * SINGULAR_THRESHOLD**4 <= 1.0


@njit(cache=True)
def _least_eigenvalue(low: np.ndarray, x: np.ndarray, y: np.ndarray) -> float:
    """The least eigenvalue of A = low lowᵀ by inverse iteration (Golub & Van Loan, Matrix
    Computations, §7.6.1): x ← A⁻¹x / ‖A⁻¹x‖ until the Rayleigh quotient xᵀA⁻¹x changes by
    less than 1e-10 of itself (4–5 steps for a damped Project J, whose least eigenvalue is far
    below the next); its error is at most the two least eigenvalues' gap, and the damping,
    smooth in s_min, barely feels it. x and y are scratch."""
    k = low.shape[0]
    for i in range(k):
        x[i] = 1.0 + 0.1 * i                  # not orthogonal to any one eigenvector, a rule
    norm = 0.0
    for i in range(k):
        norm += x[i] * x[i]
    for i in range(k):
        x[i] /= math.sqrt(norm)
    quotient = 0.0
    for _ in range(100):
        _cholesky_solve(low, x, y)
        last, quotient, norm = quotient, 0.0, 0.0
        for i in range(k):
            quotient += x[i] * y[i]
            norm += y[i] * y[i]
        norm = math.sqrt(norm)
        for i in range(k):
            x[i] = y[i] / norm
        if quotient - last <= 1e-10 * quotient:
            break
    return 1.0 / quotient


@njit(cache=True)
def _cholesky_solve(low: np.ndarray, b: np.ndarray, out: np.ndarray) -> None:
    """out = (low lowᵀ)⁻¹ b, low lower triangular; out may not be b."""
    k = low.shape[0]
    for i in range(k):
        acc = b[i]
        for c in range(i):
            acc -= low[i, c] * out[c]
        out[i] = acc / low[i, i]
    for i in range(k - 1, -1, -1):
        acc = out[i]
        for c in range(i + 1, k):
            acc -= low[c, i] * out[c]
        out[i] = acc / low[i, i]


@njit(cache=True)
def _solve_svd(jac: np.ndarray, xdot: np.ndarray, h: np.ndarray, qdot: np.ndarray,
               scratch: np.ndarray) -> None:
    """qdot = `solve_task` from the SVD of J by one-sided Jacobi rotations (Hestenes 1958;
    Demmel & Veselić 1992, who show it finds small singular values to high relative accuracy):
    plane rotations of J's columns, accumulated in V, until every pair is orthogonal; then
    J V = B, the columns of B are s_j u_j and V's columns the right singular vectors. For J
    near an exact singularity, where the Gram matrix's eigenvalues (`_solve_damped`) have lost
    the small singular values to rounding. Its arrays are carved from `scratch`
    (`solver_scratch_size`): no allocation and no LAPACK call."""
    m, n = jac.shape
    b, v = _carve(scratch, 0, m, n), _carve(scratch, m * n, n, n)
    norms = scratch[m * n + n * n:m * n + n * n + n]
    for r in range(m):
        for c in range(n):
            b[r, c] = jac[r, c]
    for r in range(n):
        for c in range(n):
            v[r, c] = 1.0 if r == c else 0.0
    for _ in range(60):
        if not _orthogonalise_columns(b, v):
            break
    for c in range(n):
        acc = 0.0
        for r in range(m):
            acc += b[r, c] * b[r, c]
        norms[c] = math.sqrt(acc)
    damping2 = _damping2(_kth_largest(norms, min(m, n)))
    for c in range(n):
        qdot[c] = h[c]
    for j in range(n):
        if norms[j] <= RANK_TOLERANCE:        # a nullspace direction: h keeps its part
            continue
        task, null = 0.0, 0.0                 # (s_j u_j . xdot), (v_j . h)
        for r in range(m):
            task += b[r, j] * xdot[r]
        for c in range(n):
            null += v[c, j] * h[c]
        coeff = task / (norms[j] * norms[j] + damping2) - null
        for c in range(n):
            qdot[c] += v[c, j] * coeff


@njit(cache=True)
def _orthogonalise_columns(b: np.ndarray, v: np.ndarray) -> bool:
    """One sweep of one-sided Jacobi (`_solve_svd`): each pair of b's columns that is not
    orthogonal to rounding turned by the rotation that makes it so, and v's columns with it.
    Returns whether any pair turned."""
    m, n = b.shape
    turned = False
    for p in range(n - 1):
        for q in range(p + 1, n):
            alpha, beta, gamma = 0.0, 0.0, 0.0
            for r in range(m):
                alpha += b[r, p] * b[r, p]
                beta += b[r, q] * b[r, q]
                gamma += b[r, p] * b[r, q]
            if gamma == 0.0 or abs(gamma) <= 1e-15 * math.sqrt(alpha * beta):
                continue
            turned = True
            zeta = (beta - alpha) / (2.0 * gamma)
            t = 1.0 / (abs(zeta) + math.sqrt(1.0 + zeta * zeta))
            if zeta < 0.0:
                t = -t
            c = 1.0 / math.sqrt(1.0 + t * t)
            s = c * t
            for r in range(m):
                bp, bq = b[r, p], b[r, q]
                b[r, p], b[r, q] = c * bp - s * bq, s * bp + c * bq
            for r in range(n):
                vp, vq = v[r, p], v[r, q]
                v[r, p], v[r, q] = c * vp - s * vq, s * vp + c * vq
    return turned


@njit(cache=True)
def _kth_largest(values: np.ndarray, k: int) -> float:
    """The k-th largest of `values` (k from 1), without sorting them in place."""
    bound = math.inf
    found = 0
    while True:
        largest, ties = -math.inf, 0
        for x in values:
            if x < bound:
                if x > largest:
                    largest, ties = x, 1
                elif x == largest:
                    ties += 1
        found += ties
        if found >= k or ties == 0:
            return largest
        bound = largest


def project_step(
    robot: RobotModel, q: np.ndarray, action: np.ndarray, dt: float, table_height: float,
    nullspace_gain: float = 0.5, rng: np.random.Generator | None = None, *,
    nullspace_noise: float = 0.1, nullspace_velocity: np.ndarray | None = None,
    correction_gain: float = 1.0, velocity_scale: float = 1.0,
) -> np.ndarray:
    """One step of Project (King et al. 2015, §V): q_new = q + dt (J⁺(q) a + h(q)), held on the
    manifold.

    action: (v_x, v_y, yaw_rate) planar tool velocity in the base frame (m/s, m/s, rad/s).
    dt: step duration (s). nullspace_gain: rad/s pull back of a joint at its limit (see
    `joint_limit_gradient`). rng: when given, h(q) also gets a random sample
    N(0, nullspace_noise² I) (rad/s) — "h samples the nullspace" (§V); both parts of h are
    projected into the task nullspace, so they move only the arm's self-motion.
    Deterministic given the rng state (draws exactly nq normals per call when rng is given).
    A fresh sample every step makes the self-motion a random walk (jittery joint paths); for
    smooth self-motion draw one `nullspace_velocity` (rad/s, added to h) per action instead
    and pass rng=None.
    A q slightly outside the joint limits is clipped onto them first.

    The step respects joint limits and joint velocity limits (scaled by `velocity_scale`):
      1. joints whose step would cross a position limit are locked to land on it and the task
         is re-solved with the other joints (an SNS-style saturation, Flacco et al. 2012), so a
         joint at its limit does not drag the tool off the manifold;
      2. if any |qdot_j| exceeds its limit, the whole qdot is scaled down uniformly, which keeps
         its direction (the tool moves less but stays on the manifold to first order);
      3. the result is clipped to the joint limits (a no-op up to rounding).
    Compiled (`project_kernel`).
    """
    if len(action) != 3:
        raise ValueError(f"action has {len(action)} values, expected 3: (v_x, v_y, yaw_rate)")
    if not dt > 0:
        raise ValueError(f"dt must be positive, got {dt}")
    extra = np.zeros(robot.nq)
    if rng is not None:
        extra += nullspace_noise * rng.standard_normal(robot.nq)
    if nullspace_velocity is not None:
        extra += nullspace_velocity
    arrays = project_arrays(robot, table_height)
    # Fresh writable arrays: one compiled signature whoever calls.
    return project_kernel(np.array(q, dtype=float), np.array(action, dtype=float),
                          float(dt), extra, *arrays, float(nullspace_gain),  # type: ignore[call-arg]
                          float(correction_gain), float(velocity_scale))


def project_arrays(robot: RobotModel, table_height: float) -> tuple:
    """The robot and manifold arguments of `project_kernel` (after q, action, dt, extra),
    made once per robot and table height (every propagation asks)."""
    by_height = _PROJECT_ARRAYS.setdefault(robot, {})
    arrays = by_height.get(table_height)
    if arrays is None:
        arrays = by_height[table_height] = _project_arrays(robot, table_height)
    return arrays


_PROJECT_ARRAYS: weakref.WeakKeyDictionary[RobotModel, dict[float, tuple]] = (
    weakref.WeakKeyDictionary())
"""`project_arrays` by robot and table height."""


def _project_arrays(robot: RobotModel, table_height: float) -> tuple:
    chain = kernels.compiled_chain(robot)
    return (chain.arrays[:4], chain.tool_joint, chain.tool_local,
            np.array(_up_in_tool(robot.config.push_posture)), push_height(robot, table_height),
            np.array([robot.lower, robot.upper]), np.array(robot.velocity_limits))


@njit(cache=True)
def project_kernel(q: np.ndarray, action: np.ndarray, dt: float, extra: np.ndarray,
                   chain: tuple, tool_joint: int, tool_local: np.ndarray, up: np.ndarray,
                   height: float, limits: np.ndarray, velocity_limits: np.ndarray,
                   nullspace_gain: float, correction_gain: float,
                   velocity_scale: float) -> np.ndarray:
    """`project_step` compiled; `extra` is added to the limit-avoidance term of h
    (`project_into` with arrays of its own)."""
    out = np.empty(q.shape[0])
    project_into(q, action, dt, extra, chain, tool_joint, tool_local, up, height, limits,
                 velocity_limits, nullspace_gain, correction_gain, velocity_scale, out,
                 project_workspace(q.shape[0], chain[0].shape[0]), False)
    return out


@njit(cache=True)
def project_workspace(nq: int, joints: int) -> tuple:
    """The arrays `project_into` works in, for an arm of nq joints on a chain of `joints`
    (`CompiledChain`): made once per propagation, so that a Project step allocates nothing.
    work[1] and work[2] are the tool's pose and Jacobian at the step's q."""
    return (np.empty(nq), np.empty((4, 4)), np.empty((6, nq)), np.empty(6),
            np.empty((4, nq)), np.empty(solver_scratch_size(6, nq)), np.empty(8 * nq + 6),
            np.empty(nq, dtype=np.int64), np.empty((2, nq), dtype=np.bool_),
            np.empty((joints, 4, 4)), np.empty((2, 4, 4)))


@kernels.njit_bare
def project_into(q: np.ndarray, action: np.ndarray, dt: float, extra: np.ndarray,
                 chain: tuple, tool_joint: int, tool_local: np.ndarray, up: np.ndarray,
                 height: float, limits: np.ndarray, velocity_limits: np.ndarray,
                 nullspace_gain: float, correction_gain: float, velocity_scale: float,
                 out: np.ndarray, work: tuple, known: bool) -> None:
    """out = `project_step`, in `work` (`project_workspace`): q held in its limits, the task
    (`build_task`), h the limit-avoidance term plus `extra`, qdot solved with each joint's
    velocity kept within what its limits allow in dt (`_solve_within_limits`), scaled down to
    `velocity_scale` of the velocity limits, and the step clipped to the limits. `known`:
    work[1] and work[2] already hold the tool's pose and Jacobian at q, which is within its
    limits (`propagation.propagate_kernel` has them from the last physics step's kinematics,
    `kernels.tool_from_joints`). Compiled without reference counting (`kernels.njit_bare`):
    it allocates nothing, and its calls would otherwise count every row and tuple it reads."""
    qc, pose, jac, xdot, joint_rows = work[0], work[1], work[2], work[3], work[4]
    h, lo, hi, qdot = joint_rows[0], joint_rows[1], joint_rows[2], joint_rows[3]
    lower, upper = limits[0], limits[1]
    nq = q.shape[0]
    for j in range(nq):
        qc[j] = min(max(q[j], lower[j]), upper[j])
    if not known:
        kernels.tool_kinematics_into(qc, chain[0], chain[1], chain[2], chain[3], tool_joint,
                                     tool_local, pose, jac, work[9], work[10])
    _task_velocity(pose, action, dt, up, height, correction_gain, xdot)
    for j in range(nq):
        h[j] = _limit_pull(qc[j], lower[j], upper[j], nullspace_gain) + extra[j]
        lo[j], hi[j] = (lower[j] - qc[j]) / dt, (upper[j] - qc[j]) / dt
    _solve_within_limits(jac, xdot, h, lo, hi, qdot, work)
    ratio = 0.0
    for j in range(nq):
        ratio = max(ratio, abs(qdot[j]) / velocity_limits[j])
    ratio /= velocity_scale
    for j in range(nq):
        step = qdot[j] / ratio if ratio > 1.0 else qdot[j]
        out[j] = min(max(qc[j] + dt * step, lower[j]), upper[j])


@njit(cache=True)
def _solve_within_limits(jac: np.ndarray, xdot: np.ndarray, h: np.ndarray, lo: np.ndarray,
                         hi: np.ndarray, qdot: np.ndarray, work: tuple) -> None:
    """qdot = `solve_task` kept in [lo, hi]: joints that leave it are locked at the bound and
    the task is re-solved with the remaining joints (at most nq rounds). In `work`
    (`project_workspace`): its rows for the reduced task (rest, the free columns of J, h and
    qdot of the free joints) after the solver's scratch."""
    scratch, sub_rows, free, flags = work[5], work[6], work[7], work[8]
    violating, locked = flags[0], flags[1]
    _solve_into(jac, xdot, h, qdot, scratch)
    m, n = jac.shape
    any_violating = False
    for j in range(n):
        violating[j] = qdot[j] > hi[j] or qdot[j] < lo[j]
        any_violating = any_violating or violating[j]
    if not any_violating:
        return
    locked[:] = False
    rest = sub_rows[:m]
    for _ in range(n):
        for j in range(n):
            if violating[j]:
                qdot[j] = min(max(qdot[j], lo[j]), hi[j])
                locked[j] = True
        nf = _free_joints(locked, free)
        if nf == 0:
            break
        for r in range(m):
            rest[r] = xdot[r]
        for j in range(n):
            if locked[j]:
                for r in range(m):
                    rest[r] -= jac[r, j] * qdot[j]
        end = m + m * nf
        sub = sub_rows[m:end].reshape((m, nf))
        h_free, q_free = sub_rows[end:end + nf], sub_rows[end + nf:end + 2 * nf]
        for c in range(nf):
            h_free[c] = h[free[c]]
            for r in range(m):
                sub[r, c] = jac[r, free[c]]
        _solve_into(sub, rest, h_free, q_free, scratch)
        violating[:] = False
        any_violating = False
        for c in range(nf):
            j = free[c]
            qdot[j] = q_free[c]
            if qdot[j] > hi[j] or qdot[j] < lo[j]:
                violating[j] = any_violating = True
        if not any_violating:
            break
    for j in range(n):
        qdot[j] = min(max(qdot[j], lo[j]), hi[j])


@njit(cache=True)
def _free_joints(locked: np.ndarray, free: np.ndarray) -> int:
    """The joints not `locked` into free[:count]; returns count."""
    count = 0
    for j in range(locked.shape[0]):
        if not locked[j]:
            free[count] = j
            count += 1
    return count


# -- IK onto the manifold --------------------------------------------------------------------


def ik_on_manifold(
    robot: RobotModel, x: float, y: float, yaw: float, table_height: float, q_seed: np.ndarray,
    rng: np.random.Generator | None = None, max_iters: int = 100, *, restarts: int = 20,
    tol: float = 1e-6, min_clearance: float | None = None,
) -> np.ndarray | None:
    """A configuration within joint limits whose tool is at the planar pose (x, y, yaw) on the
    manifold, or None if none is found.

    Solves the 6-D pose (position x, y, push height; orientation Rz(yaw) R0) by Levenberg-
    Marquardt with Sugihara's damping (IEEE T-RO 2011: (JᵀJ + (E + w̄) I) dq = -Jᵀe, E = ½|e|²),
    each iterate clipped to the joint limits. The first attempt starts at `q_seed`; then up to
    `restarts` attempts start at configurations drawn uniformly within the joint limits from
    `rng` (default: a generator seeded with 0, so the answer is deterministic). Converged when
    the position error (m) and the rotation error (rad) are both below `tol`.

    min_clearance: when given, a solution is accepted only if the lowest point of every contact
    shape is at least this far above the table top (m; see `lowest_point`).
    """
    if not all(math.isfinite(v) for v in (x, y, yaw, table_height)):
        raise ValueError(f"IK target must be finite, got x={x}, y={y}, yaw={yaw}, "
                         f"table_height={table_height}")
    rng = np.random.default_rng(0) if rng is None else rng
    p_target = np.array([x, y, push_height(robot, table_height)])
    r_target = target_rotation(robot, yaw)
    for attempt in range(restarts + 1):
        seed = (np.clip(np.asarray(q_seed, dtype=float), robot.lower, robot.upper)
                if attempt == 0 else rng.uniform(robot.lower, robot.upper))
        q = _levenberg_marquardt(robot, seed, p_target, r_target, max_iters, tol)
        if q is None:
            continue
        if min_clearance is not None and \
                lowest_point(robot, q)[0] < table_height + min_clearance:
            continue
        return q
    return None


def _pose_error(robot: RobotModel, q: np.ndarray, p_target: np.ndarray,
                r_target: np.ndarray) -> np.ndarray:
    """[p - p*; log(R R*ᵀ)], base frame: for a small error its rate is the tool twist J qdot."""
    pose = robot.tool_pose(q)
    return np.concatenate([pose[:3, 3] - p_target, pin.log3(pose[:3, :3] @ r_target.T)])


def _levenberg_marquardt(
    robot: RobotModel, q: np.ndarray, p_target: np.ndarray, r_target: np.ndarray,
    max_iters: int, tol: float, damping_floor: float = 1e-4, patience: int = 15,
) -> np.ndarray | None:
    """LM from q; joints at a limit whose step points outward are held there (their column
    dropped) so the others still make full progress. Gives up after `patience` iterations
    without a 1 % cost decrease (a local minimum: better spend the time on a restart)."""
    err = _pose_error(robot, q, p_target, r_target)
    cost = 0.5 * float(err @ err)
    best, since_best = cost, 0
    eye = np.eye(robot.nq)
    for _ in range(max_iters):
        if np.linalg.norm(err[:3]) < tol and np.linalg.norm(err[3:]) < tol:
            return q
        jac = robot.frame_jacobian(q, robot.tool_frame_id)
        damping = (cost + damping_floor) * eye
        step = -np.linalg.solve(jac.T @ jac + damping, jac.T @ err)
        blocked = ((q <= robot.lower) & (step < 0)) | ((q >= robot.upper) & (step > 0))
        if blocked.any():
            jac = jac * ~blocked
            step = -np.linalg.solve(jac.T @ jac + damping, jac.T @ err)
            step[blocked] = 0.0
        q = np.clip(q + step, robot.lower, robot.upper)
        err = _pose_error(robot, q, p_target, r_target)
        cost = 0.5 * float(err @ err)
        if cost < 0.99 * best:
            best, since_best = cost, 0
        else:
            since_best += 1
            if since_best > patience:
                return None
    if np.linalg.norm(err[:3]) < tol and np.linalg.norm(err[3:]) < tol:
        return q
    return None


def default_push_configuration(robot: RobotModel, table_height: float) -> np.ndarray:
    """A pushing configuration: the tool on the manifold at DEFAULT_PUSH_TARGET (x 0.5 m, y 0,
    yaw 0), no contact shape below the table top, away from the joint limits. The approach
    target for starts off the manifold.

    IK from the home configuration (seeded generator: deterministic), then SETTLE_STEPS
    zero-action `project_step`s whose nullspace term moves the arm along its self-motion away
    from the joint limits (the IK answer tends to sit on one) with the tool held still.
    Cached per robot and table height; returned read-only."""
    per_robot = _default_cache.setdefault(robot, {})
    key = float(table_height)
    if key not in per_robot:
        x, y, yaw = DEFAULT_PUSH_TARGET
        posture = robot.config.push_posture
        q = ik_on_manifold(robot, x, y, yaw, key, robot.home, np.random.default_rng(0),
                           max_iters=200, restarts=50, min_clearance=0.0)
        if q is not None:
            moved = q
            for _ in range(SETTLE_STEPS):
                moved = project_step(robot, moved, np.zeros(3), 0.02, key, nullspace_gain=1.0)
            # The self-motion drifts the tool by second-order terms (~0.1 mm): re-solve from there.
            settled = ik_on_manifold(robot, x, y, yaw, key, moved, restarts=0, min_clearance=0.0)
            q = q if settled is None else settled
        if q is None:
            raise RobotModelError(
                f"robot '{robot.name}': pushing posture (height {posture.height} m, roll "
                f"{posture.roll}, pitch {posture.pitch}) is unreachable at x={x}, y={y}, "
                f"yaw={yaw} above a table at height {key} m without a link below the table; "
                f"choose another push_posture in the robot config")
        q = np.array(q)
        q.setflags(write=False)
        per_robot[key] = q
    return per_robot[key]
