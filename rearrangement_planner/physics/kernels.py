"""Compiled contact geometry and kinematics (the fast core under `Physics.step` and
the Project step): the signed distance, the contact point and the contact normal between a
capsule (the arm's contact shapes; a sphere is a capsule of length 0) and an upright prism of
the scene (an object's box or cylinder, an obstacle box, the table slab), the penetration of
two prisms, and the forward kinematics of the contact shapes and the tool, with the tool's
Jacobian (`CompiledChain`, `tool_kinematics`, `tool_from_joints`), in Numba.

A capsule is a segment swept by a ball. The signed distance to a convex set is a convex
function of the point, so along the capsule's axis p(t) = a + t (b - a), t in [0, 1],
sd(p(t)) is convex in t; its minimum (golden-section search, interval below 1e-12) is the
axis point nearest to the prism, or deepest inside it, and

    signed distance = min_t sd(p(t)) - radius        (the penetration depth when negative)
    normal          = grad sd at that point          (unit, out of the prism, towards the arm)
    prism point     = the prism's surface point nearest to it
    capsule point   = axis point - radius * normal

exactly what GJK / EPA compute for a capsule against a convex body while its axis stays
outside the prism, the regime of contact (the physics refuses a step that ends more than a few
mm deep). With the axis inside, the result is the depth of the axis' deepest point: a lower
bound of the true penetration depth. Where the minimum is not unique (the capsule's side
parallel to a face) any minimiser is a valid contact. Units: m, rad; frames: the robot base
frame, prisms upright (yaw about z only).
"""

from __future__ import annotations

import math
import weakref
from typing import TYPE_CHECKING, Any, cast

import numpy as np
from numba import njit

if TYPE_CHECKING:
    from rearrangement_planner.model.robot import RobotModel

BOX, CYLINDER = 0, 1
"""Prism kinds: a box (dims = half extents x, y, z) or a cylinder about its z axis (dims =
radius, half height, unused)."""

njit_bare = cast(Any, njit)(cache=True, _nrt=False)
"""`njit` for a kernel that allocates no array, nor does any kernel it calls: compiled
without Numba's reference counting (an atomic count up and down for every array it takes and
every view it makes, which was a fifth of a physics step). A kernel that allocates fails to
compile under it ("NRT required"). A kernel that returns a view and is called from kernels of
both kinds must be inlined (`inline="always"`): Numba compiles it once per kind, but its
cache keys the machine code by the argument types alone, so a caller may be linked with the
other kind's code, and a view counted by one kind and not the other frees its buffer early."""

Vec3 = tuple[float, float, float]
"""A point or direction as three floats (a tuple: no allocation in compiled code)."""
Vector = np.ndarray | Vec3
"""Three floats (a point, a direction, a prism's dims) as an array (3,) or, from compiled
callers, a `Vec3`."""

_GOLDEN = 0.6180339887498949
_ITERATIONS = 60                     # 0.618**60 = 3e-13 of the axis
_RESOLUTION = 1e-10
"""m: the golden-section bracket along a capsule's axis ends below this (at most _ITERATIONS
steps); the distance then errs by at most this, the axis' slope being at most 1."""


@njit(cache=True)
def _box_sd(qx: float, qy: float, qz: float, hx: float, hy: float, hz: float) -> float:
    dx, dy, dz = abs(qx) - hx, abs(qy) - hy, abs(qz) - hz
    ox, oy, oz = max(dx, 0.0), max(dy, 0.0), max(dz, 0.0)
    outside = math.sqrt(ox * ox + oy * oy + oz * oz)
    return outside + min(max(dx, max(dy, dz)), 0.0)


@njit(cache=True)
def _cylinder_sd(qx: float, qy: float, qz: float, radius: float, hz: float) -> float:
    dr, dz = math.sqrt(qx * qx + qy * qy) - radius, abs(qz) - hz
    ox, oz = max(dr, 0.0), max(dz, 0.0)
    return math.sqrt(ox * ox + oz * oz) + min(max(dr, dz), 0.0)


@njit(cache=True)
def _sd_along(kind: int, qa: Vec3, d: Vec3, t: float, dims: Vector) -> float:
    """The prism's signed distance at the axis point qa + t d (prism frame)."""
    qx, qy, qz = qa[0] + t * d[0], qa[1] + t * d[1], qa[2] + t * d[2]
    if kind == BOX:
        return _box_sd(qx, qy, qz, dims[0], dims[1], dims[2])
    return _cylinder_sd(qx, qy, qz, dims[0], dims[1])


