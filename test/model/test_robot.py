"""Robot model: FK against the published Panda parameters, Jacobians against finite
differences, contact shapes attached to their links, and clear errors for bad configs."""

import math

import numpy as np
import pytest

from rearrangement_planner.model.errors import RobotModelError
from rearrangement_planner.model.robot import RobotConfig, RobotModel

# Franka Control Interface documentation, "Denavit-Hartenberg parameters" (Craig convention):
# (a_{i-1}, d_i, alpha_{i-1}); flange d = 0.107; hand rotated -pi/4; finger tips 0.1034.
PANDA_DH = [(0.0, 0.333, 0.0), (0.0, 0.0, -math.pi / 2), (0.0, 0.316, math.pi / 2),
            (0.0825, 0.0, math.pi / 2), (-0.0825, 0.384, -math.pi / 2),
            (0.0, 0.0, math.pi / 2), (0.088, 0.0, math.pi / 2)]
PANDA_LOWER = [-2.8973, -1.7628, -2.8973, -3.0718, -2.8973, -0.0175, -2.8973]
PANDA_UPPER = [2.8973, 1.7628, 2.8973, -0.0698, 2.8973, 3.7525, 2.8973]
PANDA_VELOCITY = [2.175, 2.175, 2.175, 2.175, 2.61, 2.61, 2.61]
PANDA_EFFORT = [87, 87, 87, 87, 12, 12, 12]


def rot_x(a):
    c, s = math.cos(a), math.sin(a)
    return np.array([[1, 0, 0, 0], [0, c, -s, 0], [0, s, c, 0], [0, 0, 0, 1.0]])


def rot_z(a):
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, -s, 0, 0], [s, c, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1.0]])


def trans(x, y, z):
    t = np.eye(4)
    t[:3, 3] = (x, y, z)
    return t


def dh_chain(q):
    """Frames of links 1..7, flange and finger tips from the modified DH table."""
    frames, t = [], np.eye(4)
    for (a, d, alpha), theta in zip(PANDA_DH, q, strict=True):
        t = t @ rot_x(alpha) @ trans(a, 0, 0) @ rot_z(theta) @ trans(0, 0, d)
        frames.append(t)
    flange = t @ trans(0, 0, 0.107)
    tcp = flange @ rot_z(-math.pi / 4) @ trans(0, 0, 0.1034)
    return frames, flange, tcp


def random_configurations(robot, n, seed=0):
    rng = np.random.default_rng(seed)
    return rng.uniform(robot.lower, robot.upper, size=(n, robot.nq))


def test_joint_limits_are_the_published_ones(panda):
    np.testing.assert_allclose(panda.lower, PANDA_LOWER)
    np.testing.assert_allclose(panda.upper, PANDA_UPPER)
    np.testing.assert_allclose(panda.velocity_limits, PANDA_VELOCITY)
    np.testing.assert_allclose(panda.effort_limits, PANDA_EFFORT)
    assert panda.joint_names == tuple(f"panda_joint{i}" for i in range(1, 8))


def test_a_position_a_hair_past_a_limit_is_the_limit(panda):
    """A controller reports a joint 0.5 mrad past its limit: that is the limit. 5 mrad past
    is left as it is, for the start check to name."""
    q = np.array(panda.home, dtype=float)
    q[4] = panda.lower[4] - 0.0005
    q[6] = panda.upper[6] + 0.0009
    clamped = panda.clamped(q)
    assert clamped[4] == panda.lower[4] and clamped[6] == panda.upper[6]
    assert panda.within_limits(clamped) and not panda.within_limits(q)
    np.testing.assert_array_equal(np.delete(clamped, [4, 6]), np.delete(q, [4, 6]))
    q[4] = panda.lower[4] - 0.005
    assert panda.clamped(q)[4] == q[4]
    assert not panda.within_limits(panda.upper - 0.01, tol=-0.02)


def test_fk_at_zero_matches_published_offsets(panda):
    q = np.zeros(7)
    # Stretched-up arm: flange at (a7, 0, d1 + d3 + d5 - d_flange) = (0.088, 0, 0.926).
    np.testing.assert_allclose(panda.frame_pose(q, "panda_link8")[:3, 3], [0.088, 0, 0.926],
                               atol=1e-9)
    np.testing.assert_allclose(panda.tool_pose(q)[:3, 3], [0.088, 0, 0.926 - 0.1034], atol=1e-9)


