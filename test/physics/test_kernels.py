"""The compiled contact geometry (`physics.kernels`) against python-fcl, the geometry
reference, on thousands of random capsule-prism placements: signed distance, contact point
and normal, apart and penetrating, boxes and cylinders."""

from __future__ import annotations

import math

import fcl
import numpy as np
import pytest

from rearrangement_planner.physics.kernels import (
    BOUND_RESOLUTION,
    BOX,
    CYLINDER,
    LINE_MIN_SPAN,
    capsule_prism,
    capsule_prism_bound,
    capsule_prism_line,
)


def _axis_rotation(axis: np.ndarray) -> np.ndarray:
    """A rotation whose z axis is `axis` (unit)."""
    helper = np.array([1.0, 0.0, 0.0]) if abs(axis[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    x = np.cross(helper, axis)
    x /= np.linalg.norm(x)
    return np.column_stack([x, np.cross(axis, x), axis])


def _fcl_signed_distance(a, b, radius, kind, centre, yaw, dims):
    length = float(np.linalg.norm(b - a))
    capsule = fcl.CollisionObject(fcl.Capsule(radius, length), fcl.Transform(
        _axis_rotation((b - a) / length), (a + b) / 2))
    if kind == BOX:
        geometry = fcl.Box(*(2 * dims))
    else:
        geometry = fcl.Cylinder(dims[0], 2 * dims[1])
    c, s = math.cos(yaw), math.sin(yaw)
    prism = fcl.CollisionObject(geometry, fcl.Transform(
        np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]), centre))
    request = fcl.DistanceRequest(enable_nearest_points=True, enable_signed_distance=True)
    result = fcl.DistanceResult()
    distance = fcl.distance(capsule, prism, request, result)
    return distance, np.asarray(result.nearest_points[1])


def _random_case(rng, kind):
    dims = (rng.uniform([0.02, 0.02, 0.04], [0.06, 0.06, 0.09]) if kind == BOX
            else np.array([rng.uniform(0.02, 0.06), rng.uniform(0.04, 0.09), 0.0]))
    centre = np.array([0.5, 0.0, dims[2] if kind == BOX else dims[1]])
    yaw = rng.uniform(-math.pi, math.pi)
    mid = centre + rng.uniform(-0.15, 0.15, 3)
    axis = rng.normal(size=3)
    axis /= np.linalg.norm(axis)
    half = rng.uniform(0.01, 0.12)
    return mid - half * axis, mid + half * axis, rng.uniform(0.01, 0.06), centre, yaw, dims


@pytest.mark.parametrize("kind", [BOX, CYLINDER], ids=["box", "cylinder"])
def test_signed_distance_point_and_normal_agree_with_fcl(kind):
    rng = np.random.default_rng(kind)
    point, normal = np.empty(3), np.empty(3)
    apart = deep = 0
    gaps = []
    for _ in range(3000):
        a, b, radius, centre, yaw, dims = _random_case(rng, kind)
        distance = capsule_prism(a, b, radius, kind, centre, yaw, dims, point, normal)
        if abs(distance) < 2e-3:
            continue         # touching: fcl's EPA is unreliable there (test_collision)
        reference, reference_point = _fcl_signed_distance(a, b, radius, kind, centre, yaw, dims)
        assert np.isclose(np.linalg.norm(normal), 1.0, atol=1e-9)
        if distance > 0:
            apart += 1
            # fcl's GJK may stop short of the minimum (by up to 2 mm in these cases, while a
            # dense search along the axis agrees with the kernel to a micrometre:
            # `test_the_minimum_along_the_axis_is_found`): its distance is never below ours.
            assert reference >= distance - 1e-6
            gaps.append(reference - distance)
            # the prism point is fcl's nearest point when that point is unique; always on the
            # surface and at the distance from the capsule along the normal
            tip = point + normal * distance
            along = (tip - a) @ (b - a) / ((b - a) @ (b - a))
            axis_point = a + np.clip(along, 0.0, 1.0) * (b - a)
            assert np.linalg.norm(axis_point - tip) == pytest.approx(radius, abs=1e-6)
            if reference - distance < 1e-5:
                assert np.linalg.norm(point - reference_point) < 0.02
        elif distance > -radius:         # the axis outside the prism: the depth is exact
            deep += 1
            assert distance == pytest.approx(reference, abs=2e-4)
        else:                            # the axis inside: its deepest point's depth, a bound
            assert reference <= distance + 2e-4
    assert apart > 1500 and deep > 100
    assert np.mean(np.array(gaps) < 2e-5) > 0.97 and max(gaps) < 0.003