@njit(cache=True)
def _box_surface(q: Vec3, h: Vector) -> tuple[Vec3, Vec3]:
    """Nearest surface point and outward normal of the box with half extents h (local)."""
    inside = abs(q[0]) <= h[0] and abs(q[1]) <= h[1] and abs(q[2]) <= h[2]
    if not inside:
        px, py = min(max(q[0], -h[0]), h[0]), min(max(q[1], -h[1]), h[1])
        pz = min(max(q[2], -h[2]), h[2])
        nx, ny, nz = q[0] - px, q[1] - py, q[2] - pz
        norm = math.sqrt(nx * nx + ny * ny + nz * nz)
        return (px, py, pz), (nx / norm, ny / norm, nz / norm)
    axis, best = 0, -math.inf
    for i in range(3):
        gap = abs(q[i]) - h[i]
        if gap > best:
            axis, best = i, gap
    sign = 1.0 if q[axis] >= 0.0 else -1.0
    if axis == 0:
        return (sign * h[0], q[1], q[2]), (sign, 0.0, 0.0)
    if axis == 1:
        return (q[0], sign * h[1], q[2]), (0.0, sign, 0.0)
    return (q[0], q[1], sign * h[2]), (0.0, 0.0, sign)


@njit(cache=True)
def _cylinder_surface(q: Vec3, radius: float, hz: float) -> tuple[Vec3, Vec3]:
    """Nearest surface point and outward normal of the z-axis cylinder (local)."""
    rho = math.sqrt(q[0] * q[0] + q[1] * q[1])
    ux, uy = (q[0] / rho, q[1] / rho) if rho > 1e-15 else (1.0, 0.0)
    sz = 1.0 if q[2] >= 0.0 else -1.0
    dr, dz = rho - radius, abs(q[2]) - hz
    if dr > 0.0 or dz > 0.0:                       # outside: clamp radially and along z
        r_clamped = min(rho, radius)
        z_clamped = min(max(q[2], -hz), hz)
        px, py, pz = ux * r_clamped, uy * r_clamped, z_clamped
        nx, ny, nz = q[0] - px, q[1] - py, q[2] - pz
        norm = math.sqrt(nx * nx + ny * ny + nz * nz)
        return (px, py, pz), (nx / norm, ny / norm, nz / norm)
    if dr > dz:                                    # inside, nearer the side
        return (ux * radius, uy * radius, q[2]), (ux, uy, 0.0)
    return (q[0], q[1], sz * hz), (0.0, 0.0, sz)   # inside, nearer a cap


@njit_bare
def capsule_prism(a: Vector, b: Vector, radius: float, kind: int,
                  centre: Vector, yaw: float, dims: Vector,
                  out_point: np.ndarray, out_normal: np.ndarray) -> float:
    """Signed distance (m) between the capsule with axis a-b and `radius` and the upright
    prism `kind` (BOX or CYLINDER) centred at `centre` and turned by `yaw`; writes the prism's
    contact point into `out_point` and the unit normal (out of the prism, towards the capsule)
    into `out_normal`, both in the world frame (module doc)."""
    return capsule_prism_below(a, b, radius, math.inf, kind, centre, yaw, dims, out_point,
                               out_normal)


@njit_bare
def capsule_prism_below(a: Vector, b: Vector, radius: float, limit: float, kind: int,
                        centre: Vector, yaw: float, dims: Vector,
                        out_point: np.ndarray, out_normal: np.ndarray) -> float:
    """`capsule_prism` where only distances below `limit` matter: when a lower bound already
    reaches `limit`, that bound is returned (>= limit, not the distance; the outputs
    untouched; `_axis_minimum`)."""
    c, s = math.cos(yaw), math.sin(yaw)
    qa, d = _axis_in_prism(a, b, centre, c, s)
    best_t, best = _axis_minimum(kind, qa, d, radius, limit, dims)
    if best_t < 0.0:
        return best
    q = (qa[0] + best_t * d[0], qa[1] + best_t * d[1], qa[2] + best_t * d[2])
    _surface_in_world(kind, q, dims, centre, c, s, out_point, out_normal)
    return best - radius


@njit_bare
def capsule_prism_depth_below(a: Vector, b: Vector, radius: float, limit: float, kind: int,
                              centre: Vector, yaw: float, dims: Vector) -> float:
    """`capsule_prism_below`'s value alone: the signed distance, or a bound >= `limit`."""
    qa, d = _axis_in_prism(a, b, centre, math.cos(yaw), math.sin(yaw))
    best_t, best = _axis_minimum(kind, qa, d, radius, limit, dims)
    return best if best_t < 0.0 else best - radius


