"""Collision and contact queries between the arm, the table, the obstacles and the movable
objects (docs/design.md world model, §5 contacts and validity), with python-fcl as narrow phase.

Geometry, all in the robot base frame (m, rad):

- table: a box whose top face is at ``table.height`` and which is `TABLE_THICKNESS` thick below;
- obstacles: boxes standing on the table top (static, placed once);
- movable objects: vertical prisms (box or cylinder) standing on the table top, placed from a
  planar pose (x, y, yaw) at every query;
- arm: the robot config's contact shapes (`RobotModel.contact_shapes`) placed from
  `RobotModel.shape_poses(q)`; capsules and cylinders have their axis along the shape's z.

Every fcl geometry and `CollisionObject` is built once in the constructor; a query only updates
the transforms of the bodies that survive the broad phase. The broad phase is vectorised numpy:
bounding spheres (arm shapes vs objects and obstacles), a height and footprint test (arm vs
table) and footprint circles (object vs object and obstacle). Pairs it rejects never reach the
narrow phase.

**Arm narrow phase** (python-fcl 0.7.0.11, libccd solver; measured, see
``test/test_collision.py``):

- ``fcl.collide`` (MPR) contact normals and depths for capsule-vs-box are approximations: against
  exact values the normals were off by up to 70 degrees and depths by up to 3 cm. Not used for
  contacts.
- ``fcl.distance`` with ``enable_signed_distance`` runs EPA on penetrating pairs and is accurate
  there (depth ~1e-6 m, direction < 1 degree) BUT aborts the whole process (an uncaught C++
  ``std::logic_error`` from ``validateNearestFeatureOfPolytopeBeingEdge``, which the Cython
  binding does not translate) when two shapes just touch. Reproduced with a capsule resting on
  a cylinder's side at depth 0.
- Plain ``fcl.distance`` (GJK) between polytopes is exact and cheap (~2.5 us).

So every arm shape is treated as a *core* inflated by a radius: a capsule is a segment (an fcl
capsule of radius 0) plus its radius, a sphere a point plus its radius; a box or cylinder is its
own core with radius 0. The signed distance is d = GJK(core, body) - radius, and the contact
point and the normal (from the arm into the body) come from the core's closest points:

- against a box (objects, obstacles, the table) this is exact at any depth while the core
  itself stays outside the box;
- against a cylinder object GJK converges only asymptotically on the curved side (depth error
  ~2e-5 m at the 99th percentile, 6e-4 m worst; normal ~1 degree), so there the core answer is
  used for near contacts and penetrations up to `EPA_MIN_DEPTH` (1 mm), and EPA beyond it.

EPA runs only when the penetration is known to exceed `EPA_MIN_DEPTH` (deeper than the gate
on a cylinder, or the core itself reaching into the body), where it is accurate (~1e-6 m) and
its degenerate touching case cannot occur: 0 failures in 2e5 stress trials, where ungated
calls abort within seconds (``test_touching_configurations_do_not_abort_the_process``). A box
or cylinder arm shape, which has no inflating radius, proves that depth with a copy shrunk by
`EPA_MIN_DEPTH`; shallower than that it falls back to fcl.collide's contact, its depth capped
at `EPA_MIN_DEPTH`.

**Object vs object and obstacle**: all of them are vertical prisms standing on the same table
top, so their 3D penetration depth is exactly min(2D footprint penetration, the lower height):
rectangles by the separating-axis theorem, disks by centre distance, rectangle-disk by the
closest point. These are computed in closed form here, exact and free of the EPA failure above
(boxes pushed side by side touch exactly).

A `CollisionWorld` holds mutable fcl transforms: it is not thread-safe; give every planning
thread its own (as with `RobotModel.copy()`).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass

import fcl
import numpy as np

from rearrangement_planner.model.robot import ContactShape, RobotModel
from rearrangement_planner.model.scene import MovableObject, Scene
from rearrangement_planner.physics import kernels

TABLE_THICKNESS = 0.05   # m, the table box extends this far below its top face
EPA_MIN_DEPTH = 1e-3     # m, fcl's EPA (signed distance) runs only on penetrations deeper than this
# Closest points nearer than this (m) do not define a direction; the object's face normal is
# used instead.
_WITNESS_EPS = 1e-9


@dataclass(frozen=True, eq=False)
class Contact:
    """A contact between arm contact shape `shape` and movable object `obj` (docs/design.md).

    `point` (3,): contact point in the base frame, on the object's surface (m).
    `normal` (3,): unit vector in the base frame pointing FROM the arm shape INTO the object,
    i.e. the direction in which the arm pushes the object.
    `depth`: penetration depth (m), > 0 when penetrating; a near contact within the query's
    margin has depth = -(gap distance) <= 0.
    """

    shape: int
    obj: int
    point: np.ndarray
    normal: np.ndarray
    depth: float

    def __post_init__(self) -> None:
        for name in ("point", "normal"):
            a = np.array(getattr(self, name), dtype=float)
            a.setflags(write=False)
            object.__setattr__(self, name, a)


def _rot_z(yaw: float) -> np.ndarray:
    c, s = math.cos(yaw), math.sin(yaw)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _packed_boxes(lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """(N, 8) rows (hi, -lo, inf, inf) of axis-aligned boxes, the right-hand side of
    `_overlapping`."""
    boxes = np.full((len(lo), 8), np.inf)
    boxes[:, :3] = hi
    boxes[:, 3:6] = -lo
    return boxes


def _overlapping(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(A, B) mask of the box pairs whose interiors overlap: a's rows packed as (lo, -hi, -inf,
    -inf), b's as (hi, -lo, inf, inf), so that a_lo < b_hi and a_hi > b_lo on every axis is
    one comparison of eight values per pair. The eight booleans of a pair are read as one
    64-bit word (all true = 0x0101010101010101): one broadcast comparison and no reduction
    over the axes, which matters at a few microseconds per call in the physics step."""
    hits = a[:, None, :] < b[None, :, :]
    return hits.view(np.uint64)[..., 0] == _ALL_TRUE


