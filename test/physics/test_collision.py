"""Collision and contact queries (docs/design.md): constructed touching / penetrating / separated
cases with known depths and normals, the broad phase, and the fcl failure the narrow phase
has to steer around."""

from __future__ import annotations

import math
import subprocess
import sys
import textwrap

import fcl
import numpy as np
import pytest
import yaml

from rearrangement_planner.model.resources import robots_dir
from rearrangement_planner.model.robot import RobotConfig, RobotModel
from rearrangement_planner.model.scene import Goal, MovableObject, Obstacle, Scene, Table
from rearrangement_planner.physics import collision
from rearrangement_planner.physics.collision import (
    EPA_MIN_DEPTH,
    TABLE_THICKNESS,
    CollisionWorld,
    Contact,
    prism_penetration,
)

TABLE_TOP = 0.1      # a table top above the base, so that heights are really tested
R_CAP, L_CAP = 0.03, 0.2
BOX = MovableObject.box("box", (0.06, 0.08, 0.12), (0.40, 0.0, 0.0))
CAN = MovableObject.cylinder("can", 0.04, 0.12, (0.60, 0.30, 0.0))
FAR = MovableObject.box("far", (0.05, 0.05, 0.10), (0.85, -0.50, 0.0))
POST = Obstacle("post", (0.05, 0.05, 0.30), (0.80, 0.40, 0.0))
# Probe arm: one shape of every kind, all on the hand link; tests place them directly.
CAPSULE, SPHERE, CUBE, CYLINDER = range(4)
PROBE_SHAPES = [
    {"link": "panda_hand", "type": "capsule", "radius": R_CAP,
     "points": [[0, 0, -L_CAP / 2], [0, 0, L_CAP / 2]]},
    {"link": "panda_hand", "type": "sphere", "radius": 0.03, "center": [0, 0, 0]},
    {"link": "panda_hand", "type": "box", "size": [0.04, 0.04, 0.04]},
    {"link": "panda_hand", "type": "cylinder", "radius": 0.02, "length": 0.1},
]


@pytest.fixture(scope="module")
def probe() -> RobotModel:
    data = yaml.safe_load((robots_dir() / "panda.yaml").read_text())
    data.update(name="probe", contact_shapes=PROBE_SHAPES)
    return RobotModel(RobotConfig.from_dict(data, base_dir=robots_dir()))


def make_scene(robot: RobotModel, objects=(BOX, CAN, FAR), obstacles=(POST,)) -> Scene:
    return Scene(robot, robot.home, Table((0.55, 0.0), (0.8, 1.2), TABLE_TOP), obstacles,
                 objects, Goal(objects[0].name, (0.5, -0.3)))


@pytest.fixture(scope="module")
def world(probe: RobotModel) -> CollisionWorld:
    return CollisionWorld(make_scene(probe))