@njit_bare
def _axis_minimum(kind: int, qa: Vec3, d: Vec3, radius: float, limit: float,
                  dims: Vector) -> tuple[float, float]:
    """(t, sd(q(t))) at the minimum of the prism's signed distance along the capsule's axis
    q(t) = qa + t d, t in [0, 1]; or (-1, a lower bound of the capsule's distance) as soon as
    a bound reaches `limit`. The bounds: sd is 1-Lipschitz in space, so along the axis
    (length L) it is L-Lipschitz in t. First, from samples at t = 0, 1/2, 1 the minimum over
    each half is at least (f(t_i) + f(t_j) - L/2) / 2 (Piyavskii's bound). Then, within the
    golden-section search: sd is convex along the axis, so its minimum lies in the bracket
    [lo, hi], where it is at least either sample's value minus L (hi - lo)
    (`_bracket_bound`)."""
    if limit < math.inf:
        half = 0.5 * math.sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2])
        f0, f_mid = _sd_along(kind, qa, d, 0.0, dims), _sd_along(kind, qa, d, 0.5, dims)
        f1 = _sd_along(kind, qa, d, 1.0, dims)
        bound = 0.5 * (min(f0, f1) + f_mid - half) - radius
        if bound >= limit:
            return -1.0, bound
    lo, hi = 0.0, 1.0
    t1, t2 = hi - _GOLDEN, _GOLDEN
    f1, f2 = _sd_along(kind, qa, d, t1, dims), _sd_along(kind, qa, d, t2, dims)
    # Stop once the bracket is shorter than _RESOLUTION along the axis (or after _ITERATIONS).
    length = math.sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2])
    iterations = _ITERATIONS
    if length > 0.0:
        iterations = min(_ITERATIONS, max(0, int(math.ceil(
            math.log(_RESOLUTION / length) / math.log(_GOLDEN)))))
    for _ in range(iterations):
        lo, hi, t1, t2, f1, f2 = _golden_step(kind, qa, d, dims, lo, hi, t1, t2, f1, f2)
        if limit < math.inf:
            bound = _bracket_bound(f1, f2, hi - lo, length) - radius
            if bound >= limit:
                return -1.0, bound
    best_t, best = (t1, f1) if f1 <= f2 else (t2, f2)
    for t in (0.0, 1.0):                           # a flat minimum may sit at an end
        f = _sd_along(kind, qa, d, t, dims)
        if f < best:
            best_t, best = t, f
    return best_t, best


@njit(cache=True, inline="always")
def _surface_in_world(kind: int, q: Vec3, dims: Vector, centre: Vector, c: float,
                      s: float, out_point: np.ndarray, out_normal: np.ndarray) -> None:
    """The prism's surface point nearest the prism-frame point q and its outward normal, in
    the world frame."""
    if kind == BOX:
        point, normal = _box_surface(q, dims)
    else:
        point, normal = _cylinder_surface(q, dims[0], dims[1])
    out_point[0] = centre[0] + c * point[0] - s * point[1]
    out_point[1] = centre[1] + s * point[0] + c * point[1]
    out_point[2] = centre[2] + point[2]
    out_normal[0] = c * normal[0] - s * normal[1]
    out_normal[1] = s * normal[0] + c * normal[1]
    out_normal[2] = normal[2]


@njit_bare
def capsule_prism_bound(a: Vector, b: Vector, radius: float, kind: int,
                        centre: Vector, yaw: float, dims: Vector,
                        limit: float = math.inf) -> float:
    """A lower bound (m) of `capsule_prism`'s signed distance, at most BOUND_RESOLUTION below
    it, or sooner any bound above `limit`: the same golden-section search along the axis,
    stopped once its bracket is shorter than BOUND_RESOLUTION (`_bracket_bound`)."""
    qa, d = _axis_in_prism(a, b, centre, math.cos(yaw), math.sin(yaw))
    length = math.sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2])
    if length <= BOUND_RESOLUTION:
        return _sd_along(kind, qa, d, 0.0, dims) - length - radius
    lo, hi = 0.0, 1.0
    t1, t2 = hi - _GOLDEN, _GOLDEN
    f1, f2 = _sd_along(kind, qa, d, t1, dims), _sd_along(kind, qa, d, t2, dims)
    while (hi - lo) * length > BOUND_RESOLUTION:
        lo, hi, t1, t2, f1, f2 = _golden_step(kind, qa, d, dims, lo, hi, t1, t2, f1, f2)
        if _bracket_bound(f1, f2, hi - lo, length) - radius > limit:
            break
    return _bracket_bound(f1, f2, hi - lo, length) - radius


@njit(cache=True, inline="always")
def _axis_in_prism(a: Vector, b: Vector, centre: Vector, c: float,
                   s: float) -> tuple[Vec3, Vec3]:
    """The capsule's axis a-b in the frame of a prism at `centre` turned by (cos, sin) = (c, s):
    q(t) = qa + t d, returned as (qa, d). Tuples, not arrays: they live on the stack, and an
    array allocated per call cost more than the distance (`rearrangement-bench physics`)."""
    ax, ay = a[0] - centre[0], a[1] - centre[1]
    bx, by = b[0] - centre[0], b[1] - centre[1]
    qa = (c * ax + s * ay, -s * ax + c * ay, a[2] - centre[2])
    qb = (c * bx + s * by, -s * bx + c * by, b[2] - centre[2])
    return qa, (qb[0] - qa[0], qb[1] - qa[1], qb[2] - qa[2])


@njit(cache=True, inline="always")
def _golden_step(kind: int, qa: Vec3, d: Vec3, dims: Vector, lo: float,
                 hi: float, t1: float, t2: float, f1: float,
                 f2: float) -> tuple[float, float, float, float, float, float]:
    """One golden-section step along the axis: the bracket [lo, hi] with samples t1 < t2
    (values f1, f2) shrinks towards the lower sample, which one new sample joins."""
    if f1 <= f2:
        hi, t2, f2 = t2, t1, f1
        t1 = hi - _GOLDEN * (hi - lo)
        f1 = _sd_along(kind, qa, d, t1, dims)
    else:
        lo, t1, f1 = t1, t2, f2
        t2 = lo + _GOLDEN * (hi - lo)
        f2 = _sd_along(kind, qa, d, t2, dims)
    return lo, hi, t1, t2, f1, f2