_ALL_TRUE = np.frombuffer(b"\x01" * 8, dtype=np.uint64)[0]


def _geometry(kind: str, dims: Sequence[float], shrink: float = 0.0) -> fcl.CollisionGeometry:
    """fcl geometry of a contact shape (`ContactShape.dims` convention), optionally shrunk by
    `shrink` (m) on every side."""
    tiny = 1e-9
    if kind == "capsule":
        return fcl.Capsule(max(dims[0] - shrink, 0.0), dims[1])
    if kind == "sphere":
        return fcl.Sphere(max(dims[0] - shrink, 0.0))
    if kind == "cylinder":
        return fcl.Cylinder(max(dims[0] - shrink, tiny), max(dims[1] - 2 * shrink, tiny))
    if kind == "box":
        return fcl.Box(*(max(d - 2 * shrink, tiny) for d in dims))
    raise ValueError(f"contact shape kind {kind!r}; use one of capsule, sphere, box, cylinder")


@dataclass(frozen=True)
class _ArmShape:
    """fcl bodies of one arm contact shape: `full` = `core` inflated by `radius` (m).
    Capsules and spheres have a segment / point core; boxes and cylinders are their own core
    (radius 0) and keep a copy shrunk by EPA_MIN_DEPTH to prove deep penetration."""

    full: fcl.CollisionObject
    core: fcl.CollisionObject
    radius: float
    shrunk: fcl.CollisionObject | None

    @staticmethod
    def build(shape: ContactShape) -> _ArmShape:
        full = fcl.CollisionObject(_geometry(shape.kind, shape.dims), fcl.Transform())
        if shape.kind in ("capsule", "sphere"):
            core = fcl.CollisionObject(_geometry(shape.kind, shape.dims, shrink=shape.dims[0]),
                                       fcl.Transform())
            return _ArmShape(full, core, float(shape.dims[0]), None)
        shrunk = fcl.CollisionObject(_geometry(shape.kind, shape.dims, shrink=EPA_MIN_DEPTH),
                                     fcl.Transform())
        return _ArmShape(full, full, 0.0, shrunk)


