"""One quasistatic physics step: how the objects move when the arm moves.

King et al. 2015, §III-A: "objects only move when pushed by the manipulator. Objects stop
immediately when forces cease to be imparted on the object." The arm is position controlled: its
motion q -> q' is kinematic and never changed by the objects. Objects live in SE(2) on the table
and do not touch each other (the paper does not model object-object contact; an overlap makes
the state invalid).

A step q -> q' is cut into substeps so that no point of any contact shape moves more than
`PhysicsOptions.max_substep` (the result then hardly depends on how a caller chops a motion).
Only the (contact shape, object) pairs the step can reach are asked: a box test, then a lower
bound of their distance at the step's start (`_clear_far`); a step that reaches no object is
one substep, and the substeps before the nearest pair could close its distance are skipped
(they would touch nothing). Each substep:

1. joint limits at q', arm vs table and obstacles at q' (no penetration allowed);
2. contacts: every arm contact shape vs every object at q' (`kernels.capsule_prism` after a
   bounding-box broad phase); each penetrating contact gives a point p, a normal n (arm
   into object) and a depth;
3. a contact whose normal is mostly vertical presses on the object from above: invalid;
4. the pusher displacement at p is the link's own motion between q and q' (the rigid transform
   of the link, which is J(p) dq to first order), projected on the table plane; it is scaled so
   that its normal component equals the penetration to undo ("the part of the substep spent in
   contact"), which also pushes out a small residual from earlier steps;
5. per object, the contacts in the object frame go to `pushing.object_twist`: one contact uses
   the motion-cone closed form, several the complementarity problem (no solution = jamming);
   with `PhysicsOptions.max_turn`, a twist that turns a box faster than that per metre of
   travel is invalid, and with `tipping` one that would tip it;
6. the object twist is applied on SE(2); then the moved objects are checked: residual arm-object
   penetration below `penetration_tolerance`, no object-object or object-obstacle overlap, centre
   on the table.

All of it is compiled with Numba (`step_kernel`, `check_state_kernel`), from the
scene as arrays (`World`): the contact shapes' kinematics (`kernels.shape_poses`), their
distances to the table, obstacles and objects (`kernels.capsule_prism`, exact where
python-fcl's GJK errs by up to 2 mm; tests compare them), the pushing model
(`pushing.object_twist_kernel`) and the object checks (`kernels.prism_penetration`).
`CollisionWorld` (python-fcl) stays the geometry of the validation and the baselines' free-space
queries. The compiled code is cached on disk, in a folder named after a digest of the compiled
modules' sources (`rearrangement_planner/__init__.py`), so an edited kernel is compiled afresh.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field
from enum import Enum
from typing import NamedTuple

import numpy as np
from numba import njit

from rearrangement_planner.model.errors import RobotModelError
from rearrangement_planner.model.robot import RobotModel
from rearrangement_planner.model.scene import MovableObject, Scene
from rearrangement_planner.model.state import State
from rearrangement_planner.physics import kernels, pushing
from rearrangement_planner.physics.collision import TABLE_THICKNESS, CollisionWorld
from rearrangement_planner.physics.options import PhysicsOptions

_INV_SQRT2 = 1.0 / math.sqrt(2.0)
FREE_SPACE_MARGIN = 0.01
"""Extra clearance (m) before a step counts as free space and skips its substeps."""


class Invalid(str, Enum):
    """Why a step was rejected (the state after it would leave the valid set)."""

    JOINT_LIMIT = "joint_limit"
    ARM_TABLE = "arm_table_penetration"
    ARM_OBSTACLE = "arm_obstacle_penetration"
    OBJECT_OVERLAP = "object_object_overlap"
    OBJECT_OBSTACLE = "object_obstacle_overlap"
    OFF_TABLE = "object_off_table"
    CONTACT_FROM_ABOVE = "contact_from_above"
    JAMMING = "jamming"
    RESIDUAL_PENETRATION = "residual_penetration"
    TIPPING = "object_would_tip"
    TURNING = "object_turns"


@dataclass(frozen=True)
class StepResult:
    """The outcome of `Physics.step`. On failure `state` is the unchanged input state."""

    state: State
    valid: bool
    reason: Invalid | None = None
    detail: str = ""
    pushing_links: frozenset[str] = field(default_factory=frozenset)
    moved_objects: frozenset[int] = field(default_factory=frozenset)
    substeps: int = 0


def object_limit_surface_c(obj: MovableObject) -> float:
    """c = m_max / f_max (m) of a scene object's footprint: under uniform pressure 2R/3 for a
    cylinder of radius R, the integrated mean distance for a box (King et al. 2015, §III-A;
    `pushing.limit_surface_c`), times the object's `SupportPressure.c_scale`
    (`model.scene.NOMINAL_C_SCALE` unless a perturbation drew another pressure distribution)."""
    if obj.shape == "cylinder":
        radius = obj.radius
        assert radius is not None  # MovableObject.radius is a float for every cylinder
        return pushing.limit_surface_c("cylinder", radius) * obj.support.c_scale
    return pushing.limit_surface_c("box", obj.size) * obj.support.c_scale


def tips_over(obj: MovableObject, twist: np.ndarray, height: float) -> bool:
    """The quasistatic tipping condition (beyond King et al. 2015, whose objects never tip): an
    object sliding under a horizontal push at `height` (m above the table) carries the friction
    load mu_s m g at the table; it tips about its leading bottom edge when the push's moment mu_s m
    g h exceeds gravity's m g d, d the footprint's extent from the centre along the motion (support
    function): tips when mu_s h > d. `twist` (dx, dy, dtheta) is the object-frame motion; a pure
    rotation (no translation) never tips. Conservative: friction at the pusher, which pulls the
    edge down, is left out (MuJoCo tips a 6 cm box pushed at 7 cm between mu_s 0.5 and 0.6; this
    says 0.43)."""
    dx, dy = float(twist[0]), float(twist[1])
    speed = math.hypot(dx, dy)
    if speed < 1e-12:
        return False
    ux, uy = dx / speed, dy / speed
    if obj.shape == "cylinder":
        lever = 0.5 * float(obj.size[0])
    else:
        lever = 0.5 * (abs(ux) * float(obj.size[0]) + abs(uy) * float(obj.size[1]))
    return obj.support_friction * height > lever


def footprint_reach(obj: MovableObject) -> float:
    """How far the footprint reaches from the centre at most (m): a cylinder's radius, a box's
    half diagonal."""
    if obj.shape == "cylinder":
        return 0.5 * float(obj.size[0])
    return 0.5 * math.hypot(float(obj.size[0]), float(obj.size[1]))


def tips_whichever_way(obj: MovableObject, height: float) -> bool:
    """Whether `obj` tips under a push at `height` (m above the table) whichever way the push
    slides it: `tips_over` in its steadiest direction, where the footprint reaches furthest
    from the centre (`footprint_reach`). Such an object can only move by a push lower down, as
    from another object (`object_contact`)."""
    return obj.support_friction * height > footprint_reach(obj)


# Outcome codes of the compiled step (`_REASONS[code]`; 0 is a valid step).
(_VALID, _JOINT_LIMIT, _ARM_TABLE, _ARM_OBSTACLE, _OBJECT_OVERLAP, _OBJECT_OBSTACLE, _OFF_TABLE,
 _FROM_ABOVE, _JAMMING, _RESIDUAL, _TIPPING, _STATIC_OBJECT, _TURNING) = range(13)
_REASONS: tuple[Invalid | None, ...] = (
    None, Invalid.JOINT_LIMIT, Invalid.ARM_TABLE, Invalid.ARM_OBSTACLE, Invalid.OBJECT_OVERLAP,
    Invalid.OBJECT_OBSTACLE, Invalid.OFF_TABLE, Invalid.CONTACT_FROM_ABOVE, Invalid.JAMMING,
    Invalid.RESIDUAL_PENETRATION, Invalid.TIPPING, Invalid.ARM_OBSTACLE, Invalid.TURNING)

# The compiled step takes its options and per-object constants as packed float arrays (Numba
# takes no Python objects); these name their columns. `_world_arrays` packs them in this order
# (a test checks it against `PhysicsOptions`).
(OPT_MAX_SUBSTEP, OPT_PENETRATION, OPT_OVERLAP, OPT_VERTICAL_NORMAL, OPT_TIPPING,
 OPT_FREE_SPACE, OPT_MAX_TURN, OPT_OBJECT_CONTACT, OPT_TIP_JUDGEMENT,
 OPT_CONTACT_TOLERANCE) = range(10)
OPTION_FIELDS = ("max_substep", "penetration_tolerance", "overlap_tolerance",
                 "vertical_normal_limit", "tipping", None, "max_turn", "object_contact",
                 "tip_judgement", "contact_tolerance")
"""The `PhysicsOptions` field packed in each `World.options` column (None: a module constant,
`FREE_SPACE_MARGIN`)."""
(OBJ_CENTRE_Z, OBJ_C, OBJ_PUSHER_MU, OBJ_SUPPORT_MU, OBJ_FOOTPRINT, OBJ_STATIC, OBJ_COF_X,
 OBJ_COF_Y, OBJ_MASS) = range(9)
"""The columns of `World.obj_props`: the centre's height, the limit surface's c, the pusher and
support frictions, the footprint radius, 1 for a static object, the centre of friction (x, y)
in the object frame and the mass."""


class World(NamedTuple):
    """A scene as the compiled step sees it: arrays only (Numba takes no Python objects).
    Prism dims follow `kernels.capsule_prism` (a box's half extents; a cylinder's radius and
    half height)."""

    chain: tuple[np.ndarray, ...]   # kernels.shape_poses arguments: parents .. shape_local
    shapes: np.ndarray              # (S, 3): axis half length, radius, bounding radius
    limits: np.ndarray              # (2, nq): lower, upper
    static_centre: np.ndarray       # (1 + K, 3): the table slab, then the obstacle boxes
    static_yaw: np.ndarray          # (1 + K,)
    static_dims: np.ndarray         # (1 + K, 3)
    static_size: np.ndarray         # (K, 3) obstacle full extents (object-obstacle overlap)
    obj_kind: np.ndarray            # (M,) kernels.BOX | kernels.CYLINDER
    obj_dims: np.ndarray            # (M, 3)
    obj_size: np.ndarray            # (M, 3) full extents (x, y, z), a cylinder's (2r, 2r, h)
    obj_props: np.ndarray           # (M, 9): columns OBJ_CENTRE_Z .. OBJ_MASS
    table: np.ndarray               # (5,): top z, centre x, y, half size x, y
    options: np.ndarray             # (10,): columns OPT_MAX_SUBSTEP .. OPT_CONTACT_TOLERANCE


class Physics:
    """The quasistatic world of one scene: `step(state, q_next)` is a pure function of its
    arguments (the instance only caches geometry and per-object constants). The step itself
    is compiled (`step_kernel`, Numba); this class turns scenes and states into its arrays
    and its outcome codes into `StepResult`s."""

    def __init__(self, scene: Scene, options: PhysicsOptions | None = None,
                 robot: RobotModel | None = None):
        self.scene = scene
        self.options = options or PhysicsOptions()
        self.robot = robot or scene.robot
        # c = m_max / f_max per object (a length), and the pusher friction mu_c.
        self.c = [object_limit_surface_c(o) for o in scene.objects]
        self.mu = [float(o.pusher_friction) for o in scene.objects]
        self._shape_links = [s.link for s in self.robot.contact_shapes]
        self._names = [o.name for o in scene.objects]
        unknown = set(self.options.static_objects) - set(self._names)
        if unknown:
            raise ValueError(f"static_objects names unknown objects {sorted(unknown)}; the "
                             f"scene has {self._names}")
        self._static = frozenset(i for i, n in enumerate(self._names)
                                 if n in self.options.static_objects)
        self._obstacle_names = [b.name for b in scene.obstacles]
        self.arrays = _world_arrays(scene, self.robot, self.options, self._static)
        self._shapes = len(self._shape_links)
        self._flags = self._shapes + len(self._names)
        self._named: dict[bytes, tuple[frozenset[str], frozenset[int]]] = {}
        """Pushing links and moved objects by the step's flags (few patterns recur)."""

    @functools.cached_property
    def world(self) -> CollisionWorld:
        """The python-fcl collision world of this scene (validation and the baselines'
        queries; the step does not use it)."""
        return CollisionWorld(self.scene, self.robot)

    # -- public ------------------------------------------------------------------------------

    def step(self, state: State, q_next: np.ndarray) -> StepResult:
        """Move the arm from state.q to q_next, pushing what it meets."""
        q_next = np.array(q_next, dtype=float)     # a copy: the new state keeps it
        out = np.empty_like(state.objects)
        # info: (code, a, b, substeps), then one flag per contact shape (pushed) and per
        # object (moved); value: the detail's number.
        info = np.zeros(4 + self._flags, dtype=np.int64)
        value = np.zeros(1)
        # Writable copies: the kernels are compiled for writable arrays only (a read-only
        # argument, as a State holds, would compile the whole step a second time).
        code = single_step(np.array(state.q), q_next, np.array(state.objects), self.arrays,
                           out, info, value)
        links, moved = self._flagged(info[4:])
        if code != _VALID:
            return StepResult(state, False, _REASONS[code],
                              self.describe(code, info, value, q_next),
                              links, moved, int(info[3]))
        return StepResult(State.trusted(q_next, out), True, None, "", links, moved,
                          int(info[3]))

    @property
    def flag_count(self) -> int:
        """How many flags `step_kernel` writes after its four numbers: one per contact shape,
        then one per object."""
        return self._flags

    @staticmethod
    def reasons() -> tuple[Invalid | None, ...]:
        """`reason` of every outcome code of `step_kernel`, by code (None for 0, a valid
        step)."""
        return _REASONS

    @staticmethod
    def reason(code: int) -> Invalid:
        """The `Invalid` of a non-zero outcome code of `step_kernel`."""
        reason = _REASONS[code]
        assert reason is not None, "code 0 is a valid step"
        return reason

    def pushing_links(self, flags: np.ndarray) -> frozenset[str]:
        """The links of the contact shapes flagged in `flags` (`flag_count` long)."""
        return self._flagged(flags)[0]

    def _flagged(self, flags: np.ndarray) -> tuple[frozenset[str], frozenset[int]]:
        """The pushing links and the moved objects of the step's flags, remembered by their
        bytes (few patterns recur, and the propagation asks after every action)."""
        key = flags.tobytes()
        named = self._named.get(key)
        if named is None:       # a new pattern of pushing links and moved objects
            links = frozenset(self._shape_links[s] for s in np.flatnonzero(flags[:self._shapes]))
            named = links, frozenset(np.flatnonzero(flags[self._shapes:]).tolist())
            if len(self._named) < 4096:
                self._named[key] = named
        return named

    def check_state(self, state: State) -> tuple[Invalid, str] | None:
        """Validity of a resting state, or None when valid."""
        info = np.zeros(4, dtype=np.int64)
        value = np.zeros(1)
        q = np.array(state.q, dtype=float)     # writable copies, as in `step`
        code = check_state_kernel(q, np.array(state.objects, dtype=float),
                                  *self.arrays, info, value)
        if code == _VALID:
            return None
        reason = _REASONS[code]
        assert reason is not None
        return reason, self._detail(code, info, value, q, None)

    def describe(self, code: int, info: np.ndarray, value: np.ndarray, q_next: np.ndarray) -> str:
        """The sentence for an invalid outcome of `step_kernel` (its `info` and `value`
        outputs, q_next the step's target configuration)."""
        return self._detail(code, info, value, q_next, info[4:4 + self._shapes])

    # -- internals ---------------------------------------------------------------------------

    def _detail(self, code: int, info: np.ndarray, value: np.ndarray, q: np.ndarray,
                involved: np.ndarray | None) -> str:
        """The sentence for an invalid outcome: `info` holds (code, a, b, substeps) and
        `value` a length or a normal component, as `step_kernel` writes them."""
        a, b, v = int(info[1]), int(info[2]), float(value[0])
        links, names = self._shape_links, self._names
        if code == _JOINT_LIMIT:
            return self._limit_detail(q)
        if code == _ARM_TABLE:
            return f"{links[a]} penetrates the table"
        if code == _ARM_OBSTACLE:
            return f"{links[a]} penetrates obstacle '{self._obstacle_names[b]}'"
        if code == _STATIC_OBJECT:
            return f"{links[a]} touches '{names[b]}', a static object for this planner"
        if code == _TURNING:
            return f"'{names[a]}' would turn too fast: {v:.1f} rad per m it moves"
        if code == _FROM_ABOVE:
            return f"{links[a]} presses on '{names[b]}' from above (normal z = {v:+.2f})"
        if code == _JAMMING:
            jammers = sorted({links[s] for s in np.flatnonzero(involved)}) \
                if involved is not None else []
            return f"'{names[a]}' is jammed between {', '.join(jammers)}"
        if code == _TIPPING:
            return f"'{names[a]}' would tip over: pushed {v * 100:.1f} cm above the table"
        if code == _RESIDUAL:
            where = "still " if involved is not None else ""
            after = " after the push" if involved is not None else ""
            return f"arm {where}penetrates an object by {v * 1000:.1f} mm{after}"
        if code == _OBJECT_OVERLAP:
            return f"'{names[a]}' and '{names[b]}' overlap"
        if code == _OBJECT_OBSTACLE:
            return f"'{names[a]}' overlaps obstacle '{self._obstacle_names[b]}'"
        return f"'{names[a]}' left the table"

    def _limit_detail(self, q: np.ndarray) -> str:
        robot = self.robot
        for name, value, lo, hi in zip(robot.joint_names, q, robot.lower, robot.upper, strict=True):
            if not lo - 1e-9 <= value <= hi + 1e-9:
                return f"{name} = {value:.4f} outside [{lo:.4f}, {hi:.4f}]"
        return "joint limit"