@njit(cache=True, inline="always")
def _bracket_bound(f1: float, f2: float, width: float, length: float) -> float:
    """A lower bound of a convex, `length`-Lipschitz function's minimum over a bracket of
    `width` holding it and both samples f1, f2: no point there is farther from either."""
    return max(f1, f2) - width * length


BOUND_RESOLUTION = 1e-3
"""m: how far below the distance `capsule_prism_bound` may be."""


# -- forward kinematics of the contact shapes -----------------------------------------------------


@njit(cache=True, inline="always")
def _product(a: np.ndarray, ai: int, b: np.ndarray, bi: int, out: np.ndarray, oi: int) -> None:
    """out[oi] = a[ai] @ b[bi] for stacks of 4x4 rigid transforms (last rows 0 0 0 1),
    written out with explicit indices (a BLAS call, or even an array view, per 4x4 product
    costs more than the product)."""
    for i in range(3):
        a0, a1, a2, a3 = a[ai, i, 0], a[ai, i, 1], a[ai, i, 2], a[ai, i, 3]
        for j in range(3):
            out[oi, i, j] = a0 * b[bi, 0, j] + a1 * b[bi, 1, j] + a2 * b[bi, 2, j]
        out[oi, i, 3] = a0 * b[bi, 0, 3] + a1 * b[bi, 1, 3] + a2 * b[bi, 2, 3] + a3
    out[oi, 3, 0] = out[oi, 3, 1] = out[oi, 3, 2] = 0.0
    out[oi, 3, 3] = 1.0


@njit(cache=True)
def joint_poses(q: np.ndarray, parents: np.ndarray, placements: np.ndarray, axes: np.ndarray,
                q_index: np.ndarray, world: np.ndarray) -> None:
    """World poses (J, 4, 4) of the joints at the planning configuration `q`, into `world`:
    joint j's pose is its parent's times `placements[j]` times the rotation by q[q_index[j]]
    about the unit `axes[j]` (Rodrigues; no rotation where q_index is -1: a joint held fixed,
    its placement already at its value). Joints are ordered parents first; joint 0 is the
    base (identity)."""
    joint_poses_into(q, parents, placements, axes, q_index, world, np.empty((2, 4, 4)))


@njit_bare
def joint_poses_into(q: np.ndarray, parents: np.ndarray, placements: np.ndarray,
                     axes: np.ndarray, q_index: np.ndarray, world: np.ndarray,
                     turn: np.ndarray) -> None:
    """`joint_poses` with its scratch (2, 4, 4) given: a loop of physics steps allocates it
    once."""
    for i in range(4):
        for j in range(4):
            world[0, i, j] = 1.0 if i == j else 0.0
    for j in range(1, parents.shape[0]):
        if q_index[j] < 0:
            _product(world, parents[j], placements, j, world, j)
            continue
        x, y, z = axes[j, 0], axes[j, 1], axes[j, 2]
        c, s = math.cos(q[q_index[j]]), math.sin(q[q_index[j]])
        v = 1.0 - c
        turn[1, 0, 0], turn[1, 0, 1], turn[1, 0, 2] = c + x * x * v, x * y * v - z * s, \
            x * z * v + y * s
        turn[1, 1, 0], turn[1, 1, 1], turn[1, 1, 2] = y * x * v + z * s, c + y * y * v, \
            y * z * v - x * s
        turn[1, 2, 0], turn[1, 2, 1], turn[1, 2, 2] = z * x * v - y * s, z * y * v + x * s, \
            c + z * z * v
        turn[1, 0, 3] = turn[1, 1, 3] = turn[1, 2, 3] = 0.0
        _product(placements, j, turn, 1, turn, 0)
        _product(world, parents[j], turn, 0, world, j)


@njit(cache=True)
def shape_poses(q: np.ndarray, parents: np.ndarray, placements: np.ndarray, axes: np.ndarray,
                q_index: np.ndarray, shape_joint: np.ndarray, shape_local: np.ndarray,
                out: np.ndarray) -> None:
    """World poses (S, 4, 4) of the contact shapes at the planning configuration `q`, into
    `out`: shape s sits at `shape_local[s]` on joint shape_joint[s] (`joint_poses`)."""
    shape_poses_into(q, parents, placements, axes, q_index, shape_joint, shape_local, out,
                     np.empty((parents.shape[0], 4, 4)), np.empty((2, 4, 4)))


@njit_bare
def shape_poses_into(q: np.ndarray, parents: np.ndarray, placements: np.ndarray,
                     axes: np.ndarray, q_index: np.ndarray, shape_joint: np.ndarray,
                     shape_local: np.ndarray, out: np.ndarray, world: np.ndarray,
                     turn: np.ndarray) -> None:
    """`shape_poses` with its scratch given: the joints' poses (J, 4, 4) and (2, 4, 4)."""
    joint_poses_into(q, parents, placements, axes, q_index, world, turn)
    for s in range(shape_joint.shape[0]):
        _product(world, shape_joint[s], shape_local, s, out, s)