def test_the_normal_points_out_of_the_prism_towards_the_arm():
    point, normal = np.empty(3), np.empty(3)
    dims = np.array([0.03, 0.04, 0.06])
    centre = np.array([0.5, 0.0, 0.06])
    # vertical capsules of radius 1 cm: 1 cm in front of the box's +x face (yaw 0), 5 mm into it
    for x, expected in ((0.55, 0.01), (0.535, -0.005)):
        a, b = np.array([x, 0.0, 0.03]), np.array([x, 0.0, 0.09])
        distance = capsule_prism(a, b, 0.01, BOX, centre, 0.0, dims, point, normal)
        assert distance == pytest.approx(expected, abs=1e-9)
        np.testing.assert_allclose(normal, [1.0, 0.0, 0.0], atol=1e-9)
        assert point[0] == pytest.approx(0.53, abs=1e-9)
    # turned by 90 degrees the box's long side faces +x
    a, b = np.array([0.56, 0.0, 0.03]), np.array([0.56, 0.0, 0.09])
    distance = capsule_prism(a, b, 0.01, BOX, centre, math.pi / 2, dims, point, normal)
    assert distance == pytest.approx(0.56 - 0.54 - 0.01, abs=1e-9)


@pytest.mark.parametrize("kind", [BOX, CYLINDER], ids=["box", "cylinder"])
def test_the_minimum_along_the_axis_is_found(kind):
    """Against a dense search (200,001 axis points, about a micrometre apart) with numpy's
    closed-form distances: never above it, at most 2 micrometres below."""
    rng = np.random.default_rng(10 + kind)
    point, normal = np.empty(3), np.empty(3)
    t = np.linspace(0.0, 1.0, 200_001)[:, None]
    for _ in range(200):
        a, b, radius, centre, yaw, dims = _random_case(rng, kind)
        distance = capsule_prism(a, b, radius, kind, centre, yaw, dims, point, normal)
        p = a + t * (b - a) - centre
        c, s = math.cos(yaw), math.sin(yaw)
        q = np.column_stack([c * p[:, 0] + s * p[:, 1], -s * p[:, 0] + c * p[:, 1], p[:, 2]])
        if kind == BOX:
            gap = np.abs(q) - dims
            sd = np.linalg.norm(np.maximum(gap, 0.0), axis=1) + np.minimum(gap.max(axis=1), 0)
        else:
            dr, dz = np.hypot(q[:, 0], q[:, 1]) - dims[0], np.abs(q[:, 2]) - dims[1]
            sd = np.hypot(np.maximum(dr, 0), np.maximum(dz, 0)) + np.minimum(np.maximum(dr, dz), 0)
        assert sd.min() - radius - 2e-6 <= distance <= sd.min() - radius + 1e-12


@pytest.mark.parametrize("kind", [BOX, CYLINDER], ids=["box", "cylinder"])
def test_the_distance_bound_is_below_the_distance_and_near_it(kind):
    """`capsule_prism_bound` (the step's narrow phase) never exceeds the distance, apart or
    penetrating, and is below it by at most BOUND_RESOLUTION."""
    rng = np.random.default_rng(20 + kind)
    point, normal = np.empty(3), np.empty(3)
    for _ in range(2000):
        a, b, radius, centre, yaw, dims = _random_case(rng, kind)
        distance = capsule_prism(a, b, radius, kind, centre, yaw, dims, point, normal)
        bound = capsule_prism_bound(a, b, radius, kind, centre, yaw, dims)
        assert distance - BOUND_RESOLUTION - 1e-12 <= bound <= distance + 1e-9
    a = np.array([0.5, 0.2, 0.05])      # a sphere (an axis of length zero)
    assert capsule_prism_bound(a, a, 0.01, kind, centre, 0.0, dims) == pytest.approx(
        capsule_prism(a, a, 0.01, kind, centre, 0.0, dims, point, normal))


def test_compiled_shape_kinematics_match_pinocchio(panda):
    """The compiled forward kinematics of the contact shapes against RobotModel (Pinocchio)
    on a thousand random configurations within the joint limits."""
    from rearrangement_planner.physics.kernels import CompiledChain

    chain = CompiledChain(panda)
    rng = np.random.default_rng(7)
    for _ in range(1000):
        q = rng.uniform(panda.lower, panda.upper)
        np.testing.assert_allclose(chain.shape_poses(q), panda.shape_poses(q), atol=1e-12)