def _world_arrays(scene: Scene, robot: RobotModel, options: PhysicsOptions,
                  static: frozenset[int]) -> World:
    for i, shape in enumerate(robot.contact_shapes):
        if shape.kind not in ("capsule", "sphere"):
            raise RobotModelError(
                f"robot '{robot.name}': contact shape {i} on {shape.link} is a {shape.kind}; "
                "the physics takes capsules and spheres (a sphere is a capsule of length 0)")
    chain = kernels.compiled_chain(robot)
    # Columns: half length, radius against the objects, bounding radius, radius against the
    # table and obstacles (a `RobotModel.grown` arm meets objects a few mm off, the static world
    # as it was: the offset stands for where the real links touch objects, not for the arm's
    # clearance, which the plans keep with their own margin).
    shapes = np.array([[0.5 * s.dims[1] if s.kind == "capsule" else 0.0, s.dims[0],
                        s.bounding_radius, max(s.dims[0] - robot.contact_offset, 1e-4)]
                       for s in robot.contact_shapes], dtype=float)
    table = scene.table
    top = float(table.height)
    static_centre = [[table.center[0], table.center[1], top - 0.5 * TABLE_THICKNESS]]
    static_yaw = [0.0]
    static_dims = [[0.5 * table.size[0], 0.5 * table.size[1], 0.5 * TABLE_THICKNESS]]
    for box in scene.obstacles:
        static_centre.append([box.pose[0], box.pose[1], top + 0.5 * box.size[2]])
        static_yaw.append(box.pose[2])
        static_dims.append([0.5 * v for v in box.size])
    static_size = np.array([b.size for b in scene.obstacles], dtype=float).reshape(-1, 3)
    objects = scene.objects
    obj_kind = np.array([kernels.CYLINDER if o.shape == "cylinder" else kernels.BOX
                         for o in objects], dtype=np.int64)
    obj_dims = np.array([[0.5 * o.size[0], 0.5 * o.size[2], 0.0] if o.shape == "cylinder"
                         else 0.5 * np.asarray(o.size) for o in objects],
                        dtype=float).reshape(-1, 3)
    obj_size = np.array([o.size for o in objects], dtype=float).reshape(-1, 3)
    obj_props = np.array([[top + 0.5 * o.size[2], object_limit_surface_c(o),
                           o.pusher_friction, o.support_friction, o.footprint_radius,
                           float(i in static), o.support.centre[0], o.support.centre[1],
                           o.mass] for i, o in enumerate(objects)],
                         dtype=float).reshape(-1, 9)
    return World(
        chain=chain.arrays,
        shapes=shapes, limits=np.array([robot.lower, robot.upper], dtype=float),
        static_centre=np.array(static_centre, dtype=float),
        static_yaw=np.array(static_yaw, dtype=float),
        static_dims=np.array(static_dims, dtype=float), static_size=static_size,
        obj_kind=obj_kind, obj_dims=obj_dims, obj_size=obj_size, obj_props=obj_props,
        table=np.array([top, table.center[0], table.center[1], 0.5 * table.size[0],
                        0.5 * table.size[1]], dtype=float),
        options=packed_options(options))