class CompiledChain:
    """A robot's serial chain as arrays for `shape_poses`, from its Pinocchio model: revolute
    planning joints turn about their axes, every other joint is held where Pinocchio's neutral
    configuration puts it (as `RobotModel` holds it)."""

    def __init__(self, robot: RobotModel):
        import pinocchio as pin

        model = robot.model
        data = model.createData()
        pin.forwardKinematics(model, data, pin.neutral(model))
        planned = {int(model.joints[model.getJointId(n)].idx_q): k
                   for k, n in enumerate(robot.joint_names)}
        n = model.njoints
        self.parents = np.array(model.parents, dtype=np.int64)
        self.placements = np.tile(np.eye(4), (n, 1, 1))
        self.axes = np.zeros((n, 3))
        self.q_index = np.full(n, -1, dtype=np.int64)
        for j in range(1, n):
            joint = model.joints[j]
            index = planned.get(int(joint.idx_q), -1) if joint.nq == 1 else -1
            if index < 0:
                self.placements[j] = data.liMi[j].homogeneous
                continue
            self.placements[j] = model.jointPlacements[j].homogeneous
            self.axes[j] = _revolute_axis(joint)
            self.q_index[j] = index
        frames = [model.frames[robot.frame_id(s.link)] for s in robot.contact_shapes]
        self.shape_joint = np.array([f.parentJoint for f in frames], dtype=np.int64)
        self.shape_local = np.array([f.placement.homogeneous @ s.offset
                                     for f, s in zip(frames, robot.contact_shapes, strict=True)])
        tool = model.frames[robot.tool_frame_id]
        self.tool_joint = int(tool.parentJoint)
        self.tool_local = np.ascontiguousarray(tool.placement.homogeneous)
        self.arrays = (self.parents, self.placements, self.axes, self.q_index,
                       self.shape_joint, self.shape_local)
        """The `shape_poses` arguments after q."""

    def shape_poses(self, q: np.ndarray) -> np.ndarray:
        out = np.empty((len(self.shape_joint), 4, 4))
        shape_poses(np.asarray(q, dtype=float), self.parents, self.placements, self.axes,
                    self.q_index, self.shape_joint, self.shape_local, out)
        return out


_chains: weakref.WeakKeyDictionary[RobotModel, CompiledChain] = weakref.WeakKeyDictionary()


def compiled_chain(robot: RobotModel) -> CompiledChain:
    """The `CompiledChain` of a robot model, built once per model."""
    chain = _chains.get(robot)
    if chain is None:
        chain = _chains[robot] = CompiledChain(robot)
    return chain


@njit(cache=True)
def tool_kinematics(q: np.ndarray, parents: np.ndarray, placements: np.ndarray,
                    axes: np.ndarray, q_index: np.ndarray, tool_joint: int,
                    tool_local: np.ndarray, pose: np.ndarray, jac: np.ndarray) -> None:
    """The tool frame's pose (4, 4) and its Jacobian (6, nq) [linear; angular] at its origin
    in base-frame axes (Pinocchio's LOCAL_WORLD_ALIGNED) at q (`tool_from_joints`)."""
    tool_kinematics_into(q, parents, placements, axes, q_index, tool_joint, tool_local, pose,
                         jac, np.empty((parents.shape[0], 4, 4)), np.empty((2, 4, 4)))


@njit_bare
def tool_kinematics_into(q: np.ndarray, parents: np.ndarray, placements: np.ndarray,
                         axes: np.ndarray, q_index: np.ndarray, tool_joint: int,
                         tool_local: np.ndarray, pose: np.ndarray, jac: np.ndarray,
                         world: np.ndarray, turn: np.ndarray) -> None:
    """`tool_kinematics` with the scratch of `joint_poses_into` given: the joints' poses (J, 4,
    4), which hold those at q afterwards, and (2, 4, 4)."""
    joint_poses_into(q, parents, placements, axes, q_index, world, turn)
    tool_from_joints(world, parents, axes, q_index, tool_joint, tool_local, pose, jac)


@njit_bare
def tool_from_joints(world: np.ndarray, parents: np.ndarray, axes: np.ndarray,
                     q_index: np.ndarray, tool_joint: int, tool_local: np.ndarray,
                     pose: np.ndarray, jac: np.ndarray) -> None:
    """`tool_kinematics` from the joints' poses `world` (J, 4, 4) at q (`joint_poses`), without
    computing them again: a revolute joint j of unit world axis w through o_j moves the tool
    origin p at w x (p - o_j) and turns it at w. The same numbers as from q."""
    _product(world, tool_joint, tool_local.reshape((1, 4, 4)), 0, pose.reshape((1, 4, 4)), 0)
    jac[:] = 0.0
    j = tool_joint
    while j > 0:
        k = q_index[j]
        if k >= 0:
            w = (world[j, 0, 0] * axes[j, 0] + world[j, 0, 1] * axes[j, 1]
                 + world[j, 0, 2] * axes[j, 2],
                 world[j, 1, 0] * axes[j, 0] + world[j, 1, 1] * axes[j, 1]
                 + world[j, 1, 2] * axes[j, 2],
                 world[j, 2, 0] * axes[j, 0] + world[j, 2, 1] * axes[j, 1]
                 + world[j, 2, 2] * axes[j, 2])
            rx, ry, rz = (pose[0, 3] - world[j, 0, 3], pose[1, 3] - world[j, 1, 3],
                          pose[2, 3] - world[j, 2, 3])
            jac[0, k] = w[1] * rz - w[2] * ry
            jac[1, k] = w[2] * rx - w[0] * rz
            jac[2, k] = w[0] * ry - w[1] * rx
            jac[3, k], jac[4, k], jac[5, k] = w[0], w[1], w[2]
        j = parents[j]