def test_frame_position_is_frame_poses_translation_and_leaves_its_cache(panda):
    """`frame_position` gives the very numbers of `frame_pose`'s translation (the search's
    metric compares them, so a plan does not depend on which was asked), in data of its own:
    a `frame_pose` cached at one configuration is still right after it."""
    rng = np.random.default_rng(0)
    tool = panda.tool_frame_id
    q0 = rng.uniform(panda.lower, panda.upper)
    before = panda.frame_pose(q0, tool)
    for _ in range(50):
        q = rng.uniform(panda.lower, panda.upper)
        assert np.array_equal(panda.frame_position(q, tool), panda.frame_pose(q, tool)[:3, 3])
    q1 = rng.uniform(panda.lower, panda.upper)
    panda.frame_pose(q0, tool)
    panda.frame_position(q1, tool)
    assert np.array_equal(panda.frame_pose(q0, tool), before)


@pytest.mark.parametrize("seed", range(5))
def test_fk_matches_dh_table_at_random_configurations(panda, seed):
    for q in random_configurations(panda, 4, seed):
        frames, flange, tcp = dh_chain(q)
        for i, expected in enumerate(frames, start=1):
            np.testing.assert_allclose(panda.frame_pose(q, f"panda_link{i}"), expected,
                                       atol=1e-9)
        np.testing.assert_allclose(panda.frame_pose(q, "panda_link8"), flange, atol=1e-9)
        np.testing.assert_allclose(panda.tool_pose(q), tcp, atol=1e-9)


def numeric_point_jacobian(robot, q, frame, local_point, eps=1e-6):
    """Central differences of a point fixed in `frame` (given in the frame's coordinates)."""
    jac = np.zeros((3, robot.nq))
    for j in range(robot.nq):
        dq = np.zeros(robot.nq)
        dq[j] = eps
        plus = robot.frame_pose(q + dq, frame) @ np.append(local_point, 1.0)
        minus = robot.frame_pose(q - dq, frame) @ np.append(local_point, 1.0)
        jac[:, j] = (plus[:3] - minus[:3]) / (2 * eps)
    return jac


def numeric_angular_jacobian(robot, q, frame, eps=1e-6):
    jac = np.zeros((3, robot.nq))
    for j in range(robot.nq):
        dq = np.zeros(robot.nq)
        dq[j] = eps
        r_plus = robot.frame_pose(q + dq, frame)[:3, :3]
        r_minus = robot.frame_pose(q - dq, frame)[:3, :3]
        omega_hat = (r_plus - r_minus) / (2 * eps) @ robot.frame_pose(q, frame)[:3, :3].T
        jac[:, j] = [omega_hat[2, 1], omega_hat[0, 2], omega_hat[1, 0]]
    return jac


@pytest.mark.parametrize("frame", ["panda_link4", "panda_link6", "panda_hand_tcp"])
def test_frame_jacobian_matches_finite_differences(panda, frame):
    for q in random_configurations(panda, 5, seed=1):
        jac = panda.frame_jacobian(q, frame)
        np.testing.assert_allclose(jac[:3], numeric_point_jacobian(panda, q, frame, np.zeros(3)),
                                   atol=1e-7)
        np.testing.assert_allclose(jac[3:], numeric_angular_jacobian(panda, q, frame), atol=1e-7)


def test_jacobian_at_a_point_on_a_link_matches_finite_differences(panda):
    rng = np.random.default_rng(2)
    for q in random_configurations(panda, 5, seed=3):
        local = rng.uniform(-0.1, 0.1, size=3)
        world = (panda.frame_pose(q, "panda_link5") @ np.append(local, 1.0))[:3]
        jac = panda.frame_jacobian(q, "panda_link5", point=world)
        np.testing.assert_allclose(jac[:3], numeric_point_jacobian(panda, q, "panda_link5", local),
                                   atol=1e-7)
        # The angular part does not depend on the point.
        np.testing.assert_allclose(jac[3:], panda.frame_jacobian(q, "panda_link5")[3:])


def test_contact_shapes_move_rigidly_with_their_links(panda):
    qs = random_configurations(panda, 6, seed=4)
    for q in qs:
        poses = panda.shape_poses(q)
        for shape, pose in zip(panda.contact_shapes, poses, strict=True):
            link = panda.frame_pose(q, shape.link)
            np.testing.assert_allclose(np.linalg.inv(link) @ pose, shape.offset, atol=1e-9)


def test_moving_the_last_joint_moves_only_distal_shapes(panda):
    q = panda.home.copy()
    before = panda.shape_poses(q)
    q2 = q.copy()
    q2[6] += 0.5
    after = panda.shape_poses(q2)
    for shape, a, b in zip(panda.contact_shapes, before, after, strict=True):
        moved = not np.allclose(a, b, atol=1e-12)
        distal = shape.link in ("panda_link7", "panda_hand")
        assert moved == distal, shape.link