def packed_options(options: PhysicsOptions) -> np.ndarray:
    """`World.options`: the fields of `OPTION_FIELDS` in its order, as floats."""
    return np.array([FREE_SPACE_MARGIN if name is None else float(getattr(options, name))
                     for name in OPTION_FIELDS], dtype=float)


# -- the compiled step ---------------------------------------------------------------------------
# Argument lists follow `World`'s fields; `info` receives (code, a, b, substeps) and `value` one
# number for the detail sentence (`Physics._detail`).


@njit(cache=True, inline="always")
def _row(rows: np.ndarray, i: int) -> kernels.Vec3:
    """Row i of an (n, 3) array as a tuple: passing a row view to a compiled call costs a
    reference count up and down, a tuple nothing."""
    return rows[i, 0], rows[i, 1], rows[i, 2]


@kernels.njit_bare
def _poses(q: np.ndarray, chain: tuple, out: np.ndarray, world: np.ndarray,
           turn: np.ndarray) -> None:
    """The contact shapes' poses at q into `out`, with the scratch of
    `kernels.shape_poses_into`."""
    kernels.shape_poses_into(q, chain[0], chain[1], chain[2], chain[3], chain[4], chain[5],
                             out, world, turn)


@kernels.njit_bare
def _sweep(poses_a: np.ndarray, poses_b: np.ndarray, shapes: np.ndarray) -> float:
    """How far any point of any contact shape moves from a to b, m (substeps are cut so that no
    point moves more than max_substep). A point at distance rho from the shape origin moves at
    most |dc| + rho |R_b - R_a|_F / sqrt(2) (the chord of a rotation by theta is
    2 rho sin(theta/2), and |R_b - R_a|_F = 2 sqrt(2) sin(theta/2))."""
    worst = 0.0
    for s in range(poses_a.shape[0]):
        dc = drot = 0.0
        for i in range(3):
            d = poses_b[s, i, 3] - poses_a[s, i, 3]
            dc += d * d
            for j in range(3):
                d = poses_b[s, i, j] - poses_a[s, i, j]
                drot += d * d
        worst = max(worst, math.sqrt(dc) + shapes[s, 2] * math.sqrt(drot) * _INV_SQRT2)
    return worst


@kernels.njit_bare
def _reach(poses: np.ndarray, shapes: np.ndarray, objects: np.ndarray, obj_size: np.ndarray,
           obj_props: np.ndarray, static_centre: np.ndarray, static_dims: np.ndarray,
           margin: float, near: np.ndarray, near_static: np.ndarray) -> bool:
    """Which (contact shape, object) pairs can touch within a step whose points move at most
    `margin` (the sweep plus FREE_SPACE_MARGIN for the bulge of a joint interpolation): the
    shape's box at the start (its segment grown by its radius) overlaps the object's box (its
    footprint circle and height) grown by `margin`; likewise each shape against the table and
    the obstacles (`kernels.near_prism`). Fills the masks; False when no object is near
    (free space)."""
    anything = False
    for s in range(poses.shape[0]):
        a, b = kernels.segment(poses, s, shapes[s, 0])
        r = shapes[s, 1]
        for m in range(objects.shape[0]):
            ext = obj_props[m, OBJ_FOOTPRINT] + margin
            ext_z = 0.5 * obj_size[m, 2] + margin
            z = obj_props[m, OBJ_CENTRE_Z]
            near[s, m] = (min(a[0], b[0]) - r < objects[m, 0] + ext
                          and max(a[0], b[0]) + r > objects[m, 0] - ext
                          and min(a[1], b[1]) - r < objects[m, 1] + ext
                          and max(a[1], b[1]) + r > objects[m, 1] - ext
                          and min(a[2], b[2]) - r < z + ext_z
                          and max(a[2], b[2]) + r > z - ext_z)
            anything = anything or near[s, m]
        for k in range(static_centre.shape[0]):
            near_static[s, k] = kernels.near_prism(a, b, r + margin, kernels.BOX,
                                                   _row(static_centre, k), _row(static_dims, k))
    return anything


@kernels.njit_bare
def _clear_far(poses: np.ndarray, shapes: np.ndarray, objects: np.ndarray,
               obj_kind: np.ndarray, obj_dims: np.ndarray, obj_props: np.ndarray,
               margin: float, near: np.ndarray) -> float:
    """The narrow phase of `_reach`: clears each pair it allowed whose capsule is farther than
    `margin` from the object at the step's start (by `kernels.capsule_prism_bound`, a lower
    bound of their distance), as that pair cannot touch within the step. The boxes of
    `_reach` are loose around a long link, so most steps they call near touch nothing.
    Returns the least bound of the pairs left (inf: none is left, free space)."""
    least = math.inf
    for s in range(poses.shape[0]):
        a, b = kernels.segment(poses, s, shapes[s, 0])
        for m in range(objects.shape[0]):
            if not near[s, m]:
                continue
            centre = (objects[m, 0], objects[m, 1], obj_props[m, OBJ_CENTRE_Z])
            d = kernels.capsule_prism_bound(a, b, shapes[s, 1], obj_kind[m], centre,
                                            objects[m, 2], _row(obj_dims, m), margin)
            if d > margin:
                near[s, m] = False
            else:
                least = min(least, d)
    return least


@kernels.njit_bare
def _static_hit(poses: np.ndarray, shapes: np.ndarray, static_centre: np.ndarray,
                static_yaw: np.ndarray, static_dims: np.ndarray, near_static: np.ndarray,
                info: np.ndarray) -> int:
    """The first contact shape (in order) that penetrates the table or an obstacle, among the
    pairs `near_static` allows (`_reach`)."""
    table = _row(static_centre, 0)
    top = table[2] + static_dims[0, 2]
    for s in range(poses.shape[0]):
        a, b = kernels.segment(poses, s, shapes[s, 0])
        for k in range(static_centre.shape[0]):
            if not near_static[s, k]:
                continue
            if (k == 0 and min(a[2], b[2]) >= top
                    and max(abs(a[0] - table[0]), abs(b[0] - table[0])) <= static_dims[0, 0]
                    and max(abs(a[1] - table[1]), abs(b[1] - table[1])) <= static_dims[0, 1]):
                # Above the slab's top face, over the table: the closed form.
                if min(a[2], b[2]) - top - shapes[s, 3] < 0.0:
                    info[1], info[2] = s, -1
                    return _ARM_TABLE
                continue
            centre, dims = _row(static_centre, k), _row(static_dims, k)
            if not kernels.near_prism(a, b, shapes[s, 3], kernels.BOX, centre, dims):
                continue
            if kernels.capsule_prism_depth_below(a, b, shapes[s, 3], 0.0, kernels.BOX, centre,
                                                 static_yaw[k], dims) < 0.0:
                info[1], info[2] = s, k - 1
                return _ARM_TABLE if k == 0 else _ARM_OBSTACLE
    return _VALID


@kernels.njit_bare
def _contacts(poses: np.ndarray, shapes: np.ndarray, objects: np.ndarray,
              selected: np.ndarray, near: np.ndarray, obj_kind: np.ndarray,
              obj_dims: np.ndarray, obj_props: np.ndarray, c_shape: np.ndarray,
              c_obj: np.ndarray, c_point: np.ndarray, c_normal: np.ndarray,
              c_depth: np.ndarray) -> int:
    """Penetrating (contact shape, object) pairs among the `selected` objects and the pairs
    `near` allows (`_reach`), in shape then object order: the object's surface point, the
    unit normal from the arm into the object, the depth (> 0). Returns how many were
    written."""
    count = 0
    for s in range(poses.shape[0]):
        a, b = kernels.segment(poses, s, shapes[s, 0])
        for m in range(objects.shape[0]):
            if not (selected[m] and near[s, m]):
                continue
            centre = (objects[m, 0], objects[m, 1], obj_props[m, OBJ_CENTRE_Z])
            dims = _row(obj_dims, m)
            if not kernels.near_prism(a, b, shapes[s, 1], obj_kind[m], centre, dims):
                continue
            # The row `count` takes the point and normal; it is kept only for a contact.
            d = kernels.capsule_prism_below(a, b, shapes[s, 1], 0.0, obj_kind[m], centre,
                                            objects[m, 2], dims, c_point[count],
                                            c_normal[count])
            if d < 0.0:
                c_shape[count], c_obj[count], c_depth[count] = s, m, -d
                for k in range(3):
                    c_normal[count, k] = -c_normal[count, k]
                count += 1
    return count