def _revolute_axis(joint: Any) -> np.ndarray:
    """The unit axis of a revolute Pinocchio joint model (RX, RY, RZ or unaligned)."""
    name = joint.shortname()
    for suffix, axis in (("RX", (1.0, 0.0, 0.0)), ("RY", (0.0, 1.0, 0.0)),
                         ("RZ", (0.0, 0.0, 1.0))):
        if name == f"JointModel{suffix}":
            return np.array(axis)
    if name == "JointModelRevoluteUnaligned":
        return np.asarray(joint.extract().axis, dtype=float)
    raise NotImplementedError(f"compiled kinematics: joint type {name} (revolute joints only)")


# -- prisms against each other, broad phase ------------------------------------------------------


@njit_bare
def prism_penetration(kind_a: int, size_a: np.ndarray, xa: float, ya: float, yaw_a: float,
                      kind_b: int, size_b: np.ndarray, xb: float, yb: float,
                      yaw_b: float) -> float:
    """Penetration depth (m) of two upright prisms standing on the same plane; <= 0 when they
    are apart (then minus a lower bound of the gap: the exact gap for disk-disk and
    rectangle-disk, the largest separating-axis gap for rectangles). `size_*` are the FULL
    extents (x, y, z) (a cylinder's is (2r, 2r, h)); the 3D depth is min(footprint depth,
    lower height): the Minkowski difference of P1 x [0, h1] and P2 x [0, h2] is
    (P1 - P2) x [-h2, h1] and the origin lies at z = 0 in it."""
    dx, dy = xb - xa, yb - ya
    if kind_a == CYLINDER and kind_b == CYLINDER:
        depth = 0.5 * (size_a[0] + size_b[0]) - math.hypot(dx, dy)
    elif kind_a == CYLINDER or kind_b == CYLINDER:
        # rectangle vs disk: the disk centre in the rectangle frame, then its closest point.
        if kind_a == CYLINDER:
            rect, rect_yaw, r = size_b, yaw_b, 0.5 * size_a[0]
            dx, dy = -dx, -dy
        else:
            rect, rect_yaw, r = size_a, yaw_a, 0.5 * size_b[0]
        c, s = math.cos(rect_yaw), math.sin(rect_yaw)
        qx = abs(c * dx + s * dy) - 0.5 * rect[0]
        qy = abs(-s * dx + c * dy) - 0.5 * rect[1]
        if qx > 0.0 or qy > 0.0:
            depth = r - math.hypot(max(qx, 0.0), max(qy, 0.0))
        else:   # disk centre inside the rectangle: leave through the nearest edge
            depth = r - max(qx, qy)
    else:
        # Two rectangles: separating-axis theorem over the four edge normals; for convex
        # polygons the smallest overlap along a face normal is the exact penetration depth.
        ca, sa, cb, sb = math.cos(yaw_a), math.sin(yaw_a), math.cos(yaw_b), math.sin(yaw_b)
        ha, wa, hb, wb = 0.5 * size_a[0], 0.5 * size_a[1], 0.5 * size_b[0], 0.5 * size_b[1]
        depth = math.inf
        for ax, ay in ((ca, sa), (-sa, ca), (cb, sb), (-sb, cb)):
            extent_a = ha * abs(ca * ax + sa * ay) + wa * abs(-sa * ax + ca * ay)
            extent_b = hb * abs(cb * ax + sb * ay) + wb * abs(-sb * ax + cb * ay)
            depth = min(depth, extent_a + extent_b - abs(dx * ax + dy * ay))
    return min(depth, size_a[2], size_b[2])


@njit_bare
def any_prism_overlap(kinds: np.ndarray, sizes: np.ndarray, poses: np.ndarray,
                      first: np.ndarray, second: np.ndarray, limit2: np.ndarray,
                      tol: float) -> bool:
    """Whether any pair (first[k], second[k]) of upright prisms (`prism_penetration`'s kinds,
    full sizes and planar poses by row) penetrates deeper than `tol` (m); a pair is tested
    only when its centres are nearer than the square root of limit2[k] (the sum of their
    footprint radii, squared)."""
    for k in range(first.shape[0]):
        i, j = first[k], second[k]
        dx = poses[i, 0] - poses[j, 0]
        dy = poses[i, 1] - poses[j, 1]
        if dx * dx + dy * dy < limit2[k] and prism_penetration(
                kinds[i], sizes[i], poses[i, 0], poses[i, 1], poses[i, 2], kinds[j], sizes[j],
                poses[j, 0], poses[j, 1], poses[j, 2]) > tol:
            return True
    return False