def prism_penetration(shape_a: str, size_a: Sequence[float], pose_a: Sequence[float],
                      shape_b: str, size_b: Sequence[float], pose_b: Sequence[float]) -> float:
    """Penetration depth (m) of two vertical prisms standing on the same plane; <= 0 when they
    are apart (then minus a lower bound of the gap: the exact gap for disk-disk and
    rectangle-disk, the largest separating-axis gap for rectangles).

    `shape_*` is 'box' or 'cylinder', `size_*` the full extents (x, y, z) (a cylinder's is
    (2r, 2r, h)), `pose_*` the planar pose (x, y, yaw) in a common frame. Compiled:
    `kernels.prism_penetration`, which the physics step calls directly.
    """
    return float(kernels.prism_penetration(
        _PRISM_KIND[shape_a], np.asarray(size_a, dtype=float), float(pose_a[0]),
        float(pose_a[1]), float(pose_a[2]), _PRISM_KIND[shape_b],
        np.asarray(size_b, dtype=float), float(pose_b[0]), float(pose_b[1]), float(pose_b[2])))


_PRISM_KIND = {"box": kernels.BOX, "cylinder": kernels.CYLINDER}


def _inward_normal(shape: str, half: np.ndarray, centre_z: float, pose: np.ndarray,
                   point: np.ndarray) -> np.ndarray:
    """Inward unit normal (base frame) of the face nearest to `point` of an upright box or
    cylinder (`shape`) of half extents `half`, its centre at (pose x, y, centre_z), yaw pose[2]."""
    rot = _rot_z(pose[2])
    local = rot.T @ (point - np.array([pose[0], pose[1], centre_z]))
    if shape == "cylinder":
        radial = math.hypot(local[0], local[1])
        if radial / half[0] >= abs(local[2]) / half[2] and radial > 0.0:
            outward = np.array([local[0] / radial, local[1] / radial, 0.0])
        else:
            outward = np.array([0.0, 0.0, 1.0 if local[2] >= 0 else -1.0])
    else:
        axis = int(np.argmax(np.abs(local) / half))
        outward = np.zeros(3)
        outward[axis] = 1.0 if local[axis] >= 0 else -1.0
    return -(rot @ outward)