@njit(cache=True)
def _tips_over(kind: int, size: np.ndarray, support_mu: float, dx: float, dy: float,
               height: float) -> bool:
    """`tips_over`, compiled."""
    speed = math.hypot(dx, dy)
    if speed < 1e-12:
        return False
    if kind == kernels.CYLINDER:
        lever = 0.5 * size[0]
    else:
        lever = 0.5 * (abs(dx / speed) * size[0] + abs(dy / speed) * size[1])
    return support_mu * height > lever


@njit(cache=True)
def _object_frame_contacts(m: int, pose: np.ndarray, count: int, c_shape: np.ndarray,
                           c_obj: np.ndarray, c_point: np.ndarray, c_normal: np.ndarray,
                           c_depth: np.ndarray, poses_a: np.ndarray, poses_b: np.ndarray,
                           tolerance: float, P: np.ndarray, N: np.ndarray,
                           V: np.ndarray) -> float:
    """Object m's contacts in its frame (module docstring, step 4): points P, planar unit
    normals N and pusher displacements V; returns the highest contact's z."""
    cos, sin = math.cos(pose[2]), math.sin(pose[2])
    height = -math.inf
    row = 0
    for i in range(count):
        if c_obj[i] != m:
            continue
        s = c_shape[i]
        p = c_point[i]
        # The material point of the link now at p was at T_a T_b^-1 p before the substep.
        dx, dy = p[0], p[1]
        for axis in range(2):
            before = poses_a[s, axis, 3]
            for j in range(3):
                local = 0.0
                for k in range(3):
                    local += poses_b[s, k, j] * (p[k] - poses_b[s, k, 3])
                before += poses_a[s, axis, j] * local
            if axis == 0:
                dx -= before
            else:
                dy -= before
        nx, ny = c_normal[i, 0], c_normal[i, 1]
        n_norm = math.hypot(nx, ny)
        nx, ny = nx / n_norm, ny / n_norm
        d_n = dx * nx + dy * ny
        if d_n > 1e-12:
            # Normal push needed to undo the penetration (planar), at most the substep's own
            # normal motion plus the tolerated residual.
            wanted = min(c_depth[i] / n_norm, d_n + tolerance)
            scale = max(wanted, 0.0) / d_n
            dx, dy = dx * scale, dy * scale
        # World -> object frame: R(yaw)^T v.
        px, py = p[0] - pose[0], p[1] - pose[1]
        P[row, 0], P[row, 1] = cos * px + sin * py, -sin * px + cos * py
        N[row, 0], N[row, 1] = cos * nx + sin * ny, -sin * nx + cos * ny
        V[row, 0], V[row, 1] = cos * dx + sin * dy, -sin * dx + cos * dy
        height = max(height, p[2])
        row += 1
    return height


@njit(cache=True)
def _push_object(m: int, pose: np.ndarray, count: int, c_shape: np.ndarray,
                 c_obj: np.ndarray, c_point: np.ndarray, c_normal: np.ndarray,
                 c_depth: np.ndarray, poses_a: np.ndarray, poses_b: np.ndarray,
                 obj_kind: np.ndarray, obj_size: np.ndarray, obj_props: np.ndarray,
                 table: np.ndarray, options: np.ndarray, new_pose: np.ndarray,
                 value: np.ndarray, work: tuple) -> int:
    """Object m's motion from its contacts (module docstring, steps 4-6): writes its new pose
    and returns _VALID, -1 when it does not move, or the invalid code. Its arrays are views
    of the step's `work` (`step_workspace`)."""
    k = 0
    for i in range(count):
        if c_obj[i] == m:
            k += 1
    if k > work[_P].shape[0]:        # more than one contact problem may have: refused
        return _JAMMING
    P, N, V = work[_P][:k], work[_N][:k], work[_V][:k]
    height = _object_frame_contacts(m, pose, count, c_shape, c_obj, c_point, c_normal,
                                    c_depth, poses_a, poses_b, options[OPT_PENETRATION], P, N,
                                    V)
    twist, f_n, f_t = work[_TWIST], work[_F_N][:k], work[_F_T][:k]
    modes, mus = work[_MODES][:k], work[_MUS][:k]
    for i in range(k):
        mus[i] = obj_props[m, OBJ_PUSHER_MU]
    code = pushing.object_twist_about_kernel(obj_props[m, OBJ_C], obj_props[m, OBJ_COF_X],
                                             obj_props[m, OBJ_COF_Y], P, N, V, mus,
                                             max(100, 80 * k), twist, f_n, f_t, modes,
                                             work[_FLOATS], work[_INTEGERS])
    if code == pushing.JAMMED:
        return _JAMMING
    if twist[0] == 0.0 and twist[1] == 0.0 and twist[2] == 0.0:
        return -1
    code = _object_rules(m, twist, height - table[0], obj_kind, obj_size, obj_props, options,
                         value)
    if code != _VALID:
        return code
    x, y, yaw = pushing.apply_twist_kernel(pose[0], pose[1], pose[2], twist[0], twist[1],
                                           twist[2])
    new_pose[0], new_pose[1], new_pose[2] = x, y, yaw
    return _VALID


@njit(cache=True)
def _object_rules(m: int, twist: np.ndarray, height: float, obj_kind: np.ndarray,
                  obj_size: np.ndarray, obj_props: np.ndarray, options: np.ndarray,
                  value: np.ndarray) -> int:
    """The pushing model's rules for object m moving by `twist` (object frame) under a push
    `height` m above the table (module docstring, step 5): the turn limit (boxes only: a
    cylinder's turn leaves its footprint where it was) and tipping refuse the push; with the
    tip judgement on, a tipping push is not refused but reported in value[1 + m] as the travel
    that topples the object (`_tip_travel`)."""
    turn = options[OPT_MAX_TURN]
    if turn > 0.0 and obj_kind[m] != kernels.CYLINDER \
            and abs(twist[2]) > turn * math.hypot(twist[0], twist[1]) + TURN_SLACK:
        value[0] = abs(twist[2]) / max(math.hypot(twist[0], twist[1]), 1e-9)
        return _TURNING
    if options[OPT_TIPPING] > 0.0 and _tips_over(obj_kind[m], obj_size[m],
                                                 obj_props[m, OBJ_SUPPORT_MU], twist[0],
                                                 twist[1], height):
        value[0] = height
        return _TIPPING
    if options[OPT_TIP_JUDGEMENT] > 0.0 and _tips_with_pusher_friction(
            obj_kind[m], obj_size[m], obj_props[m, OBJ_SUPPORT_MU],
            obj_props[m, OBJ_PUSHER_MU], twist[0], twist[1], height):
        if value.shape[0] > 1 + m:
            travel = _tip_travel(obj_kind[m], obj_size[m], twist[0], twist[1], height)
            value[1 + m] = travel if value[1 + m] <= 0.0 else min(value[1 + m], travel)
    return _VALID


@njit(cache=True)
def _tips_with_pusher_friction(kind: int, size: np.ndarray, support_mu: float,
                               pusher_mu: float, dx: float, dy: float, height: float) -> bool:
    """Whether a push at `height` tips the object it slides (moving along (dx, dy), object
    frame), with the pusher's friction: as the object starts to tip, its pushed face rises
    against the pusher, whose friction mu_c F_n pulls it down. Sliding, the table carries
    mu_s (m g + mu_c F_n), so F_n = mu_s m g / (1 - mu_s mu_c); about the leading bottom edge,
    2 d ahead of the pushed face, it tips when F_n height > m g d + mu_c F_n 2 d, that is
    mu_s (height - 2 mu_c d) > d (1 - mu_s mu_c), d the half extent along the push. The
    planner's rule (`tips_over`) leaves the pusher's friction out and refuses more pushes: a
    6 cm box pushed 7 cm up tips there from mu_s 0.43, here from 0.49 (mu_c 0.3); MuJoCo tips it
    between 0.5 and 0.6."""
    speed = math.hypot(dx, dy)
    if speed < 1e-12:
        return False
    if kind == kernels.CYLINDER:
        d = 0.5 * size[0]
    else:
        d = 0.5 * (abs(dx / speed) * size[0] + abs(dy / speed) * size[1])
    return support_mu * (height - 2.0 * pusher_mu * d) > d * (1.0 - support_mu * pusher_mu)


@njit(cache=True)
def _tip_travel(kind: int, size: np.ndarray, dx: float, dy: float, height: float) -> float:
    """How far (m) a pusher at `height` above the table must carry an object that tips about
    its leading bottom edge (moving along (dx, dy), object frame) before its centre of mass
    passes over that edge and it falls: tilted by theta about the edge, the pushed point of
    the trailing face (2 d behind the edge, `height` up) has moved 2 d (1 - cos theta) +
    height sin theta, and the object falls at theta_c = atan(2 d / H), d its half extent along
    the push and H its height (the centre of mass d behind the edge and H / 2 up). Short of
    it, an object that stops being pushed falls back upright."""
    speed = math.hypot(dx, dy)
    if kind == kernels.CYLINDER:
        d = 0.5 * size[0]
    else:
        d = 0.5 * (abs(dx / speed) * size[0] + abs(dy / speed) * size[1])
    critical = math.atan2(2.0 * d, size[2])
    return 2.0 * d * (1.0 - math.cos(critical)) + height * math.sin(critical)