@njit_bare
def near_prism(a: Vector, b: Vector, grow: float, kind: int, centre: Vector,
               dims: Vector) -> bool:
    """Broad phase: the axis-aligned box of segment a-b grown by `grow` overlaps the box of the
    upright prism's bounding circle and height (dims as in `capsule_prism`)."""
    if kind == BOX:
        reach, half_z = math.sqrt(dims[0] ** 2 + dims[1] ** 2), dims[2]
    else:
        reach, half_z = dims[0], dims[1]
    return not (min(a[0], b[0]) - grow > centre[0] + reach
                or max(a[0], b[0]) + grow < centre[0] - reach
                or min(a[1], b[1]) - grow > centre[1] + reach
                or max(a[1], b[1]) + grow < centre[1] - reach
                or min(a[2], b[2]) - grow > centre[2] + half_z
                or max(a[2], b[2]) + grow < centre[2] - half_z)


@njit(cache=True, inline="always")
def segment(shape_poses: np.ndarray, s: int, half_length: float) -> tuple[Vec3, Vec3]:
    """End points (a, b) of contact shape s's axis (its pose's z, `half_length` each way)."""
    x, y, z = (shape_poses[s, 0, 2] * half_length, shape_poses[s, 1, 2] * half_length,
               shape_poses[s, 2, 2] * half_length)
    return ((shape_poses[s, 0, 3] - x, shape_poses[s, 1, 3] - y, shape_poses[s, 2, 3] - z),
            (shape_poses[s, 0, 3] + x, shape_poses[s, 1, 3] + y, shape_poses[s, 2, 3] + z))


# -- object-object contacts on the table -------------------------------------------------------


@njit(cache=True)
def _box_vertices(size: np.ndarray, x: float, y: float, yaw: float, out: np.ndarray) -> None:
    """The footprint rectangle's corners (4, 2), counter-clockwise from (-x, -y) in its frame;
    edge k runs from corner k to corner k + 1 with outward normal R(yaw) (0, -1), (1, 0),
    (0, 1), (-1, 0)."""
    c, s = math.cos(yaw), math.sin(yaw)
    hx, hy = 0.5 * size[0], 0.5 * size[1]
    for k, (lx, ly) in enumerate(((-hx, -hy), (hx, -hy), (hx, hy), (-hx, hy))):
        out[k, 0] = x + c * lx - s * ly
        out[k, 1] = y + s * lx + c * ly


@njit(cache=True)
def _edge_normal(vertices: np.ndarray, k: int) -> tuple[float, float]:
    """The outward unit normal of edge k of a counter-clockwise polygon."""
    ax, ay = vertices[k]
    bx, by = vertices[(k + 1) % vertices.shape[0]]
    ex, ey = bx - ax, by - ay
    n = math.hypot(ex, ey)
    return ey / n, -ex / n


@njit(cache=True)
def _max_separation(ref: np.ndarray, inc: np.ndarray) -> tuple[int, float]:
    """The edge of `ref` along whose outward normal `inc` lies farthest out, and how far
    (the separating-axis distance of the two rectangles over ref's edge normals)."""
    best_k, best = 0, -math.inf
    for k in range(4):
        nx, ny = _edge_normal(ref, k)
        lowest = math.inf
        for v in range(4):
            lowest = min(lowest, nx * (inc[v, 0] - ref[k, 0]) + ny * (inc[v, 1] - ref[k, 1]))
        if lowest > best:
            best_k, best = k, lowest
    return best_k, best


