"""One quasistatic physics step: how the objects move when the arm moves (DESIGN §5).

King et al. §III-A: "objects only move when pushed by the manipulator. Objects stop immediately
when forces cease to be imparted on the object." The arm is position controlled: its motion
q -> q' is kinematic and never changed by the objects. Objects live in SE(2) on the table and
do not touch each other (the paper does not model object-object contact; an overlap makes the
state invalid).

A step q -> q' is cut into substeps so that no point of any contact shape moves more than
`PhysicsOptions.max_substep` (the result then hardly depends on how a caller chops a motion).
Each substep:

1. joint limits at q', arm vs table and obstacles at q' (no penetration allowed);
2. contacts: every arm contact shape vs every object at q' (python-fcl after a NumPy broad
   phase, `collision.CollisionWorld`); each penetrating contact gives a point p, a normal n (arm
   into object) and a depth;
3. a contact whose normal is mostly vertical presses on the object from above: invalid;
4. the pusher displacement at p is the link's own motion between q and q' (the rigid transform
   of the link, which is J(p) dq to first order), projected on the table plane; it is scaled so
   that its normal component equals the penetration to undo ("the part of the substep spent in
   contact"), which also pushes out a small residual from earlier steps;
5. per object, the contacts in the object frame go to `pushing.object_twist`: one contact uses
   the motion-cone closed form, several the complementarity problem (no solution = jamming);
6. the object twist is applied on SE(2); then the moved objects are checked: residual arm-object
   penetration below `penetration_tolerance`, no object-object or object-obstacle overlap, centre
   on the table.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from enum import Enum

import numpy as np

from rearrangement_planner.model.robot import RobotModel
from rearrangement_planner.model.scene import MovableObject, Scene
from rearrangement_planner.model.state import State
from rearrangement_planner.physics import pushing
from rearrangement_planner.physics.collision import CollisionWorld

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


@dataclass(frozen=True)
class PhysicsOptions:
    max_substep: float = 0.004
    """Largest displacement (m) of any point of any contact shape within one substep."""
    penetration_tolerance: float = 0.003
    """Largest arm-object penetration (m) allowed after a step."""
    vertical_normal_limit: float = 0.7
    """|n_z| of a contact normal above which the arm presses on an object from above (45 deg)."""
    overlap_tolerance: float = 1e-4
    """Object-object and object-obstacle penetration (m) still counted as touching."""
    tipping: bool = False
    """Refuse a push that would tip its object over (the quasistatic tipping condition,
    `tips_over`). Off here, where the physics also serves execution (world_sim lets a pushed
    object slide whatever the push height); the planners switch it on with their `tipping`
    setting (`PlannerOptions.tipping`, on by default). Off = objects never tip, as in King
    et al."""
    static_objects: frozenset[str] = frozenset()
    """Names of movable objects treated as static obstacles: any arm contact with one is
    invalid (`Invalid.ARM_OBSTACLE`). The Static RRT baseline makes every object but the goal
    object static (§V-A of King et al.)."""


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
    """c = m_max / f_max (m) of a scene object's footprint: 2R/3 for a cylinder of radius R,
    the integrated mean distance for a box (DESIGN §5; `pushing.limit_surface_c`)."""
    if obj.shape == "cylinder":
        radius = obj.radius
        assert radius is not None  # MovableObject.radius is a float for every cylinder
        return pushing.limit_surface_c("cylinder", radius)
    return pushing.limit_surface_c("box", obj.size)


def tips_over(obj: MovableObject, twist: np.ndarray, height: float) -> bool:
    """The quasistatic tipping condition (DESIGN §5): an object sliding under a horizontal push
    at `height` (m above the table) carries the friction load mu_s m g at the table; it tips
    about its leading bottom edge when the push's moment mu_s m g h exceeds gravity's m g d,
    d the footprint's extent from the centre along the motion (support function): tips when
    mu_s h > d. `twist` (dx, dy, dtheta) is the object-frame motion; a pure rotation (no
    translation) never tips. Conservative: friction at the pusher, which pulls the edge down,
    is left out (MuJoCo tips a 6 cm box pushed at 7 cm between mu_s 0.5 and 0.6; this says 0.43)."""
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


class Physics:
    """The quasistatic world of one scene: `step(state, q_next)` is a pure function of its
    arguments (the instance only caches geometry and per-object constants)."""

    def __init__(self, scene: Scene, options: PhysicsOptions | None = None,
                 robot: RobotModel | None = None):
        self.scene = scene
        self.options = options or PhysicsOptions()
        self.robot = robot or scene.robot
        self.world = CollisionWorld(scene, self.robot)
        # c = m_max / f_max per object (a length; DESIGN §5), and the pusher friction mu_c.
        self.c = [object_limit_surface_c(o) for o in scene.objects]
        self.mu = [float(o.pusher_friction) for o in scene.objects]
        self._shape_links = [s.link for s in self.robot.contact_shapes]
        self._shape_radii = np.asarray(self.robot.shape_bounding_radii)
        self._names = [o.name for o in scene.objects]
        unknown = set(self.options.static_objects) - set(self._names)
        if unknown:
            raise ValueError(f"static_objects names unknown objects {sorted(unknown)}; the "
                             f"scene has {self._names}")
        self._static = frozenset(i for i, n in enumerate(self._names)
                                 if n in self.options.static_objects)

    # -- public ------------------------------------------------------------------------------

    def step(self, state: State, q_next: np.ndarray) -> StepResult:
        """Move the arm from state.q to q_next, pushing what it meets."""
        q_next = np.asarray(q_next, dtype=float)
        if not self.robot.within_limits(q_next, tol=1e-9):
            # The joint box is convex: q_next inside means every substep is inside too.
            return StepResult(state, False, Invalid.JOINT_LIMIT, self._limit_detail(q_next))
        poses_a = self.robot.shape_poses(state.q)
        poses_b = self.robot.shape_poses(q_next)
        sweep = self._sweep(poses_a, poses_b)
        n = max(1, math.ceil(sweep / self.options.max_substep - 1e-9))
        objects = state.objects
        if n > 1 and self._out_of_reach(poses_a, sweep, objects):
            # Free space: no substep can touch an object, so the substeps would only repeat
            # the static check. One substep at q_next (DESIGN §5 substepping is for contacts).
            n = 1
        pushing_links: set[str] = set()
        moved: set[int] = set()
        q_a = state.q
        for i in range(1, n + 1):
            q_b = q_next if i == n else state.q + (q_next - state.q) * (i / n)
            if i < n:
                poses_b = self.robot.shape_poses(q_b)
            elif n > 1:
                poses_b = self.robot.shape_poses(q_next)
            outcome = self._substep(q_a, poses_a, q_b, poses_b, objects, pushing_links, moved)
            if isinstance(outcome, tuple):
                reason, detail = outcome
                return StepResult(state, False, reason, detail, frozenset(pushing_links),
                                  frozenset(moved), i)
            objects = outcome
            q_a, poses_a = q_b, poses_b
        return StepResult(State(q_next, objects), True, None, "", frozenset(pushing_links),
                          frozenset(moved), n)

    def check_state(self, state: State) -> tuple[Invalid, str] | None:
        """Validity of a resting state (DESIGN §5), or None when valid."""
        robot, opts = self.robot, self.options
        if not robot.within_limits(state.q, tol=1e-9):
            return Invalid.JOINT_LIMIT, self._limit_detail(state.q)
        poses = robot.shape_poses(state.q)
        static = self._static_collision(poses)
        if static is not None:
            return static
        depth = self.world.arm_object_penetration(poses, state.objects)
        if depth > opts.penetration_tolerance:
            return (Invalid.RESIDUAL_PENETRATION,
                    f"arm penetrates an object by {depth * 1000:.1f} mm")
        return self._object_checks(state.objects, range(len(self._names)))

    # -- internals ---------------------------------------------------------------------------

    def _sweep(self, poses_a: np.ndarray, poses_b: np.ndarray) -> float:
        """How far any point of any contact shape moves from a to b, m (substeps are cut so
        that no point moves more than max_substep). A point at distance rho from the shape
        origin moves at most |dc| + rho |R_b - R_a|_F / sqrt(2) (the chord of a rotation by
        theta is 2 rho sin(theta/2), and |R_b - R_a|_F = 2 sqrt(2) sin(theta/2))."""
        diff = poses_b[:, :3, :] - poses_a[:, :3, :]
        dc = np.sqrt(np.einsum("ni,ni->n", diff[:, :, 3], diff[:, :, 3]))
        drot = np.sqrt(np.einsum("nij,nij->n", diff[:, :, :3], diff[:, :, :3]))
        return float((dc + self._shape_radii * drot * _INV_SQRT2).max())

    def _out_of_reach(self, poses_a: np.ndarray, sweep: float, objects: np.ndarray) -> bool:
        """True when no contact shape can reach any object during the step: every shape's
        bounding box at a, grown by the sweep (plus FREE_SPACE_MARGIN for the bulge of a joint
        interpolation between a and b), is clear of every object's bounding box."""
        shapes, _ = self.world.object_candidates(poses_a, objects, sweep + FREE_SPACE_MARGIN)
        return shapes.size == 0

    def _static_collision(self, poses: np.ndarray) -> tuple[Invalid, str] | None:
        hit = self.world.arm_static_collision(poses)
        if hit is None:
            return None
        shape, what = hit
        link = self._shape_links[shape]
        if what == "table":
            return Invalid.ARM_TABLE, f"{link} penetrates the table"
        return Invalid.ARM_OBSTACLE, f"{link} penetrates obstacle '{what}'"

    def _limit_detail(self, q: np.ndarray) -> str:
        robot = self.robot
        for name, value, lo, hi in zip(robot.joint_names, q, robot.lower, robot.upper, strict=True):
            if not lo - 1e-9 <= value <= hi + 1e-9:
                return f"{name} = {value:.4f} outside [{lo:.4f}, {hi:.4f}]"
        return "joint limit"

    def _substep(self, q_a, poses_a, q_b, poses_b, objects, pushing_links, moved):
        opts = self.options
        static = self._static_collision(poses_b)
        if static is not None:
            return static
        contacts = self.world.arm_object_contacts(poses_b, objects)
        if not contacts:
            return objects
        by_object: dict[int, list] = {}
        for contact in contacts:
            n = contact.normal
            if abs(n[2]) > opts.vertical_normal_limit:
                return (Invalid.CONTACT_FROM_ABOVE,
                        f"{self._shape_links[contact.shape]} presses on "
                        f"'{self._names[contact.obj]}' from above (normal z = {n[2]:+.2f})")
            if contact.obj in self._static:
                return (Invalid.ARM_OBSTACLE,
                        f"{self._shape_links[contact.shape]} touches '{self._names[contact.obj]}'"
                        f", a static object for this planner")
            by_object.setdefault(contact.obj, []).append(contact)
        new_objects = objects.copy()
        changed: list[int] = []
        for obj, obj_contacts in by_object.items():
            result = self._push_object(obj, objects[obj], obj_contacts, poses_a, poses_b)
            if isinstance(result, tuple):
                return result
            if result is not None:
                new_objects[obj] = result
                changed.append(obj)
                moved.add(obj)
                pushing_links.update(self._shape_links[c.shape] for c in obj_contacts)
        if changed:
            after = self.world.arm_object_contacts(poses_b, new_objects, objects=changed)
            depth = max((c.depth for c in after), default=0.0)
            still = [c.depth for c in contacts if c.obj not in changed]
            depth = max([depth, *still])
        else:
            depth = max(c.depth for c in contacts)
        if depth > opts.penetration_tolerance:
            return (Invalid.RESIDUAL_PENETRATION,
                    f"arm still penetrates an object by {depth * 1000:.1f} mm after the push")
        if changed:
            problem = self._object_checks(new_objects, changed)
            if problem is not None:
                return problem
        return new_objects

    def _push_object(self, obj, pose, contacts, poses_a, poses_b):
        """Twist of one object from its contacts; None if it does not move."""
        cos, sin = math.cos(pose[2]), math.sin(pose[2])
        k = len(contacts)
        points, normals, disps = np.empty((k, 2)), np.empty((k, 2)), np.empty((k, 2))
        for row, contact in enumerate(contacts):
            p = contact.point
            # The material point of the link now at p was at T_a T_b^-1 p before the substep.
            t_a, t_b = poses_a[contact.shape], poses_b[contact.shape]
            p_before = t_a[:3, :3] @ (t_b[:3, :3].T @ (p - t_b[:3, 3])) + t_a[:3, 3]
            dx, dy = p[0] - p_before[0], p[1] - p_before[1]
            nx, ny = contact.normal[0], contact.normal[1]
            n_norm = math.hypot(nx, ny)
            nx, ny = nx / n_norm, ny / n_norm
            d_n = dx * nx + dy * ny
            if d_n > 1e-12:
                # Normal push needed to undo the penetration (planar), at most the substep's own
                # normal motion plus the tolerated residual.
                wanted = min(contact.depth / n_norm, d_n + self.options.penetration_tolerance)
                scale = max(wanted, 0.0) / d_n
                dx, dy = dx * scale, dy * scale
            # World -> object frame: R(yaw)^T v.
            px, py = p[0] - pose[0], p[1] - pose[1]
            points[row] = (cos * px + sin * py, -sin * px + cos * py)
            normals[row] = (cos * nx + sin * ny, -sin * nx + cos * ny)
            disps[row] = (cos * dx + sin * dy, -sin * dx + cos * dy)
        if k == 1:
            result = pushing.single_contact_twist(self.c[obj], points[0], normals[0], disps[0],
                                                  self.mu[obj])
        else:
            result = pushing.object_twist(self.c[obj], points, normals, disps, self.mu[obj])
        if result.mode == "jammed":
            links = sorted({self._shape_links[c.shape] for c in contacts})
            return (Invalid.JAMMING,
                    f"'{self._names[obj]}' is jammed between {', '.join(links)}")
        if not result.twist.any():
            return None
        if self.options.tipping:
            height = max(c.point[2] for c in contacts) - self.scene.table.height
            if tips_over(self.scene.objects[obj], result.twist, height):
                return (Invalid.TIPPING,
                        f"'{self._names[obj]}' would tip over: pushed {height * 100:.1f} cm "
                        f"above the table")
        return pushing.apply_twist(pose, result.twist)

    def _object_checks(self, objects: np.ndarray, which) -> tuple[Invalid, str] | None:
        opts = self.options
        which = set(which)
        for i, j in self.world.object_overlaps(objects, tol=opts.overlap_tolerance):
            if i in which or j in which:
                return (Invalid.OBJECT_OVERLAP,
                        f"'{self._names[i]}' and '{self._names[j]}' overlap")
        for i, name in self.world.object_obstacle_overlaps(objects, tol=opts.overlap_tolerance):
            if i in which:
                return Invalid.OBJECT_OBSTACLE, f"'{self._names[i]}' overlaps obstacle '{name}'"
        for i in self.world.objects_off_table(objects):
            if i in which:
                return Invalid.OFF_TABLE, f"'{self._names[i]}' left the table"
        return None