@njit(cache=True, inline="always")
def _apart(objects: np.ndarray, obj_props: np.ndarray, i: int, j: int,
           tolerance: float) -> bool:
    """Objects i and j cannot overlap by more than `tolerance` (>= 0): their footprints'
    circles (`OBJ_FOOTPRINT`) are apart, so the prisms are, and `kernels.prism_penetration`
    would answer a depth <= 0. A broad phase before it: most pairs of a scene are far."""
    dx, dy = objects[i, 0] - objects[j, 0], objects[i, 1] - objects[j, 1]
    reach = obj_props[i, OBJ_FOOTPRINT] + obj_props[j, OBJ_FOOTPRINT]
    return tolerance >= 0.0 and dx * dx + dy * dy > reach * reach


@njit(cache=True)
def _resolve_object_contacts(objects: np.ndarray, new_objects: np.ndarray,
                             changed: np.ndarray, count: int, c_shape: np.ndarray,
                             c_obj: np.ndarray, c_point: np.ndarray, c_normal: np.ndarray,
                             c_depth: np.ndarray, poses_a: np.ndarray, poses_b: np.ndarray,
                             obj_kind: np.ndarray, obj_size: np.ndarray,
                             obj_props: np.ndarray, table: np.ndarray, options: np.ndarray,
                             moved: np.ndarray, near: np.ndarray, info: np.ndarray,
                             value: np.ndarray, work: tuple) -> int:
    """Objects that meet push each other (`PhysicsOptions.object_contact`; module docstring,
    step 5b). When the pushes of step 5 leave a moved object overlapping another, the group of
    objects in contact (`_contact_group`) is moved by one complementarity problem over all of
    them (`pushing.multibody_twists_kernel`): the arm's contacts on any of them, and their
    contacts with each other (`_group_contacts`). Replaces the group's poses in new_objects;
    the rest keep theirs. Returns _VALID or the invalid code. Its arrays are views of the
    step's `work` (`step_workspace`)."""
    group = work[_GROUP]
    _contact_group(objects, new_objects, changed, obj_kind, obj_size, obj_props, options,
                   group)
    if _drop_static(group, new_objects, changed, obj_kind, obj_size, obj_props, options, info):
        return _OBJECT_OVERLAP
    B = 0
    members = work[_MEMBERS]
    for m in range(group.shape[0]):
        if group[m]:
            members[B] = m
            B += 1
    if B == 0:
        return _VALID
    members = members[:B]
    K = 0
    for i in range(count):
        if group[c_obj[i]]:
            K += 1
    K += _object_pair_contacts(members, objects, obj_kind, obj_size, options, None,
                               work[_PAIR_POINTS], work[_PAIR_NORMALS], work[_PAIR_GAPS],
                               work[_CORNERS])
    if K > work[_P].shape[0]:        # more than one contact problem may have: refused
        return _jammed(group, members, count, c_obj, c_shape, poses_b.shape[0], info)
    P, N, V, body, other, gaps, mus, heights, centres, cs, weights = _group_buffers(work, K, B)
    _group_contacts(members, objects, count, c_shape, c_obj, c_point, c_normal, c_depth,
                    poses_a, poses_b, obj_kind, obj_size, obj_props, table, options, P, N, V,
                    body, other, gaps, mus, heights, centres, cs, weights, work)
    twists = work[_TWISTS][:B]
    code = pushing.multibody_twists_kernel(centres, cs, weights, P, N, body, other, V, gaps,
                                           mus, max(100, 80 * K), twists, work[_FLOATS],
                                           work[_INTEGERS])
    if code == pushing.JAMMED:
        return _jammed(group, members, count, c_obj, c_shape, poses_b.shape[0], info)
    if value.shape[0] > 1:           # the group's motion replaces its members' own pushes
        for b in range(members.shape[0]):
            value[1 + members[b]] = 0.0
    return _move_group(members, twists, centres, heights, objects, new_objects, obj_kind,
                       obj_size, obj_props, options, changed, moved, near, info, value,
                       work[_TWIST])


@kernels.njit_bare
def _jammed(group: np.ndarray, members: np.ndarray, count: int, c_obj: np.ndarray,
            c_shape: np.ndarray, shapes: int, info: np.ndarray) -> int:
    """_JAMMING for a group in contact, with a member the arm touches and the links on it in
    info (as `Physics.reason` reads a jam)."""
    pushing_shapes = info[4:4 + shapes]
    for s in range(shapes):
        pushing_shapes[s] = 0
    info[1] = members[0]
    for i in range(count):
        if group[c_obj[i]]:
            info[1] = c_obj[i]
            pushing_shapes[c_shape[i]] = 1
    return _JAMMING


@njit(cache=True, inline="always")
def _group_buffers(work: tuple, K: int, B: int) -> tuple:
    """The contact problem's arrays for K contacts on B objects, as `_group_contacts` expects
    them before it writes (zero points, normals, displacements and gaps, no other object,
    heights -inf): views of the step's `work`. Inlined (it returns views;
    `kernels.njit_bare`)."""
    P, N, V = work[_P][:K], work[_N][:K], work[_V][:K]
    body, other, gaps, mus = work[_BODY][:K], work[_OTHER][:K], work[_GAPS][:K], work[_MUS][:K]
    for k in range(K):
        P[k, 0] = P[k, 1] = N[k, 0] = N[k, 1] = V[k, 0] = V[k, 1] = gaps[k] = 0.0
        other[k] = -1
    heights, centres = work[_HEIGHTS][:B], work[_CENTRES][:B]
    for b in range(B):
        heights[b] = -math.inf
    return P, N, V, body, other, gaps, mus, heights, centres, work[_CS][:B], work[_WEIGHTS][:B]


@njit(cache=True)
def _drop_static(group: np.ndarray, new_objects: np.ndarray, changed: np.ndarray,
                 obj_kind: np.ndarray, obj_size: np.ndarray, obj_props: np.ndarray,
                 options: np.ndarray, info: np.ndarray) -> bool:
    """A static object (the Static RRT's) is an obstacle, not a body of the group's problem:
    takes it out of group. True, with the pair in info, when a moved object overlaps it; one
    merely near stays out (the checks after the step refuse an overlap with it)."""
    for m in range(group.shape[0]):
        if group[m] and obj_props[m, OBJ_STATIC] > 0.0:
            group[m] = False
            for peer in range(group.shape[0]):
                if changed[peer] and peer != m and not _apart(
                        new_objects, obj_props, m, peer, options[OPT_OVERLAP]) and \
                        kernels.prism_penetration(
                        obj_kind[m], obj_size[m], new_objects[m, 0], new_objects[m, 1],
                        new_objects[m, 2], obj_kind[peer], obj_size[peer],
                        new_objects[peer, 0], new_objects[peer, 1],
                        new_objects[peer, 2]) > options[OPT_OVERLAP]:
                    info[1], info[2] = peer, m
                    return True
    return False


@njit(cache=True)
def _contact_group(objects: np.ndarray, new_objects: np.ndarray, changed: np.ndarray,
                   obj_kind: np.ndarray, obj_size: np.ndarray, obj_props: np.ndarray,
                   options: np.ndarray, group: np.ndarray) -> None:
    """Into `group` (M,), the objects of one contact problem: those a moved object overlaps
    after the pushes of step 5 (beyond the overlap tolerance), and every object within
    `_CONTACT_MARGIN` substeps of one of them at the substep's start, transitively. Empty
    when nothing overlaps."""
    M = objects.shape[0]
    grown = False
    for m in range(M):
        group[m] = False
    for i in range(M):
        for j in range(i + 1, M):
            if (changed[i] or changed[j]) and not _apart(
                    new_objects, obj_props, i, j, options[OPT_OVERLAP]) and \
                    kernels.prism_penetration(
                    obj_kind[i], obj_size[i], new_objects[i, 0], new_objects[i, 1],
                    new_objects[i, 2], obj_kind[j], obj_size[j], new_objects[j, 0],
                    new_objects[j, 1], new_objects[j, 2]) > options[OPT_OVERLAP]:
                group[i] = group[j] = grown = True
    margin = _CONTACT_MARGIN * options[OPT_MAX_SUBSTEP]
    while grown:                     # every object within the margin of the group joins it
        grown = False
        for j in range(M):
            if group[j]:
                continue
            for i in range(M):
                if group[i] and kernels.prism_penetration(
                        obj_kind[i], obj_size[i], objects[i, 0], objects[i, 1],
                        objects[i, 2], obj_kind[j], obj_size[j], objects[j, 0],
                        objects[j, 1], objects[j, 2]) > -margin:
                    group[j] = grown = True
                    break


@njit(cache=True)
def _object_pair_contacts(members: np.ndarray, objects: np.ndarray, obj_kind: np.ndarray,
                          obj_size: np.ndarray, options: np.ndarray, out: tuple | None,
                          pts: np.ndarray, nrm: np.ndarray, gps: np.ndarray,
                          corners: np.ndarray) -> int:
    """The contacts between the members (`kernels.planar_contacts` within the margin), at
    the substep's start: counted, and when `out` = (first row, P, N, body, other, gaps, mus,
    heights, obj_props) is given, written from its first row on (normal into the second
    object of a pair; friction MuJoCo's max of the two mu_c; the force at half the lower
    object's height, both standing on the table). Returns how many. pts (2, 2), nrm (2, 2),
    gps (2,) and corners (2, 4, 2) are scratch."""
    margin = _CONTACT_MARGIN * options[OPT_MAX_SUBSTEP]
    total = 0
    for a in range(members.shape[0]):
        for b in range(a + 1, members.shape[0]):
            i, j = members[a], members[b]
            n = kernels.planar_contacts(
                obj_kind[i], obj_size[i], objects[i, 0], objects[i, 1], objects[i, 2],
                obj_kind[j], obj_size[j], objects[j, 0], objects[j, 1], objects[j, 2],
                margin, pts, nrm, gps, corners)
            if out is not None:
                row, P, N, body, other, gaps, mus, heights, props = out
                level = 0.5 * min(obj_size[i, 2], obj_size[j, 2])
                for r in range(n):
                    k = row + total + r
                    P[k, 0], P[k, 1], N[k, 0], N[k, 1] = pts[r, 0], pts[r, 1], nrm[r, 0], \
                        nrm[r, 1]
                    body[k], other[k], gaps[k] = b, a, gps[r]
                    mus[k] = max(props[i, OBJ_PUSHER_MU], props[j, OBJ_PUSHER_MU])
                    heights[a] = max(heights[a], level)
                    heights[b] = max(heights[b], level)
            total += n
    return total