class _ArmBodies:
    """The fcl bodies of the arm's contact shapes with their placement and broad-phase boxes,
    reused while the arm configuration is unchanged (one substep asks several queries at one
    configuration), and the arm's narrow phase against any placed body."""

    def __init__(self, shapes: Sequence[ContactShape]):
        self._bodies = [_ArmShape.build(s) for s in shapes]
        # Tighter broad phase: a capsule is its axis segment (half-length along the shape's z
        # axis) swept by its radius; other shapes are their bounding sphere.
        self.seg_half = np.array([0.5 * s.dims[1] if s.kind == "capsule" else 0.0
                                  for s in shapes], dtype=float)
        self.seg_radius = np.array([s.dims[0] if s.kind == "capsule" else s.bounding_radius
                                    for s in shapes], dtype=float)
        self._boxes_for: np.ndarray | None = None
        self._boxes = np.zeros((0, 8))
        self._cores_for: np.ndarray | None = None
        self._cores_placed: list[bool] = []
        self._gjk = fcl.DistanceRequest(enable_nearest_points=True)
        self._epa = fcl.DistanceRequest(enable_nearest_points=True, enable_signed_distance=True)
        self._contact = fcl.CollisionRequest(num_max_contacts=1, enable_contact=True)

    def place(self, s: int, shape_poses: np.ndarray) -> None:
        """Move arm shape s's core to its pose (the full/shrunk bodies follow on demand).
        Within one read-only pose array (RobotModel.shape_poses caches it per configuration)
        a core already placed stays placed: one substep queries the static world, the objects
        and the pushed objects again at the same configuration."""
        if shape_poses is not self._cores_for:
            self._cores_for = None if shape_poses.flags.writeable else shape_poses
            self._cores_placed = [False] * len(self._bodies)
        elif self._cores_placed[s]:
            return
        self._bodies[s].core.setTransform(fcl.Transform(shape_poses[s, :3, :3],
                                                     shape_poses[s, :3, 3]))
        if self._cores_for is not None:
            self._cores_placed[s] = True

    def boxes(self, shape_poses: np.ndarray) -> np.ndarray:
        """Axis-aligned bounding boxes of the arm's contact shapes, exact for capsules (segment
        end points -/+ radius), bounding sphere otherwise, packed for `_overlapping`: (S, 8)
        rows (lo_x, lo_y, lo_z, -hi_x, -hi_y, -hi_z, -inf, -inf). The last result is reused for
        the same read-only pose array (RobotModel.shape_poses caches it), since one physics
        substep asks several queries at one arm configuration."""
        if shape_poses is self._boxes_for and not shape_poses.flags.writeable:
            return self._boxes
        centres = shape_poses[:, :3, 3]
        extent = np.abs(shape_poses[:, :3, 2]) * self.seg_half[:, None] \
            + self.seg_radius[:, None]
        boxes = np.full((len(centres), 8), -np.inf)
        boxes[:, :3] = centres - extent
        boxes[:, 3:6] = -(centres + extent)
        self._boxes_for, self._boxes = shape_poses, boxes
        return boxes

    def distance(self, s: int, shape_poses: np.ndarray, body: fcl.CollisionObject,
                      margin: float, polytope: bool
                      ) -> tuple[float, np.ndarray, np.ndarray | None] | None:
        """Signed distance d (m; < 0 when penetrating) between arm shape s, whose core is
        already placed, and a placed body: (d, closest point on the body, unit normal from the
        arm into the body or None if undefined), or None as soon as d >= margin is known.
        `polytope`: the body is a box, so GJK from a capsule's segment core is exact at any
        depth; on a curved body EPA is more accurate once it is safe. See the module
        docstring for why the core and the EPA gate."""
        arm = self._bodies[s]
        result = fcl.DistanceResult()
        gap = fcl.distance(arm.core, body, self._gjk, result)
        if gap > 0.0:
            d = gap - arm.radius
            if d >= margin:
                return None
            if -d <= EPA_MIN_DEPTH or (polytope and gap > _WITNESS_EPS):
                p_core, p_body = result.nearest_points
                if gap > _WITNESS_EPS:
                    return d, p_body, (p_body - p_core) / gap
                return d, p_body, None
        # Penetration deeper than EPA_MIN_DEPTH, or a box/cylinder shape whose depth is unknown.
        pose = fcl.Transform(shape_poses[s, :3, :3], shape_poses[s, :3, 3])
        arm.full.setTransform(pose)
        if arm.shrunk is not None:
            arm.shrunk.setTransform(pose)
            if fcl.distance(arm.shrunk, body, self._gjk, fcl.DistanceResult()) > 0.0:
                # 0 < depth < EPA_MIN_DEPTH: too shallow for EPA; MPR's contact is close enough.
                hit = fcl.CollisionResult()
                fcl.collide(arm.full, body, self._contact, hit)
                if not hit.contacts:
                    return None if margin <= 0.0 else (0.0, result.nearest_points[1], None)
                c = hit.contacts[0]
                depth = min(max(c.penetration_depth, 0.0), EPA_MIN_DEPTH)
                return -depth, np.asarray(c.pos, dtype=float), np.asarray(c.normal, dtype=float)
        result = fcl.DistanceResult()
        d = fcl.distance(arm.full, body, self._epa, result)
        p_arm, p_body = result.nearest_points
        between = p_arm - p_body       # penetrating: the arm's deepest point lies inside
        length = math.sqrt(float(between @ between))
        return d, p_body, (between / length if length > _WITNESS_EPS else None)

    def depth(self, s: int, shape_poses: np.ndarray, body: fcl.CollisionObject,
                   polytope: bool) -> float:
        hit = self.distance(s, shape_poses, body, 0.0, polytope)
        return 0.0 if hit is None else -hit[0]