def _line(a, b, radius, kind, centre, yaw, dims):
    points, normals, depths = np.empty((2, 3)), np.empty((2, 3)), np.empty(2)
    found = capsule_prism_line(np.asarray(a, float), np.asarray(b, float), radius, kind,
                               centre, yaw, dims, points, normals, depths)
    return found, points[:found], normals[:found], depths[:found]


def test_a_capsule_lying_along_a_face_touches_it_at_the_lines_two_ends():
    """A horizontal capsule 1 mm into the box's -x face: parallel, the contacts are the face's
    two ends (one point at the axis' end, before: the box would turn); turned 0.1 rad, they
    span the part of the face within 1 mm of the deepest point; turned 0.5 rad, or end on,
    it is a corner's or a cap's one contact. Both ends carry the deepest depth and the
    face's normal."""
    dims, centre = np.array([0.03, 0.04, 0.06]), np.array([0.0, 0.0, 0.06])
    x = -0.03 - 0.01 + 0.001
    found, points, normals, depths = _line([x, -0.1, 0.06], [x, 0.1, 0.06], 0.01, BOX, centre,
                                           0.0, dims)
    assert found == 2
    np.testing.assert_allclose(points[:, :2], [[-0.03, -0.04], [-0.03, 0.04]], atol=1e-6)
    np.testing.assert_allclose(normals, [[-1.0, 0.0, 0.0]] * 2, atol=1e-6)
    np.testing.assert_allclose(depths, [0.001, 0.001], atol=1e-9)
    for tilt, expected in ((0.1, 2), (0.5, 1)):
        half = 0.1 * np.array([math.sin(tilt), math.cos(tilt), 0.0])
        middle = np.array([x, 0.0, 0.06])
        found, points, normals, depths = _line(middle - half, middle + half, 0.01, BOX,
                                               centre, 0.0, dims)
        point, normal = np.empty(3), np.empty(3)
        distance = capsule_prism(middle - half, middle + half, 0.01, BOX, centre, 0.0, dims,
                                 point, normal)
        assert found == expected and depths == pytest.approx([-distance] * found)
        np.testing.assert_allclose(normals, [normal] * found, atol=1e-9)
        if found == 2:
            assert abs(points[1, 1] - points[0, 1]) >= LINE_MIN_SPAN
    found, _, _, _ = _line([x - 0.1, 0.0, 0.06], [x, 0.0, 0.06], 0.01, BOX, centre, 0.0, dims)
    assert found == 1                                      # end on: the cap's one point
    found, _, _, _ = _line([x - 0.002, -0.1, 0.06], [x - 0.002, 0.1, 0.06], 0.01, BOX, centre,
                           0.0, dims)
    assert found == 0                                      # 1 mm apart


def test_a_capsule_along_a_cylinder_or_standing_upright_touches_it_at_one_point():
    """A cylinder's side is curved, and an upright capsule's line is one point in the table
    plane: one contact, the deepest."""
    centre = np.array([0.0, 0.0, 0.06])
    assert _line([-0.039, -0.1, 0.06], [-0.039, 0.1, 0.06], 0.01, CYLINDER, centre, 0.0,
                 np.array([0.03, 0.06, 0.0]))[0] == 1
    assert _line([-0.039, 0.0, 0.02], [-0.039, 0.0, 0.09], 0.01, BOX, centre, 0.0,
                 np.array([0.03, 0.04, 0.06]))[0] == 1


@pytest.mark.parametrize("kind", [BOX, CYLINDER], ids=["box", "cylinder"])
def test_line_contacts_agree_with_the_distance(kind):
    """On random placements: contacts exactly when the capsule penetrates, each as deep as
    the deepest point with its normal; a line's ends within the capsule."""
    rng = np.random.default_rng(30 + kind)
    point, normal = np.empty(3), np.empty(3)
    for _ in range(2000):
        a, b, radius, centre, yaw, dims = _random_case(rng, kind)
        distance = capsule_prism(a, b, radius, kind, centre, yaw, dims, point, normal)
        found, points, normals, depths = _line(a, b, radius, kind, centre, yaw, dims)
        assert (found > 0) == (distance < 0.0)
        if not found:
            continue
        np.testing.assert_allclose(depths, -distance, atol=1e-12)
        np.testing.assert_allclose(normals, [normal] * found, atol=1e-9)
        for p in points if found == 2 else ():
            axis = b - a
            t = np.clip((p - a) @ axis / (axis @ axis), 0.0, 1.0)
            assert np.linalg.norm(p - (a + t * axis)) <= radius + 1e-9