@njit(cache=True)
def _group_contacts(members: np.ndarray, objects: np.ndarray, count: int,
                    c_shape: np.ndarray, c_obj: np.ndarray, c_point: np.ndarray,
                    c_normal: np.ndarray, c_depth: np.ndarray, poses_a: np.ndarray,
                    poses_b: np.ndarray, obj_kind: np.ndarray, obj_size: np.ndarray,
                    obj_props: np.ndarray, table: np.ndarray, options: np.ndarray,
                    P: np.ndarray, N: np.ndarray, V: np.ndarray, body: np.ndarray,
                    other: np.ndarray, gaps: np.ndarray, mus: np.ndarray,
                    heights: np.ndarray, centres: np.ndarray, cs: np.ndarray,
                    weights: np.ndarray, work: tuple) -> None:
    """The group's contact problem in the world frame (`pushing.build_multibody_lcp_kernel`
    says what each array is): per member its centre of friction, c and support-load weight
    (1 / (mu_s m), the largest 1), and the arm's contacts on it (`_object_frame_contacts`,
    turned into the world frame; heights the highest, above the table); then the members'
    contacts with each other (`_object_pair_contacts`). Its scratch is the step's `work`."""
    row = 0
    for b in range(members.shape[0]):
        m = members[b]
        cos, sin = math.cos(objects[m, 2]), math.sin(objects[m, 2])
        cx, cy = obj_props[m, OBJ_COF_X], obj_props[m, OBJ_COF_Y]
        centres[b, 0] = objects[m, 0] + cos * cx - sin * cy
        centres[b, 1] = objects[m, 1] + sin * cx + cos * cy
        cs[b] = obj_props[m, OBJ_C]
        weights[b] = 1.0 / (obj_props[m, OBJ_SUPPORT_MU] * obj_props[m, OBJ_MASS])
        k = 0
        for i in range(count):
            if c_obj[i] == m:
                k += 1
        if k == 0:
            continue
        Pm, Nm, Vm = work[_P_OBJECT][:k], work[_N_OBJECT][:k], work[_V_OBJECT][:k]
        top = _object_frame_contacts(m, objects[m], count, c_shape, c_obj, c_point, c_normal,
                                     c_depth, poses_a, poses_b, options[OPT_PENETRATION], Pm,
                                     Nm, Vm)
        heights[b] = top - table[0]
        for r in range(k):           # object frame -> world
            P[row, 0] = objects[m, 0] + cos * Pm[r, 0] - sin * Pm[r, 1]
            P[row, 1] = objects[m, 1] + sin * Pm[r, 0] + cos * Pm[r, 1]
            N[row, 0], N[row, 1] = cos * Nm[r, 0] - sin * Nm[r, 1], sin * Nm[r, 0] + cos * Nm[r, 1]
            V[row, 0], V[row, 1] = cos * Vm[r, 0] - sin * Vm[r, 1], sin * Vm[r, 0] + cos * Vm[r, 1]
            body[row], mus[row] = b, obj_props[m, OBJ_PUSHER_MU]
            row += 1
    heaviest = -math.inf
    for b in range(weights.shape[0]):
        heaviest = max(heaviest, weights[b])
    for b in range(weights.shape[0]):
        weights[b] /= heaviest
    _object_pair_contacts(members, objects, obj_kind, obj_size, options,
                          (row, P, N, body, other, gaps, mus, heights, obj_props),
                          work[_PAIR_POINTS], work[_PAIR_NORMALS], work[_PAIR_GAPS],
                          work[_CORNERS])


@njit(cache=True)
def _move_group(members: np.ndarray, twists: np.ndarray, centres: np.ndarray,
                heights: np.ndarray, objects: np.ndarray, new_objects: np.ndarray,
                obj_kind: np.ndarray, obj_size: np.ndarray, obj_props: np.ndarray,
                options: np.ndarray, changed: np.ndarray, moved: np.ndarray,
                near: np.ndarray, info: np.ndarray, value: np.ndarray,
                twist: np.ndarray) -> int:
    """Each member moved by its twist about its centre of friction (world frame): the
    origin's displacement v_o = v_c + w x (o - c), turned into the object frame, checked by
    the pushing model's rules (`_object_rules`) and applied on SE(2). `twist` (3,) is
    scratch."""
    for b in range(members.shape[0]):
        m = members[b]
        new_objects[m, 0], new_objects[m, 1] = objects[m, 0], objects[m, 1]
        new_objects[m, 2] = objects[m, 2]
        vx, vy, w = twists[b, 0], twists[b, 1], twists[b, 2]
        if vx == 0.0 and vy == 0.0 and w == 0.0:
            continue
        ox = vx - w * (objects[m, 1] - centres[b, 1])
        oy = vy + w * (objects[m, 0] - centres[b, 0])
        cos, sin = math.cos(objects[m, 2]), math.sin(objects[m, 2])
        twist[0], twist[1], twist[2] = cos * ox + sin * oy, -sin * ox + cos * oy, w
        code = _object_rules(m, twist, heights[b], obj_kind, obj_size, obj_props, options,
                             value)
        if code != _VALID:
            info[1] = m
            return code
        x, y, yaw = pushing.apply_twist_kernel(objects[m, 0], objects[m, 1], objects[m, 2],
                                               twist[0], twist[1], twist[2])
        new_objects[m, 0], new_objects[m, 1], new_objects[m, 2] = x, y, yaw
        changed[m] = True
        moved[m] = 1
        for s in range(near.shape[0]):
            near[s, m] = True
    return _VALID


_CONTACT_MARGIN = 2.0
"""Object pairs closer than this many substeps (`PhysicsOptions.max_substep`) at a substep's
start join one contact problem: within a substep nothing moves farther than one."""


@kernels.njit_bare
def _object_checks(objects: np.ndarray, which: np.ndarray, static_centre: np.ndarray,
                   static_yaw: np.ndarray, static_size: np.ndarray, obj_kind: np.ndarray,
                   obj_size: np.ndarray, obj_props: np.ndarray, table: np.ndarray,
                   options: np.ndarray, info: np.ndarray) -> int:
    """The objects in `which` overlap no other object or obstacle (beyond the overlap
    tolerance) and keep their centres on the table."""
    M = objects.shape[0]
    tol = options[OPT_OVERLAP]
    pair_tol = options[OPT_CONTACT_TOLERANCE] if options[OPT_OBJECT_CONTACT] > 0.0 else tol
    for i in range(M):
        for j in range(i + 1, M):
            if not (which[i] or which[j]) or _apart(objects, obj_props, i, j, pair_tol):
                continue
            depth = kernels.prism_penetration(
                obj_kind[i], obj_size[i], objects[i, 0], objects[i, 1], objects[i, 2],
                obj_kind[j], obj_size[j], objects[j, 0], objects[j, 1], objects[j, 2])
            if depth > pair_tol:
                info[1], info[2] = i, j
                return _OBJECT_OVERLAP
    for i in range(M):
        if not which[i]:
            continue
        for k in range(static_size.shape[0]):
            depth = kernels.prism_penetration(
                obj_kind[i], obj_size[i], objects[i, 0], objects[i, 1], objects[i, 2],
                kernels.BOX, static_size[k], static_centre[k + 1, 0], static_centre[k + 1, 1],
                static_yaw[k + 1])
            if depth > tol:
                info[1], info[2] = i, k
                return _OBJECT_OBSTACLE
    for i in range(M):
        if which[i] and (abs(objects[i, 0] - table[1]) > table[3]
                         or abs(objects[i, 1] - table[2]) > table[4]):
            info[1] = i
            return _OFF_TABLE
    return _VALID


TURN_SLACK = 1e-4
"""rad per substep a push may turn its object beyond `PhysicsOptions.max_turn` (a substep
moves a contact at most `max_substep`, 4 mm: a grazing touch may nudge an object in place)."""
@kernels.njit_bare
def _admissible(count: int, c_shape: np.ndarray, c_obj: np.ndarray, c_point: np.ndarray,
                c_normal: np.ndarray, objects: np.ndarray, obj_kind: np.ndarray,
                obj_dims: np.ndarray, obj_props: np.ndarray, options: np.ndarray,
                touched: np.ndarray, info: np.ndarray, value: np.ndarray) -> int:
    """No contact presses from above (module docstring, step 3) or touches a static object;
    marks the touched objects."""
    for i in range(count):
        if abs(c_normal[i, 2]) > options[OPT_VERTICAL_NORMAL]:
            info[1], info[2] = c_shape[i], c_obj[i]
            value[0] = c_normal[i, 2]
            return _FROM_ABOVE
        if obj_props[c_obj[i], OBJ_STATIC] > 0.0:
            info[1], info[2] = c_shape[i], c_obj[i]
            return _STATIC_OBJECT
        touched[c_obj[i]] = True
    return _VALID


@kernels.njit_bare
def _residual_depth(poses: np.ndarray, shapes: np.ndarray, new_objects: np.ndarray,
                    changed: np.ndarray, any_changed: bool, count: int, c_shape: np.ndarray,
                    c_obj: np.ndarray, c_point: np.ndarray, c_normal: np.ndarray,
                    c_depth: np.ndarray, near: np.ndarray, obj_kind: np.ndarray,
                    obj_dims: np.ndarray, obj_props: np.ndarray) -> float:
    """The deepest arm-object penetration after the push: objects that did not move keep the
    depths of the substep's contacts; the moved ones are asked again (overwrites the
    contact buffers)."""
    depth = 0.0
    for i in range(count):
        if not changed[c_obj[i]]:
            depth = max(depth, c_depth[i])
    if any_changed:
        after = _contacts(poses, shapes, new_objects, changed, near, obj_kind, obj_dims,
                          obj_props, c_shape, c_obj, c_point, c_normal, c_depth)
        for i in range(after):
            depth = max(depth, c_depth[i])
    return depth