@njit(cache=True)
def _box_box_contacts(va: np.ndarray, vb: np.ndarray, margin: float, points: np.ndarray,
                      normals: np.ndarray, gaps: np.ndarray) -> int:
    """Up to two contacts of rectangles a and b (corners `va`, `vb`), normals from a into b:
    the reference face is the edge of largest separation (Box2D's b2CollidePolygons, after
    Catto's GDC 2007 notes); the incident edge of the other rectangle, clipped to the
    reference face's side planes, gives the points whose separation is within `margin`."""
    ka, sep_a = _max_separation(va, vb)
    kb, sep_b = _max_separation(vb, va)
    if max(sep_a, sep_b) > margin:
        return 0
    flip = sep_b > sep_a + 1e-6
    ref, inc, k = (vb, va, kb) if flip else (va, vb, ka)
    nx, ny = _edge_normal(ref, k)
    # The incident edge: the one whose normal opposes the reference normal most.
    best, j = math.inf, 0
    for e in range(4):
        ex, ey = _edge_normal(inc, e)
        if ex * nx + ey * ny < best:
            best, j = ex * nx + ey * ny, e
    r1, r2 = ref[k], ref[(k + 1) % 4]
    tx, ty = r2[0] - r1[0], r2[1] - r1[1]
    length = math.hypot(tx, ty)
    tx, ty = tx / length, ty / length
    w1x, w1y = inc[j, 0], inc[j, 1]
    w2x, w2y = inc[(j + 1) % 4, 0], inc[(j + 1) % 4, 1]
    # Clip the incident segment to 0 <= t . (w - r1) <= length.
    s1 = tx * (w1x - r1[0]) + ty * (w1y - r1[1])
    s2 = tx * (w2x - r1[0]) + ty * (w2y - r1[1])
    count = 0
    for bound, sign in ((0.0, 1.0), (length, -1.0)):
        d1, d2 = sign * (s1 - bound), sign * (s2 - bound)
        if d1 < 0.0 and d2 < 0.0:
            return 0
        if d1 < 0.0 or d2 < 0.0:
            f = d1 / (d1 - d2)
            px, py = w1x + f * (w2x - w1x), w1y + f * (w2y - w1y)
            if d1 < 0.0:
                w1x, w1y = px, py
            else:
                w2x, w2y = px, py
            s1 = tx * (w1x - r1[0]) + ty * (w1y - r1[1])
            s2 = tx * (w2x - r1[0]) + ty * (w2y - r1[1])
    for px, py in ((w1x, w1y), (w2x, w2y)):
        gap = nx * (px - r1[0]) + ny * (py - r1[1])
        if gap <= margin:
            # the point midway between the incident point and its projection on the face
            points[count, 0] = px - 0.5 * gap * nx
            points[count, 1] = py - 0.5 * gap * ny
            normals[count, 0], normals[count, 1] = (-nx, -ny) if flip else (nx, ny)
            gaps[count] = gap
            count += 1
    return count


@njit(cache=True)
def planar_contacts(kind_a: int, size_a: np.ndarray, xa: float, ya: float, yaw_a: float,
                    kind_b: int, size_b: np.ndarray, xb: float, yb: float, yaw_b: float,
                    margin: float, points: np.ndarray, normals: np.ndarray,
                    gaps: np.ndarray, corners: np.ndarray) -> int:
    """The contacts of two upright prisms standing on the table, seen from above: up to two
    points (2, 2) (m, world), unit normals (2, 2) from a into b and signed gaps (2,) (m,
    negative when they penetrate), for every contact whose gap is at most `margin`. A disk
    meets anything at one point; two rectangles at one (a corner) or two (faces side by side).
    `size_*` are the full extents as in `prism_penetration`. Returns how many. `corners`
    (2, 4, 2) is scratch for two rectangles' corners."""
    if kind_a == CYLINDER and kind_b == CYLINDER:
        dx, dy = xb - xa, yb - ya
        d = math.hypot(dx, dy)
        ra, rb = 0.5 * size_a[0], 0.5 * size_b[0]
        gap = d - ra - rb
        if gap > margin or d < 1e-12:
            return 0
        nx, ny = dx / d, dy / d
        points[0, 0], points[0, 1] = xa + nx * (ra + 0.5 * gap), ya + ny * (ra + 0.5 * gap)
        normals[0, 0], normals[0, 1] = nx, ny
        gaps[0] = gap
        return 1
    if kind_a == CYLINDER or kind_b == CYLINDER:
        flip = kind_a == CYLINDER        # work with a rectangle r and a disk d
        rect, rx, ry, ryaw = (size_b, xb, yb, yaw_b) if flip else (size_a, xa, ya, yaw_a)
        radius, dxc, dyc = (0.5 * size_a[0], xa, ya) if flip else (0.5 * size_b[0], xb, yb)
        c, s = math.cos(ryaw), math.sin(ryaw)
        lx, ly = c * (dxc - rx) + s * (dyc - ry), -s * (dxc - rx) + c * (dyc - ry)
        hx, hy = 0.5 * rect[0], 0.5 * rect[1]
        qx, qy = min(max(lx, -hx), hx), min(max(ly, -hy), hy)
        ox, oy = lx - qx, ly - qy
        d = math.hypot(ox, oy)
        if d > 1e-12:                    # the disk's centre outside: its nearest point
            nlx, nly = ox / d, oy / d
            gap = d - radius
        else:                            # inside: out through the nearest edge
            if hx - abs(lx) < hy - abs(ly):
                nlx, nly = (1.0 if lx >= 0.0 else -1.0), 0.0
                qx, d = nlx * hx, -(hx - abs(lx))
            else:
                nlx, nly = 0.0, (1.0 if ly >= 0.0 else -1.0)
                qy, d = nly * hy, -(hy - abs(ly))
            gap = d - radius
        if gap > margin:
            return 0
        nx, ny = c * nlx - s * nly, s * nlx + c * nly      # rectangle -> disk, world
        px = rx + c * qx - s * qy + 0.5 * gap * nx
        py = ry + s * qx + c * qy + 0.5 * gap * ny
        points[0, 0], points[0, 1] = px, py
        normals[0, 0], normals[0, 1] = (-nx, -ny) if flip else (nx, ny)
        gaps[0] = gap
        return 1
    va, vb = corners[0], corners[1]
    _box_vertices(size_a, xa, ya, yaw_a, va)
    _box_vertices(size_b, xb, yb, yaw_b, vb)
    return _box_box_contacts(va, vb, margin, points, normals, gaps)