class CollisionWorld:
    """Collision and contact queries for one scene and one robot (docs/design.md).

    All arrays are in the robot base frame: `shape_poses` is the (S, 4, 4) output of
    `RobotModel.shape_poses(q)`, `object_poses` an (M, 3) array of (x, y, yaw) in the order of
    `scene.objects`. The table and obstacles come from the scene and never move.
    """

    def __init__(self, scene: Scene, robot: RobotModel | None = None):
        self.scene = scene
        self.robot = robot if robot is not None else scene.robot
        table = scene.table
        self._table_top = float(table.height)
        self._table_center = np.array(table.center, dtype=float)
        self._table_half = 0.5 * np.array(table.size, dtype=float)

        # Arm contact shapes: geometry now, transforms per query.
        shapes = self.robot.contact_shapes
        self.shape_links: tuple[str, ...] = tuple(s.link for s in shapes)
        self._shapes = _ArmBodies(shapes)
        self._init_objects(scene.objects)
        self._init_static(scene)

    def _init_objects(self, objects: Sequence[MovableObject]) -> None:
        """Movable objects: vertical prisms on the table top; the z of their centre is fixed."""
        self.object_names: tuple[str, ...] = tuple(o.name for o in objects)
        self._obj_fcl = [
            fcl.CollisionObject(fcl.Cylinder(0.5 * o.size[0], o.size[2]) if o.shape == "cylinder"
                                else fcl.Box(*o.size), fcl.Transform())
            for o in objects]
        self._obj_shape = tuple(o.shape for o in objects)
        self._obj_polytope = tuple(o.shape == "box" for o in objects)
        self._obj_size = tuple(tuple(float(v) for v in o.size) for o in objects)
        self._obj_half = np.array([0.5 * o.size for o in objects], dtype=float).reshape(-1, 3)
        self._obj_z = self._table_top + self._obj_half[:, 2]
        self._obj_radius = np.array([o.bounding_radius for o in objects], dtype=float)
        self._obj_footprint = np.array([o.footprint_radius for o in objects], dtype=float)
        self._obj_pairs = np.triu_indices(len(objects), k=1)
        self._obj_pair_limit2 = (self._obj_footprint[self._obj_pairs[0]]
                                 + self._obj_footprint[self._obj_pairs[1]]) ** 2
        self._obj_kind = np.array([_PRISM_KIND[o.shape] for o in objects], dtype=np.int64)
        self._obj_size_array = np.array(self._obj_size, dtype=float).reshape(-1, 3)
        self._all_objects = np.arange(len(objects))
        # Object centres (x, y, z) for the object broad phase: z is fixed, x and y are filled
        # in per query.
        self._obj_centre = np.column_stack([np.zeros((len(objects), 2)), self._obj_z])
        self._obj_boxes = np.full((len(objects), 8), np.inf)
        self._obj_extent0 = np.column_stack([self._obj_footprint, self._obj_footprint,
                                             self._obj_half[:, 2]])
        # What the object bodies were last placed at (see _place_object).
        self._obj_placed: list[list[float] | None] = [None] * len(objects)

    def _init_static(self, scene: Scene) -> None:
        """Obstacles (boxes on the table top) and the table slab, placed once, and their
        broad-phase boxes."""
        table, obstacles = scene.table, scene.obstacles
        self.obstacle_names: tuple[str, ...] = tuple(b.name for b in obstacles)
        self._obst_size = tuple(tuple(float(v) for v in b.size) for b in obstacles)
        self._obst_pose = tuple(tuple(float(v) for v in b.pose) for b in obstacles)
        self._obst_centre = np.array(
            [[b.pose[0], b.pose[1], self._table_top + 0.5 * b.size[2]] for b in obstacles],
            dtype=float).reshape(-1, 3)
        self._obst_fcl = [fcl.CollisionObject(fcl.Box(*b.size),
                                              fcl.Transform(_rot_z(b.pose[2]), centre))
                          for b, centre in zip(obstacles, self._obst_centre, strict=True)]
        self._obst_radius = np.array([b.bounding_radius for b in obstacles], dtype=float)
        self._obst_footprint = np.array([b.footprint_radius for b in obstacles], dtype=float)

        # The table: a slab whose top face is at table.height.
        self._table_fcl = fcl.CollisionObject(
            fcl.Box(table.size[0], table.size[1], TABLE_THICKNESS),
            fcl.Transform(np.eye(3), np.array([table.center[0], table.center[1],
                                               self._table_top - 0.5 * TABLE_THICKNESS])))

        # Broad-phase boxes of the static world, packed for `_overlapping` as (1 + K, 8) rows
        # (hi_x, hi_y, hi_z, -lo_x, -lo_y, -lo_z, inf, inf): the table slab (its top face at
        # table.height), then each obstacle's bounding-sphere box.
        table_lo = self._table_center - self._table_half
        table_hi = self._table_center + self._table_half
        static_lo = np.vstack([[table_lo[0], table_lo[1], self._table_top - TABLE_THICKNESS],
                               self._obst_centre - self._obst_radius[:, None]])
        static_hi = np.vstack([[table_hi[0], table_hi[1], self._table_top],
                               self._obst_centre + self._obst_radius[:, None]])
        self._static_boxes = _packed_boxes(static_lo, static_hi)

    # -- placing bodies -----------------------------------------------------------------------

    def _place_object(self, i: int, pose: np.ndarray) -> fcl.CollisionObject:
        """Move object i's body to its planar pose (kept when the pose is unchanged: most
        objects do not move between queries)."""
        co = self._obj_fcl[i]
        key = pose.tolist()
        if key != self._obj_placed[i]:
            co.setTransform(fcl.Transform(_rot_z(key[2]),
                                          np.array([key[0], key[1], self._obj_z[i]])))
            self._obj_placed[i] = key
        return co

    def _object_poses(self, object_poses: np.ndarray) -> np.ndarray:
        poses = np.asarray(object_poses, dtype=float)
        if poses.shape != (len(self._obj_fcl), 3):
            raise ValueError(f"object_poses has shape {poses.shape}, expected "
                             f"({len(self._obj_fcl)}, 3): one (x, y, yaw) per scene object")
        return poses

    # -- arm vs static world ------------------------------------------------------------------

    def _static_hit(self, shape_poses: np.ndarray, tol: float) -> tuple[int, str, float] | None:
        # Broad phase: (S, 1 + K) mask of the shapes whose boxes overlap the table slab
        # (column 0) or an obstacle's box.
        near = _overlapping(self._shapes.boxes(shape_poses), self._static_boxes)
        if not near.any():
            return None     # the common case on the pushing plane, decided without a loop
        for s in np.flatnonzero(near.any(axis=1)).tolist():
            self._shapes.place(s, shape_poses)
            if near[s, 0]:
                depth = self._shapes.depth(s, shape_poses, self._table_fcl, True)
                if depth > tol:
                    return s, "table", depth
            for k in np.flatnonzero(near[s, 1:]).tolist():
                depth = self._shapes.depth(s, shape_poses, self._obst_fcl[k], True)
                if depth > tol:
                    return s, self.obstacle_names[k], depth
        return None

    def arm_static_collision(self, shape_poses: np.ndarray,
                             tol: float = 0.0) -> tuple[int, str] | None:
        """The first (shape index, ``'table'`` or obstacle name), in shape order, whose
        penetration depth exceeds `tol` (m); None if the arm is clear of the static world
        (docs/design.md validity: no arm-table or arm-obstacle penetration)."""
        hit = self._static_hit(np.asarray(shape_poses, dtype=float), tol)
        return None if hit is None else (hit[0], hit[1])

    # -- arm vs movable objects ---------------------------------------------------------------

    def _object_candidates(self, shape_poses: np.ndarray, poses: np.ndarray, margin: float,
                           objects: Iterable[int] | np.ndarray | None
                           ) -> tuple[np.ndarray, np.ndarray]:
        """Broad phase: (shape, object) index arrays, sorted by shape then object, of the pairs
        whose axis-aligned boxes come within `margin`: the shape's box (exact for a capsule)
        against the object's footprint-circle box and height range. Vectorised over all pairs."""
        extent = self._object_extent(margin)
        if objects is None:
            sel, centre, boxes = None, self._obj_centre, self._obj_boxes
            centre[:, :2] = poses[:, :2]
        else:
            # any iterable of indices (list, set, array); sorted so contacts come out in order
            sel = (np.unique(objects.astype(np.intp)) if isinstance(objects, np.ndarray)
                   else np.array(sorted(set(objects)), dtype=np.intp))
            centre, extent = self._obj_centre[sel], extent[sel]
            centre[:, :2] = poses[sel, :2]
            boxes = np.full((len(sel), 8), np.inf)
        # Packed as in _packed_boxes (hi, -lo, inf, inf), written in place: -(c - e) == e - c
        # exactly in IEEE arithmetic.
        np.add(centre, extent, out=boxes[:, :3])
        np.subtract(extent, centre, out=boxes[:, 3:6])
        near = _overlapping(self._shapes.boxes(shape_poses), boxes)
        shape_idx, col = near.nonzero()
        return shape_idx, (col if sel is None else sel[col])

    def _object_extent(self, margin: float) -> np.ndarray:
        """(M, 3) half-extents of the objects' broad-phase boxes grown by `margin`: the
        footprint circle's radius in x and y, the half height in z (the margin-0 boxes are
        built once)."""
        if margin == 0.0:
            return self._obj_extent0
        extent = np.empty((len(self._obj_fcl), 3))
        extent[:, :2] = (self._obj_footprint + margin)[:, None]
        extent[:, 2] = self._obj_half[:, 2] + margin
        return extent

    def object_candidates(self, shape_poses: np.ndarray, object_poses: np.ndarray,
                          margin: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
        """The broad phase alone: (shape, object) index arrays of the pairs whose bounding
        boxes come within `margin` (m). An empty result means no arm-object contact within
        `margin`; a pair in it may still be apart (boxes are conservative)."""
        return self._object_candidates(np.asarray(shape_poses, dtype=float),
                                       self._object_poses(object_poses), margin, None)

    def arm_object_contacts(self, shape_poses: np.ndarray, object_poses: np.ndarray,
                            margin: float = 0.0,
                            objects: Iterable[int] | np.ndarray | None = None) -> list[Contact]:
        """Contacts (docs/design.md) between the arm's contact shapes and the movable objects:
        every penetrating pair and, with `margin` > 0 (m), every pair whose gap is below
        `margin`. `objects` restricts the query to these object indices. Sorted by shape index
        then object index; one contact per (shape, object) pair."""
        shape_poses = np.asarray(shape_poses, dtype=float)
        poses = self._object_poses(object_poses)
        shape_idx, obj_idx = self._object_candidates(shape_poses, poses, margin, objects)
        contacts: list[Contact] = []
        if shape_idx.size == 0:
            return contacts
        placed = [False] * len(self._obj_fcl)
        last_shape = -1
        for s, i in zip(shape_idx.tolist(), obj_idx.tolist(), strict=True):
            if s != last_shape:
                self._shapes.place(s, shape_poses)
                last_shape = s
            if not placed[i]:
                self._place_object(i, poses[i])
                placed[i] = True
            hit = self._shapes.distance(s, shape_poses, self._obj_fcl[i], margin,
                                     self._obj_polytope[i])
            if hit is None or hit[0] >= margin:
                continue
            d, point, normal = hit
            if normal is None:
                normal = _inward_normal(self._obj_shape[i], self._obj_half[i], self._obj_z[i],
                                        poses[i], point)
            contacts.append(Contact(s, i, point, normal, -float(d)))
        return contacts

    def arm_object_penetration(self, shape_poses: np.ndarray, object_poses: np.ndarray) -> float:
        """The largest penetration depth (m) over all arm-shape/object pairs; 0 if none
        (docs/design.md: residual arm-object penetration must stay below a small tolerance)."""
        contacts = self.arm_object_contacts(shape_poses, object_poses)
        return max((c.depth for c in contacts), default=0.0)

    # -- objects vs objects, obstacles, table -------------------------------------------------

    def object_overlaps(self, object_poses: np.ndarray,
                        tol: float = 0.0) -> list[tuple[int, int]]:
        """Pairs (i, j), i < j, of movable objects that penetrate deeper than `tol` (m)
        (docs/design.md validity: no object-object overlap). Footprint-circle broad phase, then the
        exact `prism_penetration`."""
        poses = self._object_poses(object_poses)
        first, second = self._obj_pairs
        if first.size == 0:
            return []
        dx = poses[first, 0] - poses[second, 0]
        dy = poses[first, 1] - poses[second, 1]
        near = (dx * dx + dy * dy < self._obj_pair_limit2).nonzero()[0]
        overlaps: list[tuple[int, int]] = []
        for k in near.tolist():
            i, j = int(first[k]), int(second[k])
            depth = prism_penetration(self._obj_shape[i], self._obj_size[i], poses[i].tolist(),
                                      self._obj_shape[j], self._obj_size[j], poses[j].tolist())
            if depth > tol:
                overlaps.append((i, j))
        return overlaps

    def objects_overlap(self, object_poses: np.ndarray, tol: float = 0.0) -> bool:
        """Whether `object_overlaps` finds a pair: the same test in one compiled call (the
        samplers ask it of every arrangement they draw)."""
        poses = np.array(self._object_poses(object_poses), dtype=float)   # writable: one signature
        kinds, sizes, first, second, limit2 = self.overlap_arrays()
        return bool(kernels.any_prism_overlap(kinds, sizes, poses, first, second, limit2,
                                              float(tol)))

    def overlap_arrays(self) -> tuple[np.ndarray, ...]:
        """`kernels.any_prism_overlap`'s arguments but the poses and the tolerance: the
        objects' kinds and sizes, the pairs to test and their squared bounds."""
        first, second = self._obj_pairs
        return self._obj_kind, self._obj_size_array, first, second, self._obj_pair_limit2

    def object_obstacle_overlaps(self, object_poses: np.ndarray,
                                 tol: float = 0.0) -> list[tuple[int, str]]:
        """Pairs (object index, obstacle name) that penetrate deeper than `tol` (m)."""
        poses = self._object_poses(object_poses)
        if not self._obst_fcl or len(poses) == 0:
            return []
        diff = poses[:, None, :2] - self._obst_centre[:, :2]
        limit = self._obj_footprint[:, None] + self._obst_footprint
        obj_idx, obst_idx = ((diff * diff).sum(axis=2) < limit * limit).nonzero()
        overlaps: list[tuple[int, str]] = []
        for i, k in zip(obj_idx.tolist(), obst_idx.tolist(), strict=True):
            depth = prism_penetration(self._obj_shape[i], self._obj_size[i], poses[i].tolist(),
                                      "box", self._obst_size[k], self._obst_pose[k])
            if depth > tol:
                overlaps.append((i, self.obstacle_names[k]))
        return overlaps

    def objects_off_table(self, object_poses: np.ndarray) -> list[int]:
        """Indices of objects whose centre lies outside the table rectangle (docs/design.md:
        objects stay on the table)."""
        poses = self._object_poses(object_poses)
        off = (np.abs(poses[:, :2] - self._table_center) > self._table_half).any(axis=1)
        return off.nonzero()[0].tolist()

    # -- whole-arm check ----------------------------------------------------------------------

    def arm_in_collision(self, q: np.ndarray, object_poses: np.ndarray,
                         tol: float = 0.0) -> str | None:
        """Why the arm at configuration q (rad) penetrates the table, an obstacle or a movable
        object deeper than `tol` (m), as one human-readable sentence; None if it is clear.
        Used to validate start configurations (docs/design.md "The world model")."""
        shape_poses = self.robot.shape_poses(np.asarray(q, dtype=float))
        hit = self._static_hit(shape_poses, tol)
        if hit is not None:
            s, what, depth = hit
            target = "the table" if what == "table" else f"obstacle '{what}'"
            return (f"{self.shape_links[s]} (contact shape {s}) penetrates {target} by "
                    f"{1000 * depth:.1f} mm")
        for c in self.arm_object_contacts(shape_poses, object_poses):
            if c.depth > tol:
                return (f"{self.shape_links[c.shape]} (contact shape {c.shape}) penetrates "
                        f"object '{self.object_names[c.obj]}' by {1000 * c.depth:.1f} mm")
        return None