@kernels.njit_bare
def _push_touched(touched: np.ndarray, objects: np.ndarray, new_objects: np.ndarray,
                  count: int, c_shape: np.ndarray, c_obj: np.ndarray, c_point: np.ndarray,
                  c_normal: np.ndarray, c_depth: np.ndarray, poses_a: np.ndarray,
                  poses_b: np.ndarray, obj_kind: np.ndarray, obj_size: np.ndarray,
                  obj_props: np.ndarray, table: np.ndarray, options: np.ndarray,
                  changed: np.ndarray, pushing_shapes: np.ndarray, moved: np.ndarray,
                  near: np.ndarray, info: np.ndarray, value: np.ndarray, work: tuple) -> int:
    """Push every touched object (`_push_object`) into new_objects; flags the moved objects,
    their pushing shapes and (for the rest of the step) every shape as near them."""
    for m in range(objects.shape[0]):
        if not touched[m]:
            continue
        code = _push_object(m, objects[m], count, c_shape, c_obj, c_point, c_normal, c_depth,
                            poses_a, poses_b, obj_kind, obj_size, obj_props, table, options,
                            new_objects[m], value, work)
        if code == -1:
            continue
        if code != _VALID:
            info[1] = m
            if code == _JAMMING:       # the links that squeeze it, for the detail
                for s in range(pushing_shapes.shape[0]):
                    pushing_shapes[s] = 0
                for i in range(count):
                    if c_obj[i] == m:
                        pushing_shapes[c_shape[i]] = 1
            return code
        changed[m] = True
        moved[m] = 1
        for s in range(near.shape[0]):
            near[s, m] = True
        for i in range(count):
            if c_obj[i] == m:
                pushing_shapes[c_shape[i]] = 1
    return _VALID


@kernels.njit_bare
def _substep(poses_a: np.ndarray, poses_b: np.ndarray, objects: np.ndarray,
             new_objects: np.ndarray, shapes: np.ndarray, static_centre: np.ndarray,
             static_yaw: np.ndarray, static_dims: np.ndarray, static_size: np.ndarray,
             obj_kind: np.ndarray, obj_dims: np.ndarray, obj_size: np.ndarray,
             obj_props: np.ndarray, table: np.ndarray, options: np.ndarray, info: np.ndarray,
             value: np.ndarray, pushing_shapes: np.ndarray, moved: np.ndarray,
             work: tuple) -> int:
    """One substep (module docstring, 1-6): objects -> new_objects, or an invalid code. Only
    the pairs `_reach` found near are asked; an object that moves is asked against every
    shape from then on. The contact buffers (c_*, one row per shape-object pair) and
    `everything` (all True) are the step's `work` (`step_workspace`), reused by each
    substep."""
    near, near_static = work[_NEAR], work[_NEAR_STATIC]
    c_shape, c_obj, c_point = work[_C_SHAPE], work[_C_OBJ], work[_C_POINT]
    c_normal, c_depth, everything = work[_C_NORMAL], work[_C_DEPTH], work[_EVERYTHING]
    code = _static_hit(poses_b, shapes, static_centre, static_yaw, static_dims, near_static,
                       info)
    if code != _VALID:
        return code
    count = _contacts(poses_b, shapes, objects, everything, near, obj_kind, obj_dims,
                      obj_props, c_shape, c_obj, c_point, c_normal, c_depth)
    _copy_rows(objects, new_objects)
    if count == 0:
        return _VALID
    touched, changed = work[_TOUCHED], work[_CHANGED]
    for m in range(touched.shape[0]):
        touched[m] = changed[m] = False
    code = _admissible(count, c_shape, c_obj, c_point, c_normal, objects, obj_kind, obj_dims,
                       obj_props, options, touched, info, value)
    if code != _VALID:
        return code
    code = _push_touched(touched, objects, new_objects, count, c_shape, c_obj, c_point,
                         c_normal, c_depth, poses_a, poses_b, obj_kind, obj_size, obj_props,
                         table, options, changed, pushing_shapes, moved, near, info, value,
                         work)
    if code != _VALID:
        return code
    any_changed = False
    for m in range(changed.shape[0]):
        any_changed = any_changed or changed[m]
    if options[OPT_OBJECT_CONTACT] > 0.0 and any_changed:
        code = _resolve_object_contacts(objects, new_objects, changed, count, c_shape, c_obj,
                                        c_point, c_normal, c_depth, poses_a, poses_b,
                                        obj_kind, obj_size, obj_props, table, options, moved,
                                        near, info, value, work)
        if code != _VALID:
            return code
    depth = _residual_depth(poses_b, shapes, new_objects, changed, any_changed, count,
                            c_shape, c_obj, c_point, c_normal, c_depth, near, obj_kind,
                            obj_dims, obj_props)
    if depth > options[OPT_PENETRATION]:
        value[0] = depth
        return _RESIDUAL
    if any_changed:
        return _object_checks(new_objects, changed, static_centre, static_yaw, static_size,
                              obj_kind, obj_size, obj_props, table, options, info)
    return _VALID


@kernels.njit_bare
def _copy_rows(source: np.ndarray, out: np.ndarray) -> None:
    """out[:] = source for (M, 3) pose arrays, written out (a whole-array assignment may
    allocate a temporary, which a kernel without reference counting cannot)."""
    for m in range(source.shape[0]):
        out[m, 0], out[m, 1], out[m, 2] = source[m, 0], source[m, 1], source[m, 2]


@kernels.njit_bare
def _copy_poses(source: np.ndarray, out: np.ndarray) -> None:
    """out[:] = source for (N, 4, 4) pose stacks, written out (`_copy_rows`)."""
    for m in range(source.shape[0]):
        for i in range(4):
            for j in range(4):
                out[m, i, j] = source[m, i, j]


@kernels.njit_bare
def _substeps(q0: np.ndarray, q1: np.ndarray, objects: np.ndarray, chain: tuple,
              poses_a: np.ndarray, shapes: np.ndarray, static_centre: np.ndarray,
              static_dims: np.ndarray,
              obj_kind: np.ndarray, obj_dims: np.ndarray, obj_size: np.ndarray,
              obj_props: np.ndarray, options: np.ndarray, sweep: float,
              work: tuple) -> tuple[int, int]:
    """How `step_kernel` cuts the step q0 -> q1, whose points move at most `sweep`: (n, the
    first substep to run), the pairs it may touch in the workspace's `near` and
    `near_static` (`_reach`, `_clear_far`), and its `poses_a` moved to the start of the
    first substep."""
    q_b, near, near_static = work[_Q_B], work[_NEAR], work[_NEAR_STATIC]
    n = max(1, math.ceil(sweep / options[OPT_MAX_SUBSTEP] - 1e-9))
    margin = sweep + options[OPT_FREE_SPACE]
    least = math.inf
    if _reach(poses_a, shapes, objects, obj_size, obj_props, static_centre, static_dims,
              margin, near, near_static):
        least = _clear_far(poses_a, shapes, objects, obj_kind, obj_dims, obj_props, margin,
                           near)
    if least == math.inf:
        # Free space: no substep can touch an object, so the substeps would only repeat the
        # static check. One substep at q1 (substeps are for contacts).
        return 1, 1
    if n == 1:
        return 1, 1
    # No point moves more than sweep / n per substep (plus the bulge): the substeps before the
    # nearest pair can close its distance touch nothing, so start at the one before.
    first = max(1, min(n, int(math.floor((least - options[OPT_FREE_SPACE]) / (sweep / n)))))
    if first > 1:
        for j in range(q1.shape[0]):
            q_b[j] = q0[j] + (q1[j] - q0[j]) * ((first - 1) / n)
        _poses(q_b, chain, poses_a, work[_JOINTS], work[_TURN])
    return n, first


@njit(cache=True)
def single_step(q0: np.ndarray, q1: np.ndarray, objects: np.ndarray, world: tuple,
                out_objects: np.ndarray, info: np.ndarray, value: np.ndarray) -> int:
    """`step_kernel` with buffers of its own (`Physics.step`: one step at a time)."""
    work = step_workspace(world, q1, objects)
    return step_kernel(q0, q1, objects, world, out_objects, info, value, work)


_POSES_A, _POSES_B, _Q_B, _NEAR, _NEAR_STATIC, _CURRENT, _FOLLOWING = 0, 1, 2, 3, 4, 5, 6
_C_SHAPE, _C_OBJ, _C_POINT, _C_NORMAL, _C_DEPTH, _EVERYTHING = 7, 8, 9, 10, 11, 12
_JOINTS, _TURN, _TOUCHED, _CHANGED = 13, 14, 15, 16
_P, _N, _V, _BODY, _OTHER, _GAPS, _MUS, _F_N, _F_T, _MODES = range(17, 27)
_HEIGHTS, _CENTRES, _CS, _WEIGHTS, _TWISTS, _TWIST, _GROUP, _MEMBERS = range(27, 35)
_P_OBJECT, _N_OBJECT, _V_OBJECT, _PAIR_POINTS, _PAIR_NORMALS, _PAIR_GAPS = 35, 36, 37, 38, 39, 40
_FLOATS, _INTEGERS, _CORNERS, _KNOWN, _KNOWN_Q, _END_POSES, _END_JOINTS = range(41, 48)
"""The buffers of `step_workspace`, by name: the step's (_POSES_A .. _CHANGED), then those of
the pushes' contact problems (_P .. _CORNERS), then which of _POSES_A and _POSES_B (0, 1;
-1: neither) holds the contact shapes' poses at the arm configuration _KNOWN_Q, then the
contact shapes' and the joints' poses at q1 kept while substeps compute others."""
WORK_JOINTS = _JOINTS
"""The buffer of `step_workspace` that holds the arm's joints' poses (J, 4, 4) at q1 after a
valid `step_kernel` (its last forward kinematics is at q1): the next Project step takes the
tool's pose and Jacobian from them (`kernels.tool_from_joints`)."""