def rot_z_to(axis) -> np.ndarray:
    """A rotation whose z column (the capsule/cylinder axis) is `axis`."""
    axis = np.asarray(axis, dtype=float) / np.linalg.norm(axis)
    helper = np.array([1.0, 0.0, 0.0]) if abs(axis[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    x = np.cross(helper, axis)
    x /= np.linalg.norm(x)
    return np.column_stack([x, np.cross(axis, x), axis])


def place(shape: int, position, rotation=None) -> np.ndarray:
    """(4, 4, 4) shape poses: `shape` at the given pose, the others parked far above."""
    poses = np.tile(np.eye(4), (len(PROBE_SHAPES), 1, 1))
    poses[:, :3, 3] = [0.0, 0.0, 10.0]
    poses[shape, :3, 3] = position
    if rotation is not None:
        poses[shape, :3, :3] = rotation
    return poses


def initial(world: CollisionWorld) -> np.ndarray:
    return world.scene.object_poses


def box_face_point(yaw: float, offset: float, z: float) -> tuple[np.ndarray, np.ndarray]:
    """A point `offset` outside the centre of BOX's local +x face (at yaw) and the face's
    outward normal."""
    n = np.array([math.cos(yaw), math.sin(yaw), 0.0])
    centre = np.array([BOX.pose[0], BOX.pose[1], z])
    return centre + (0.03 + offset) * n, n


# -- arm shape vs movable object -----------------------------------------------------------------


@pytest.mark.parametrize("yaw", [0.0, 0.7])
@pytest.mark.parametrize("depth", [0.04, 0.01, 0.002, 0.0005, 1e-5, -0.004])
def test_capsule_against_box_face(world: CollisionWorld, depth: float, yaw: float) -> None:
    """A horizontal capsule parallel to a box face: depth, point and normal are exact. 0.04 puts
    the capsule's axis inside the box (EPA path), 0.01 and 0.002 are above the EPA gate, the
    rest use the segment core; -0.004 is a near contact inside a 1 cm margin."""
    poses = initial(world).copy()
    poses[0, 2] = yaw
    centre, n = box_face_point(yaw, R_CAP - depth, TABLE_TOP + 0.06)
    tangent = np.array([-n[1], n[0], 0.0])
    shapes = place(CAPSULE, centre, rot_z_to(tangent))
    contacts = world.arm_object_contacts(shapes, poses, margin=0.01)
    assert [(c.shape, c.obj) for c in contacts] == [(CAPSULE, 0)]
    c = contacts[0]
    # GJK from the segment core is exact on a box; with the axis inside the box (0.04) only
    # EPA can answer, to ~1e-6 m and a few 1e-6 rad
    tol = 1e-5 if depth > R_CAP else 1e-6
    assert c.depth == pytest.approx(depth, abs=tol)
    assert np.allclose(c.normal, -n, atol=tol)
    assert np.dot(c.point - centre, n) == pytest.approx(-(R_CAP - depth), abs=tol)  # on the face
    assert np.linalg.norm(c.normal) == pytest.approx(1.0)
    assert world.arm_object_penetration(shapes, poses) == pytest.approx(max(depth, 0), abs=1e-6)
    if depth < 0:
        assert world.arm_object_contacts(shapes, poses) == []   # no margin, no contact


def test_capsule_against_box_edge(world: CollisionWorld) -> None:
    """A vertical capsule at the box's (+x, +y) vertical edge, diagonally: the normal points
    from the capsule towards the edge."""
    corner = np.array([0.43, 0.04, TABLE_TOP + 0.06])
    direction = np.array([1.0, 1.0, 0.0]) / math.sqrt(2)
    for depth in (0.003, 0.0002, -0.002):
        centre = corner + (R_CAP - depth) * direction
        contacts = world.arm_object_contacts(place(CAPSULE, centre), initial(world), margin=0.01)
        assert len(contacts) == 1
        assert contacts[0].depth == pytest.approx(depth, abs=1e-6)
        assert np.allclose(contacts[0].normal, -direction, atol=1e-5)
        assert np.allclose(contacts[0].point, [0.43, 0.04, contacts[0].point[2]], atol=1e-6)


@pytest.mark.parametrize("theta", [0.0, 2.0, -2.5])
@pytest.mark.parametrize("depth", [0.01, 0.0005, -0.003])
def test_capsule_against_cylinder(world: CollisionWorld, theta: float, depth: float) -> None:
    """A vertical capsule beside the can and a horizontal one across it: the depth is within
    GJK's accuracy on the curved side and the normal points at the can's axis."""
    radial = np.array([math.cos(theta), math.sin(theta), 0.0])
    axis_point = np.array([CAN.pose[0], CAN.pose[1], TABLE_TOP + 0.06])
    for rotation in (None, rot_z_to([-radial[1], radial[0], 0.0])):
        centre = axis_point + (0.04 + R_CAP - depth) * radial
        contacts = world.arm_object_contacts(place(CAPSULE, centre, rotation), initial(world),
                                             margin=0.01)
        assert [(c.shape, c.obj) for c in contacts] == [(CAPSULE, 1)]
        c = contacts[0]
        assert c.depth == pytest.approx(depth, abs=1e-4)
        assert math.degrees(math.acos(min(1.0, float(c.normal @ -radial)))) < 1.0
        assert np.linalg.norm(c.point[:2] - axis_point[:2]) == pytest.approx(0.04, abs=1e-4)


@pytest.mark.parametrize("depth", [0.005, 0.0005, -0.003])
@pytest.mark.parametrize("shape", [SPHERE, CUBE, CYLINDER])
def test_other_shape_kinds_against_a_box(world: CollisionWorld, shape: int, depth: float) -> None:
    """Sphere (point core), box and cylinder shapes (own core, shrunk copy gating EPA) pressed
    onto the box's +x face."""
    half_x = {SPHERE: 0.03, CUBE: 0.02, CYLINDER: 0.02}[shape]
    centre, n = box_face_point(0.0, half_x - depth, TABLE_TOP + 0.06)
    contacts = world.arm_object_contacts(place(shape, centre), initial(world), margin=0.01)
    assert [(c.shape, c.obj) for c in contacts] == [(shape, 0)]
    c = contacts[0]
    if depth > 0 and depth < EPA_MIN_DEPTH and shape != SPHERE:
        # below the EPA gate a box/cylinder shape falls back to fcl.collide's contact: only
        # "penetrating, by less than the gate" is guaranteed
        assert 0 < c.depth <= EPA_MIN_DEPTH
        assert c.normal @ -n > 0.9
    else:
        # GJK/EPA converge only asymptotically on a cylinder's curved side
        tol = 5e-5 if shape == CYLINDER else 1e-6
        assert c.depth == pytest.approx(depth, abs=tol)
        assert np.allclose(c.normal, -n, atol=tol)


def test_witness_points_coincide_uses_the_face_normal(world: CollisionWorld) -> None:
    """A box shape touching the box object's +x face (gap ~0): the normal is still -x."""
    centre, n = box_face_point(0.0, 0.02 + 1e-12, TABLE_TOP + 0.06)
    contacts = world.arm_object_contacts(place(CUBE, centre), initial(world), margin=0.01)
    assert len(contacts) == 1 and abs(contacts[0].depth) < 1e-6
    assert np.allclose(contacts[0].normal, -n, atol=1e-6)


def test_pressing_on_top_gives_a_vertical_normal(world: CollisionWorld) -> None:
    """docs/design.md rejects contacts whose normal is mostly vertical; they must come out so."""
    top = np.array([BOX.pose[0], BOX.pose[1], TABLE_TOP + 0.12 + R_CAP - 0.002])
    contacts = world.arm_object_contacts(place(CAPSULE, top, rot_z_to([0, 1, 0])),
                                         initial(world))
    assert len(contacts) == 1 and np.allclose(contacts[0].normal, [0, 0, -1], atol=1e-6)
    assert contacts[0].depth == pytest.approx(0.002, abs=1e-6)


def test_several_contacts_sorted_by_shape_then_object(probe: RobotModel) -> None:
    a = MovableObject.box("a", (0.06, 0.06, 0.12), (0.40, 0.0, 0.0))
    b = MovableObject.box("b", (0.06, 0.06, 0.12), (0.40, 0.12, 0.0))
    world = CollisionWorld(make_scene(probe, objects=(a, b), obstacles=()))
    shapes = place(CAPSULE, [0.40 + 0.03 + R_CAP - 0.002, 0.05, TABLE_TOP + 0.06],
                   rot_z_to([0, 1, 0]))
    shapes[SPHERE, :3, 3] = [0.40, 0.12 - 0.03 - 0.03 + 0.001, TABLE_TOP + 0.06]  # b's -y face
    poses = world.scene.object_poses
    contacts = world.arm_object_contacts(shapes, poses)
    assert [(c.shape, c.obj) for c in contacts] == [(CAPSULE, 0), (CAPSULE, 1), (SPHERE, 1)]
    assert np.allclose(contacts[2].normal, [0, 1, 0], atol=1e-6)
    only_b = world.arm_object_contacts(shapes, poses, objects=[1])
    assert [(c.shape, c.obj) for c in only_b] == [(CAPSULE, 1), (SPHERE, 1)]
    for subset in ({1, 0}, (1, 0), np.array([1, 0])):
        assert [(c.shape, c.obj) for c in world.arm_object_contacts(shapes, poses,
                                                                    objects=subset)] == [
            (CAPSULE, 0), (CAPSULE, 1), (SPHERE, 1)]
    assert world.arm_object_contacts(shapes, poses, objects=np.array([], dtype=int)) == []
    assert world.arm_object_penetration(shapes, poses) == pytest.approx(0.002, abs=1e-6)


def segment_box_distance(p0: np.ndarray, p1: np.ndarray, half: np.ndarray):
    """Exact distance from the segment p0-p1 to the axis-aligned box [-half, half] and the
    closest points: golden-section search on the convex t -> dist(p(t), box)."""
    def at(t: float):
        p = p0 + t * (p1 - p0)
        q = np.clip(p, -half, half)
        return float(np.linalg.norm(p - q)), p, q

    lo, hi = 0.0, 1.0
    ratio = (math.sqrt(5) - 1) / 2
    for _ in range(80):
        a, b = hi - ratio * (hi - lo), lo + ratio * (hi - lo)
        if at(a)[0] <= at(b)[0]:
            hi = b
        else:
            lo = a
    return at(0.5 * (lo + hi))


def test_random_capsules_match_the_exact_segment_box_distance(world: CollisionWorld) -> None:
    """Property test (seeded): for random capsules near the box whose axis stays outside it,
    depth = radius - dist(axis segment, box) to 1e-6 m and the normal is the direction from
    the segment's closest point to the box's, within 0.1 degree."""
    rng = np.random.default_rng(7)
    half = np.array([0.03, 0.04, 0.06])
    box_centre = np.array([BOX.pose[0], BOX.pose[1], TABLE_TOP + 0.06])
    checked = 0
    while checked < 150:
        axis = rng.normal(size=3)
        axis /= np.linalg.norm(axis)
        offset = rng.uniform(-0.12, 0.12, 3)          # capsule centre in the box frame (yaw 0)
        dist, p, q = segment_box_distance(offset - 0.5 * L_CAP * axis,
                                          offset + 0.5 * L_CAP * axis, half)
        if not 1e-3 < dist < R_CAP + 0.01:
            continue
        checked += 1
        contacts = world.arm_object_contacts(place(CAPSULE, box_centre + offset, rot_z_to(axis)),
                                             initial(world), margin=0.01)
        assert len(contacts) == 1
        assert contacts[0].depth == pytest.approx(R_CAP - dist, abs=1e-6)
        angle = math.degrees(math.acos(min(1.0, float(contacts[0].normal @ (q - p) / dist))))
        assert angle < 0.1
        assert np.allclose(contacts[0].point, box_centre + q, atol=1e-5)


# -- arm shape vs table and obstacles ------------------------------------------------------------


def test_arm_against_the_table(world: CollisionWorld) -> None:
    lying = rot_z_to([1, 0, 0])
    for depth, tol, expected in [(0.01, 0.0, (CAPSULE, "table")), (0.01, 0.02, None),
                                 (0.01, 0.0099, (CAPSULE, "table")), (0.01, 0.0101, None),
                                 (0.0005, 0.0, (CAPSULE, "table")), (-0.001, 0.0, None)]:
        shapes = place(CAPSULE, [0.5, 0.2, TABLE_TOP + R_CAP - depth], lying)
        assert world.arm_static_collision(shapes, tol=tol) == expected, (depth, tol)
    # below the top but beside the table: no contact (and the broad phase skips it)
    shapes = place(CAPSULE, [-0.3, 0.0, TABLE_TOP - 0.01], lying)
    assert world.arm_static_collision(shapes) is None
    # through the slab's thickness from below is still the table
    shapes = place(SPHERE, [0.5, 0.0, TABLE_TOP - TABLE_THICKNESS - 0.02])
    assert world.arm_static_collision(shapes) == (SPHERE, "table")
    assert world.arm_static_collision(place(CUBE, [0.5, 0.0, TABLE_TOP + 0.015])) == (CUBE,
                                                                                      "table")


def test_arm_against_an_obstacle(world: CollisionWorld) -> None:
    face = np.array([0.80 - 0.025, 0.40, TABLE_TOP + 0.25])
    shapes = place(CAPSULE, face + [-R_CAP + 0.004, 0, 0], rot_z_to([0, 0, 1]))
    assert world.arm_static_collision(shapes) == (CAPSULE, "post")
    assert world.arm_static_collision(shapes, tol=0.005) is None
    shapes = place(CAPSULE, face + [-R_CAP - 0.001, 0, 0], rot_z_to([0, 0, 1]))
    assert world.arm_static_collision(shapes) is None
    # obstacles stand on the table top: above the post's top there is nothing
    shapes = place(SPHERE, [0.80, 0.40, TABLE_TOP + 0.30 + 0.031])
    assert world.arm_static_collision(shapes) is None


def test_first_static_hit_in_shape_order(world: CollisionWorld) -> None:
    shapes = place(CYLINDER, [0.5, 0.0, TABLE_TOP])
    shapes[SPHERE, :3, 3] = [0.80 - 0.025 - 0.02, 0.40, TABLE_TOP + 0.1]
    assert world.arm_static_collision(shapes) == (SPHERE, "post")


def test_arm_in_collision_names_the_link_and_the_body(default_scene: Scene) -> None:
    world = CollisionWorld(default_scene)
    poses = default_scene.object_poses
    assert world.arm_in_collision(default_scene.start_configuration, poses) is None
    lowered = np.array([0.0, 0.8, 0.0, -2.2, 0.0, 2.0, 0.785])
    reason = world.arm_in_collision(lowered, poses)
    assert reason is not None and "penetrates the table by" in reason
    assert reason.split()[0].startswith("panda_")
    assert world.arm_in_collision(lowered, poses, tol=0.5) is None


# -- objects vs objects, obstacles and the table -------------------------------------------------


def two_objects_world(probe: RobotModel, first: MovableObject, second: MovableObject):
    return CollisionWorld(make_scene(probe, objects=(first, second), obstacles=()))


@pytest.mark.parametrize(("gap", "expected"), [(-0.01, [(0, 1)]), (0.0, []), (0.002, [])])
def test_box_box_side_by_side(probe: RobotModel, gap: float, expected: list) -> None:
    a = MovableObject.box("a", (0.06, 0.08, 0.12), (0.5, 0.0, 0.0))
    b = MovableObject.box("b", (0.04, 0.04, 0.10), (0.5 + 0.05 + gap, 0.01, 0.0))
    world = two_objects_world(probe, a, b)
    assert world.object_overlaps(world.scene.object_poses) == expected
    assert world.object_overlaps(world.scene.object_poses, tol=0.02) == []


def test_prism_penetration_exact_values() -> None:
    box = ("box", (0.06, 0.08, 0.12))
    # side by side, overlap 0.01 along x
    assert prism_penetration(*box, (0, 0, 0), *box, (0.05, 0.0, 0.0)) == pytest.approx(0.01)
    # a unit-diagonal square turned 45 deg poking its corner 0.005 into a face
    sq = ("box", (0.04, 0.04, 0.1))
    corner = 0.02 * math.sqrt(2)
    d = prism_penetration(*box, (0, 0, 0), *sq, (0.03 + corner - 0.005, 0.0, math.pi / 4))
    assert d == pytest.approx(0.005)
    # disks
    can = ("cylinder", (0.07, 0.07, 0.12))
    assert prism_penetration(*can, (0, 0, 0), *can, (0.06, 0.0, 0.0)) == pytest.approx(0.01)
    assert prism_penetration(*can, (0, 0, 0), *can, (0.0, 0.08, 0.0)) == pytest.approx(-0.01)
    # disk against a rotated box's face, and against its corner from outside
    yaw = 0.4
    n = np.array([math.cos(yaw), math.sin(yaw)])
    at = (0.03 + 0.035 - 0.004) * n
    assert prism_penetration(*box, (0, 0, yaw), *can, (*at, 0.0)) == pytest.approx(0.004)
    assert prism_penetration(*can, (*at, 0.0), *box, (0, 0, yaw)) == pytest.approx(0.004)
    corner_dir = np.array([1.0, 1.0]) / math.sqrt(2)
    at = np.array([0.03, 0.04]) + (0.035 + 0.002) * corner_dir
    assert prism_penetration(*box, (0, 0, 0), *can, (*at, 0.0)) == pytest.approx(-0.002)
    # disk centre inside the box: leave through the nearest face
    assert prism_penetration(*box, (0, 0, 0), *can, (0.02, 0.0, 0.0)) == pytest.approx(
        0.035 + 0.01)
    # a flat object: the depth is capped by the lower height
    flat = ("box", (0.06, 0.08, 0.004))
    assert prism_penetration(*box, (0, 0, 0), *flat, (0.02, 0.0, 0.0)) == pytest.approx(0.004)


def test_prism_penetration_agrees_with_fcl(probe: RobotModel) -> None:
    """Property test (seeded): the closed form matches fcl's EPA on random overlapping pairs
    (deep enough for EPA to be safe) and the sign of fcl's distance on separated ones."""
    rng = np.random.default_rng(11)
    request = fcl.DistanceRequest(enable_nearest_points=True, enable_signed_distance=True)
    checked = 0
    for _ in range(400):
        kinds = rng.choice(["box", "cylinder"], size=2)
        sizes, bodies, poses = [], [], []
        for kind in kinds:
            if kind == "box":
                size = (*rng.uniform(0.03, 0.09, 2), rng.uniform(0.08, 0.15))
                geom = fcl.Box(*size)
            else:
                r = rng.uniform(0.02, 0.045)
                size = (2 * r, 2 * r, rng.uniform(0.08, 0.15))
                geom = fcl.Cylinder(r, size[2])
            pose = (*rng.uniform(-0.06, 0.06, 2), rng.uniform(-np.pi, np.pi))
            rot = np.array([[math.cos(pose[2]), -math.sin(pose[2]), 0],
                            [math.sin(pose[2]), math.cos(pose[2]), 0], [0, 0, 1]])
            bodies.append(fcl.CollisionObject(geom, fcl.Transform(rot, np.array(
                [pose[0], pose[1], size[2] / 2]))))
            sizes.append(size)
            poses.append(pose)
        depth = prism_penetration(kinds[0], sizes[0], poses[0], kinds[1], sizes[1], poses[1])
        if abs(depth) < 2e-3:
            continue
        if depth < 0:
            gap = fcl.distance(*bodies, fcl.DistanceRequest(), fcl.DistanceResult())
            assert gap > 0 and -depth <= gap + 1e-6     # separating-axis gap <= true gap
            continue
        checked += 1
        d = fcl.distance(*bodies, request, fcl.DistanceResult())
        tol = 1e-6 if "cylinder" not in kinds else 2e-4
        assert depth == pytest.approx(-d, abs=tol), (kinds, sizes, poses)
    assert checked > 100


def test_box_and_cylinder_overlap(probe: RobotModel) -> None:
    a = MovableObject.box("a", (0.06, 0.08, 0.12), (0.5, 0.0, 0.3))
    for offset, expected in [(0.06, [(0, 1)]), (0.0651, [])]:
        direction = np.array([math.cos(0.3), math.sin(0.3)])
        at = np.array([0.5, 0.0]) + offset * direction
        b = MovableObject.cylinder("b", 0.035, 0.1, (*at, 0.0))
        world = two_objects_world(probe, a, b)
        assert world.object_overlaps(world.scene.object_poses) == expected


def test_objects_overlap_says_whether_object_overlaps_finds_a_pair(probe: RobotModel) -> None:
    """The compiled yes-or-no the samplers ask agrees with `object_overlaps` on crowded random
    arrangements of boxes and cylinders, at depth 0 and at a tolerance."""
    objects = (BOX, CAN, FAR, MovableObject.cylinder("slim", 0.025, 0.1, (0.3, 0.2, 0.0)),
               MovableObject.box("flat", (0.12, 0.04, 0.05), (0.7, -0.2, 0.0)))
    world = CollisionWorld(make_scene(probe, objects=objects))
    rng = np.random.default_rng(3)
    seen = {True: 0, False: 0}
    for _ in range(400):
        poses = np.column_stack([rng.uniform(0.3, 0.55, 5), rng.uniform(-0.15, 0.15, 5),
                                 rng.uniform(-math.pi, math.pi, 5)])
        for tol in (0.0, 0.01):
            found = world.objects_overlap(poses, tol)
            assert found == bool(world.object_overlaps(poses, tol)), (poses, tol)
            seen[found] += 1
    assert min(seen.values()) > 50          # both answers were tested


def test_object_against_obstacle(probe: RobotModel) -> None:
    near = MovableObject.box("near", (0.06, 0.06, 0.12), (0.80 - 0.025 - 0.03 + 0.005, 0.40, 0))
    clear = MovableObject.cylinder("clear", 0.03, 0.1, (0.80, 0.40 + 0.025 + 0.031, 0))
    world = CollisionWorld(make_scene(probe, objects=(near, clear, FAR)))
    poses = world.scene.object_poses
    assert world.object_obstacle_overlaps(poses) == [(0, "post")]
    assert world.object_obstacle_overlaps(poses, tol=0.01) == []
    poses[1, 1] -= 0.002
    assert world.object_obstacle_overlaps(poses) == [(0, "post"), (1, "post")]


def test_objects_off_table(world: CollisionWorld) -> None:
    poses = initial(world).copy()
    assert world.objects_off_table(poses) == []
    poses[0, :2] = [0.96, 0.0]     # beyond x_max = 0.95
    poses[2, :2] = [0.5, -0.6]     # exactly on the edge counts as on the table
    assert world.objects_off_table(poses) == [0]


def test_object_poses_must_match_the_scene(world: CollisionWorld) -> None:
    with pytest.raises(ValueError, match=r"expected \(3, 3\): one \(x, y, yaw\) per scene"):
        world.object_overlaps(np.zeros((2, 3)))


def test_contact_is_a_frozen_value() -> None:
    c = Contact(0, 1, np.zeros(3), np.array([1.0, 0, 0]), 0.001)
    with pytest.raises(AttributeError):
        c.depth = 0.0  # type: ignore[misc]
    with pytest.raises(ValueError):
        c.normal[0] = 0.0


# -- broad phase ---------------------------------------------------------------------------------


@pytest.fixture
def narrow_phase_calls(monkeypatch: pytest.MonkeyPatch) -> dict[str, int]:
    """Counts every narrow-phase call: fcl.distance, fcl.collide, prism_penetration."""
    calls = {"fcl": 0, "prism": 0}

    def counting(name: str, function):
        def wrapper(*args, **kwargs):
            calls[name] += 1
            return function(*args, **kwargs)
        return wrapper

    monkeypatch.setattr(fcl, "distance", counting("fcl", fcl.distance))
    monkeypatch.setattr(fcl, "collide", counting("fcl", fcl.collide))
    monkeypatch.setattr(collision, "prism_penetration",
                        counting("prism", collision.prism_penetration))
    return calls


def test_far_pairs_never_reach_the_narrow_phase(world: CollisionWorld,
                                                narrow_phase_calls: dict[str, int]) -> None:
    poses = initial(world)
    high = place(CAPSULE, [0.5, 0.0, TABLE_TOP + 0.5])
    assert world.arm_object_contacts(high, poses, margin=0.05) == []
    assert world.arm_object_penetration(high, poses) == 0.0
    assert world.arm_static_collision(high) is None
    assert world.object_overlaps(poses) == []
    assert world.object_obstacle_overlaps(poses) == []
    assert narrow_phase_calls == {"fcl": 0, "prism": 0}
    # next to the box only: the box is the only object that reaches fcl
    centre, _ = box_face_point(0.0, R_CAP + 0.005, TABLE_TOP + 0.06)
    near_box = place(CAPSULE, centre, rot_z_to([0, 1, 0]))
    assert world.arm_object_contacts(near_box, poses) == []
    assert narrow_phase_calls["fcl"] == 1


def test_broad_phase_finds_every_narrow_phase_contact(world: CollisionWorld,
                                                      monkeypatch: pytest.MonkeyPatch) -> None:
    """Seeded random arm poses: the answer with the broad phase equals the answer with all
    pairs forced through the narrow phase."""
    rng = np.random.default_rng(3)
    poses = initial(world)
    for _ in range(60):
        centre = np.array([*rng.uniform([0.3, -0.1], [0.7, 0.4]), TABLE_TOP + rng.uniform(0, 0.2)])
        shapes = place(CAPSULE, centre, rot_z_to(rng.normal(size=3)))
        expected = [(c.shape, c.obj) for c in world.arm_object_contacts(shapes, poses, 0.01)]
        with monkeypatch.context() as patched:
            patched.setattr(world._shapes, "seg_radius", np.full(4, 1e3))
            everything = [(c.shape, c.obj) for c in world.arm_object_contacts(shapes, poses, 0.01)]
        assert expected == everything


def test_packed_box_test_matches_the_interval_test() -> None:
    """`_overlapping` (eight comparisons read as one 64-bit word) gives exactly the strict
    interval-overlap answer, for random boxes, touching faces (no overlap) and NaN (none)."""
    rng = np.random.default_rng(11)
    for _ in range(200):
        lo_a = rng.uniform(-1, 1, (6, 3)).round(1)     # rounded: many exactly touching faces
        hi_a = lo_a + rng.uniform(0, 1, (6, 3)).round(1)
        lo_b = rng.uniform(-1, 1, (4, 3)).round(1)
        hi_b = lo_b + rng.uniform(0, 1, (4, 3)).round(1)
        lo_a[0, 0] = np.nan
        expected = ((lo_a[:, None, :] < hi_b) & (hi_a[:, None, :] > lo_b)).all(axis=2)
        packed_a = np.full((6, 8), -np.inf)
        packed_a[:, :3], packed_a[:, 3:6] = lo_a, -hi_a
        got = collision._overlapping(packed_a, collision._packed_boxes(lo_b, hi_b))
        assert got.dtype == bool and got.shape == (6, 4)
        assert np.array_equal(got, expected)
    touching = collision._overlapping(np.array([[0, 0, 0, -1, -1, -1, -np.inf, -np.inf]], float),
                                      collision._packed_boxes(np.array([[1.0, 0, 0]]),
                                                              np.array([[2.0, 1, 1]])))
    assert not touching.any()


def test_queries_follow_bodies_that_moved_since_the_last_query(world: CollisionWorld) -> None:
    """The fcl bodies are only re-placed when their pose changed. Each move below is 8 mm,
    from 4 mm deep to a 4 mm gap, so the pair stays a broad-phase candidate and a body left
    at its old pose would still report the contact: a pose array changed in place, an object
    pose changed, and read-only arrays (RobotModel.shape_poses) queried alternately."""
    poses = initial(world)
    centre, normal = box_face_point(0.0, R_CAP - 0.004, TABLE_TOP + 0.06)
    shapes = place(CAPSULE, centre, rot_z_to([0, 1, 0]))
    assert [(c.shape, c.obj) for c in world.arm_object_contacts(shapes, poses)] == [(CAPSULE, 0)]
    shapes[CAPSULE, :3, 3] += 0.008 * normal       # the same (writable) array, moved away
    assert world.object_candidates(shapes, poses)[0].size == 1
    assert world.arm_object_contacts(shapes, poses) == []
    shapes[CAPSULE, :3, 3] -= 0.008 * normal
    assert len(world.arm_object_contacts(shapes, poses)) == 1
    moved = poses.copy()
    moved[0, :2] -= 0.008 * normal[:2]             # the box moved away from the capsule
    assert world.object_candidates(shapes, moved)[0].size == 1
    assert world.arm_object_contacts(shapes, moved) == []
    assert len(world.arm_object_contacts(shapes, poses)) == 1
    touching, apart = shapes.copy(), shapes.copy()
    apart[CAPSULE, :3, 3] += 0.008 * normal
    touching.setflags(write=False)
    apart.setflags(write=False)
    for _ in range(2):
        assert len(world.arm_object_contacts(touching, poses)) == 1
        assert world.arm_object_contacts(apart, poses) == []


def test_hot_path_queries_are_cheap(default_scene: Scene) -> None:
    """Not a benchmark, a guard against accidental per-query allocation or Python loops over
    far pairs: far-apart queries on the 3-object demo scene take well under 1 ms each."""
    import time

    world = CollisionWorld(default_scene)
    shapes = default_scene.robot.shape_poses(default_scene.start_configuration)
    poses = default_scene.object_poses
    start = time.perf_counter()
    for _ in range(200):
        world.arm_object_contacts(shapes, poses, margin=0.01)
        world.object_overlaps(poses)
        world.arm_static_collision(shapes)
    assert (time.perf_counter() - start) / 200 < 1e-3


# -- the fcl failure the narrow phase steers around ----------------------------------------------


def test_touching_configurations_do_not_abort_the_process() -> None:
    """fcl's signed distance (EPA) aborts the process (an uncaught C++ std::logic_error) on
    shapes that just touch, e.g. a tilted capsule resting on a cylinder's side. Run exactly
    such configurations, and many near them, through CollisionWorld in a child process: it must
    finish normally."""
    script = textwrap.dedent("""
        import math, numpy as np
        from rearrangement_planner.physics.collision import CollisionWorld
        from rearrangement_planner.model.robot import RobotModel
        from rearrangement_planner.model.scene import Goal, MovableObject, Scene, Table
        robot = RobotModel.load("panda")
        can = MovableObject.cylinder("can", 0.04, 0.12, (0.5, 0.0, 0.0))
        box = MovableObject.box("box", (0.06, 0.08, 0.12), (0.5, 0.3, 0.0))
        scene = Scene(robot, robot.home, Table((0.55, 0), (0.8, 1.2), 0.0), (), (can, box),
                      Goal("can", (0.5, -0.3)))
        world = CollisionWorld(scene)
        radius = 0.033          # panda_hand's first capsule
        s = [i for i, c in enumerate(robot.contact_shapes) if c.dims[0] == radius][0]
        shapes = np.tile(np.eye(4), (len(robot.contact_shapes), 1, 1))
        shapes[:, :3, 3] = [0, 0, 10]
        poses = scene.object_poses
        rng = np.random.default_rng(0)
        count = 0
        for face, centre in ((0.04, (0.5, 0.0)), (0.03, (0.5, 0.3))):
            for offset in (0.0, 1e-12, -1e-12, 1e-9, -1e-9, 1e-6, -1e-6, 5e-4, 1e-3, 1.5e-3):
                for tilt in list(np.linspace(-1.2, 1.2, 13)) + list(rng.uniform(-1.5, 1.5, 10)):
                    c, s_ = math.cos(tilt), math.sin(tilt)
                    # axis in the y-z plane, parallel to the +x face / tangent to the side
                    shapes[s, :3, :3] = [[1, 0, 0], [0, s_, c], [0, -c, s_]]
                    shapes[s, :3, 3] = [centre[0] + face + radius - offset, centre[1], 0.06]
                    world.arm_object_contacts(shapes, poses, margin=0.01)
                    world.arm_object_penetration(shapes, poses)
                    count += 1
        print("ok", count)
    """)
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                          timeout=120)
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.startswith("ok")