def test_capsules_cover_the_segments_between_joint_axes(panda):
    """Every point of the kinematic chain's link segments lies inside some contact capsule."""
    for q in random_configurations(panda, 3, seed=5):
        frames, flange, tcp = dh_chain(q)
        origins = [np.zeros(3)] + [f[:3, 3] for f in frames] + [flange[:3, 3], tcp[:3, 3]]
        poses = panda.shape_poses(q)
        for a, b in zip(origins[1:-1], origins[2:], strict=True):
            for s in np.linspace(0.0, 1.0, 9):
                point = a + s * (b - a)
                shapes = zip(panda.contact_shapes, poses, strict=True)
                assert min(capsule_distance(point, s, p) for s, p in shapes) <= 1e-9, point


def capsule_distance(point, shape, pose):
    radius, length = shape.dims
    axis = pose[:3, 2]
    t = np.clip(np.dot(point - pose[:3, 3], axis), -length / 2, length / 2)
    return np.linalg.norm(point - (pose[:3, 3] + t * axis)) - radius


def test_urdf_from_string_is_the_robot_description_convention(panda):
    again = RobotModel(panda.config, urdf_xml=panda.urdf_xml)
    q = panda.home
    np.testing.assert_allclose(again.tool_pose(q), panda.tool_pose(q))


def test_copy_is_independent(panda):
    other = panda.copy()
    q = random_configurations(panda, 1, seed=6)[0]
    np.testing.assert_allclose(other.tool_pose(q), panda.tool_pose(q))
    assert other.data is not panda.data


def test_within_limits(panda):
    assert panda.within_limits(panda.home)
    q = panda.home.copy()
    q[3] = 0.0
    assert not panda.within_limits(q)


def test_unknown_robot_name_lists_the_shipped_ones():
    with pytest.raises(RobotModelError, match=r"unknown robot 'ur5'.*\['panda', 'xarm7'\]"):
        RobotModel.load("ur5")


def test_unknown_joint_names_the_joint_and_the_alternatives(panda):
    data = _config_dict(panda)
    data["joints"] = data["joints"][:6] + ["panda_joint9"]
    with pytest.raises(RobotModelError,
                       match=r"joint 'panda_joint9' not in the URDF.*panda_joint1"):
        RobotModel(RobotConfig.from_dict(data, base_dir=panda.config.source.parent))


def test_bad_shape_type_is_named(panda):
    data = _config_dict(panda)
    data["contact_shapes"] = [{"link": "panda_hand", "type": "cone", "radius": 0.1}]
    with pytest.raises(RobotModelError, match=r"contact_shapes\[0\].*unknown type 'cone'"):
        RobotConfig.from_dict(data)


def test_home_outside_limits_is_rejected(panda):
    data = _config_dict(panda)
    data["home"] = [0, 0, 0, 0, 0, 0, 0]
    with pytest.raises(RobotModelError, match="outside the joint limits"):
        RobotModel(RobotConfig.from_dict(data, base_dir=panda.config.source.parent))


def test_unknown_config_key_is_named(panda):
    data = _config_dict(panda)
    data["gripper"] = "hand"
    with pytest.raises(RobotModelError, match=r"unknown key\(s\) \['gripper'\]"):
        RobotConfig.from_dict(data)


def test_a_urdf_may_be_a_package_uri_of_an_installed_package(panda):
    """The xArm7's config names its URDF in example-robot-data (no robot file copied); the
    Panda's names the collision URDF the execution check simulates the same way."""
    xarm = RobotModel.load("xarm7")
    assert xarm.config.urdf_path.is_file()
    assert "example-robot-data/robots/xarm_description/urdf" in str(xarm.config.urdf_path)
    assert xarm.config.geometry_urdf == xarm.config.urdf_path and xarm.nq == 7
    assert panda.config.geometry_urdf.name == "panda.urdf"
    assert "panda_description" in str(panda.config.geometry_urdf)
    data = _config_dict(panda)
    data["collision_urdf"] = "package://no_such_robot_description/urdf/arm.urdf"
    with pytest.raises(RobotModelError, match=r"collision_urdf: .*no package "
                                              r"'no_such_robot_description'"):
        RobotConfig.from_dict(data)


def _config_dict(robot):
    import yaml

    return yaml.safe_load(robot.config.source.read_text())