@njit(cache=True)
def step_workspace(world: tuple, q: np.ndarray, objects: np.ndarray) -> tuple:
    """The buffers of a physics step (`step_kernel`) in the scene's arrays `world` (a
    `World`), for the arm at q and the `objects` (M, 3): allocated once for a loop of
    steps, as allocating them at every step cost a tenth of the step (`rearrangement-bench
    physics`), and so that the step compiles without reference counting
    (`kernels.njit_bare`). Named by _POSES_A .. _KNOWN_Q. The contact problems' buffers
    hold the most contacts one problem can have (one per (contact shape, object) pair and
    two per object pair, `kernels.planar_contacts`), at most `pushing.LCP_CONTACTS`: a
    problem with more is refused as a jam."""
    chain, shapes, static_centre = world[0], world[1], world[3]
    S, M = shapes.shape[0], objects.shape[0]
    capacity = S * M
    most = min(capacity + M * (M - 1), pushing.LCP_CONTACTS)
    floats, integers = pushing.lcp_scratch(most, M)
    return (np.empty((S, 4, 4)), np.empty((S, 4, 4)), np.empty(q.shape[0]),
            np.empty((S, M), dtype=np.bool_), np.empty((S, static_centre.shape[0]),
                                                        dtype=np.bool_),
            np.empty((M, 3)), np.empty((M, 3)), np.empty(capacity, dtype=np.int64),
            np.empty(capacity, dtype=np.int64), np.empty((capacity, 3)),
            np.empty((capacity, 3)), np.empty(capacity), np.ones(M, dtype=np.bool_),
            np.empty((chain[0].shape[0], 4, 4)), np.empty((2, 4, 4)),
            np.empty(M, dtype=np.bool_), np.empty(M, dtype=np.bool_),
            np.empty((most, 2)), np.empty((most, 2)), np.empty((most, 2)),
            np.empty(most, dtype=np.int64), np.empty(most, dtype=np.int64), np.empty(most),
            np.empty(most), np.empty(most), np.empty(most), np.empty(most, dtype=np.int64),
            np.empty(M), np.empty((M, 2)), np.empty(M), np.empty(M), np.empty((M, 3)),
            np.empty(3), np.empty(M, dtype=np.bool_), np.empty(M, dtype=np.int64),
            np.empty((S, 2)), np.empty((S, 2)), np.empty((S, 2)), np.empty((2, 2)),
            np.empty((2, 2)), np.empty(2), floats, integers, np.empty((2, 4, 2)),
            np.full(1, -1, dtype=np.int64), np.empty(q.shape[0]), np.empty((S, 4, 4)),
            np.empty((chain[0].shape[0], 4, 4)))


@kernels.njit_bare
def step_kernel(q0: np.ndarray, q1: np.ndarray, objects: np.ndarray, world: tuple,
                out_objects: np.ndarray, info: np.ndarray, value: np.ndarray,
                work: tuple) -> int:
    """`Physics.step` compiled: the arm from q0 to q1 through substeps (module docstring) in
    the scene's arrays `world` (a `World`); the objects after it into `out_objects`; info
    gets (code, a, b, substeps run) and then one flag per contact shape (it pushed an object;
    for a jam, it squeezes the object) and per object (it moved); returns the outcome code
    (0 = valid). The buffers are `work` (`step_workspace`: a loop of steps allocates them
    once). Only the contact shapes' poses at q1 carry over to the next step: one that starts
    where this one ended (its q0 equal to this q1, entry by entry) takes them instead of
    computing them again, the same numbers."""
    chain, shapes, limits, static_centre, static_yaw = (world[0], world[1], world[2],
                                                        world[3], world[4])
    static_dims, static_size, obj_kind, obj_dims = world[5], world[6], world[7], world[8]
    obj_size, obj_props, table, options = world[9], world[10], world[11], world[12]
    S = shapes.shape[0]
    pushing_shapes = info[4:4 + S]
    moved = info[4 + S:]
    for j in range(q1.shape[0]):
        # The joint box is convex: q1 inside means every substep is inside too.
        if not limits[0, j] - 1e-9 <= q1[j] <= limits[1, j] + 1e-9:
            info[0] = _JOINT_LIMIT
            return _JOINT_LIMIT
    q_b, joints, turn = work[_Q_B], work[_JOINTS], work[_TURN]
    in_b = _poses_at_start(q0, chain, work)        # poses_a is work[_POSES_B]
    poses_a, poses_b = ((work[_POSES_B], work[_POSES_A]) if in_b
                        else (work[_POSES_A], work[_POSES_B]))
    _poses(q1, chain, poses_b, joints, turn)
    sweep = _sweep(poses_a, poses_b, shapes)
    if sweep / options[OPT_MAX_SUBSTEP] - 1e-9 > 1.0:  # may take substeps: keep the end's poses
        _copy_poses(poses_b, work[_END_POSES])
        _copy_poses(joints, work[_END_JOINTS])
    n, first = _substeps(q0, q1, objects, chain, poses_a, shapes, static_centre, static_dims,
                         obj_kind, obj_dims, obj_size, obj_props, options, sweep, work)
    current, following = work[_CURRENT], work[_FOLLOWING]
    _copy_rows(objects, current)
    for i in range(first, n + 1):
        if i < n:
            for j in range(q1.shape[0]):
                q_b[j] = q0[j] + (q1[j] - q0[j]) * (i / n)
            _poses(q_b, chain, poses_b, joints, turn)
        elif n > 1:                                     # the end's poses, kept above
            _copy_poses(work[_END_POSES], poses_b)
            _copy_poses(work[_END_JOINTS], joints)
        code = _substep(poses_a, poses_b, current, following, shapes, static_centre,
                        static_yaw, static_dims, static_size, obj_kind, obj_dims, obj_size,
                        obj_props, table, options, info, value, pushing_shapes, moved, work)
        if code != _VALID:
            info[0], info[3] = code, i
            return code
        current, following = following, current
        poses_a, poses_b = poses_b, poses_a
        in_b = not in_b
    _copy_rows(current, out_objects)
    info[3] = n
    work[_KNOWN][0] = 1 if in_b else 0       # poses_a: the contact shapes' poses at q1
    known_q = work[_KNOWN_Q]
    for j in range(q1.shape[0]):
        known_q[j] = q1[j]
    return _VALID


@kernels.njit_bare
def _poses_at_start(q0: np.ndarray, chain: tuple, work: tuple) -> bool:
    """The contact shapes' poses at a step's q0: those the last step left (`step_kernel`)
    when it ended at q0, else computed into work[_POSES_A]. True when they are in
    work[_POSES_B]. Forgets them either way: the step overwrites the buffers."""
    known = work[_KNOWN]
    in_b = known[0] == 1
    if known[0] >= 0 and _same(q0, work[_KNOWN_Q]):
        known[0] = -1
        return in_b
    known[0] = -1
    _poses(q0, chain, work[_POSES_A], work[_JOINTS], work[_TURN])
    return False


@kernels.njit_bare
def _same(a: np.ndarray, b: np.ndarray) -> bool:
    """a == b, entry by entry."""
    for j in range(a.shape[0]):
        if a[j] != b[j]:
            return False
    return True


@njit(cache=True)
def check_state_kernel(q: np.ndarray, objects: np.ndarray, chain: tuple, shapes: np.ndarray,
                       limits: np.ndarray, static_centre: np.ndarray, static_yaw: np.ndarray,
                       static_dims: np.ndarray, static_size: np.ndarray, obj_kind: np.ndarray,
                       obj_dims: np.ndarray, obj_size: np.ndarray, obj_props: np.ndarray,
                       table: np.ndarray, options: np.ndarray, info: np.ndarray,
                       value: np.ndarray) -> int:
    """`Physics.check_state` compiled: the outcome code of a resting state (0 = valid)."""
    for j in range(q.shape[0]):
        if not limits[0, j] - 1e-9 <= q[j] <= limits[1, j] + 1e-9:
            return _JOINT_LIMIT
    S, M = shapes.shape[0], objects.shape[0]
    poses = np.empty((S, 4, 4))
    _poses(q, chain, poses, np.empty((chain[0].shape[0], 4, 4)), np.empty((2, 4, 4)))
    near_static = np.ones((S, static_centre.shape[0]), dtype=np.bool_)
    code = _static_hit(poses, shapes, static_centre, static_yaw, static_dims, near_static,
                       info)
    if code != _VALID:
        return code
    capacity = S * M
    c_shape, c_obj = np.empty(capacity, dtype=np.int64), np.empty(capacity, dtype=np.int64)
    c_point, c_normal, c_depth = np.empty((capacity, 3)), np.empty((capacity, 3)), \
        np.empty(capacity)
    everything = np.ones(M, dtype=np.bool_)
    count = _contacts(poses, shapes, objects, everything, np.ones((S, M), dtype=np.bool_),
                      obj_kind, obj_dims, obj_props, c_shape, c_obj, c_point, c_normal,
                      c_depth)
    depth = 0.0
    for i in range(count):
        depth = max(depth, c_depth[i])
    if depth > options[OPT_PENETRATION]:
        value[0] = depth
        return _RESIDUAL
    return _object_checks(objects, everything, static_centre, static_yaw, static_size,
                          obj_kind, obj_size, obj_props, table, options, info)
