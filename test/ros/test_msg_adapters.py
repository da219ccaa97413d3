"""msg_adapters: every x_to_msg / msg_to_x pair round-trips over seeded random inputs, every
rejection names its field and says what is wrong, and the plan markers show the plan."""

from __future__ import annotations

import math
from fractions import Fraction

import numpy as np
import pytest
from builtin_interfaces.msg import Duration, Time
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import Point, Pose, PoseArray, PoseStamped, Quaternion
from sensor_msgs.msg import JointState
from std_msgs.msg import Header
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint
from visualization_msgs.msg import Marker

from msg_adapters import (
    configuration_to_joint_state,
    diagnostics_to_status,
    goal_to_pose_stamped,
    joint_state_to_configuration,
    msg_to_status,
    msg_to_trajectory,
    objects_to_pose_array,
    plan_markers,
    pose_array_to_objects,
    pose_stamped_to_goal,
    status_to_diagnostics,
    status_to_msg,
    trajectory_to_msg,
)
from rearrangement_planner.model.errors import InputError
from rearrangement_planner.planning.requests.status import STATES, PlannerStatus
from rearrangement_planner.planning.requests.trajectory import Trajectory

CASES = 200
FRAME = "panda_link0"
JOINTS = tuple(f"panda_joint{i}" for i in range(1, 8))
IDS = ("target", "can")


def angle_error(a: float, b: float) -> float:
    return abs(math.remainder(a - b, 2 * math.pi))


def quaternion_multiply(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hamilton product of quaternions stored (x, y, z, w)."""
    ax, ay, az, aw = a
    bx, by, bz, bw = b
    return np.array([aw * bx + ax * bw + ay * bz - az * by,
                     aw * by - ax * bz + ay * bw + az * bx,
                     aw * bz + ax * by - ay * bx + az * bw,
                     aw * bw - ax * bx - ay * by - az * bz])


def x_axis_heading(o: Quaternion) -> float:
    """Heading (rad) of the object's x axis projected on the table: rotate e_x by q v q*."""
    q = np.array([o.x, o.y, o.z, o.w])
    conjugate = q * [-1, -1, -1, 1] / np.dot(q, q)
    x_axis = quaternion_multiply(quaternion_multiply(q, [1.0, 0.0, 0.0, 0.0]), conjugate)
    return math.atan2(x_axis[1], x_axis[0])


def axis_angle(axis: np.ndarray, angle: float) -> np.ndarray:
    axis = np.asarray(axis, dtype=float) / np.linalg.norm(axis)
    return np.append(math.sin(angle / 2) * axis, math.cos(angle / 2))


# --------------------------------------------------------------------------------------------
# Round trips
# --------------------------------------------------------------------------------------------


def test_joint_state_round_trip(panda):
    rng = np.random.default_rng(1)
    names = panda.joint_names
    for _ in range(CASES):
        q = rng.uniform(panda.lower, panda.upper)
        msg = configuration_to_joint_state(q, names)
        assert list(msg.name) == list(names)
        assert msg.header.stamp == Time()
        np.testing.assert_array_equal(joint_state_to_configuration(msg, names), q)


def test_joint_state_mapped_by_name_with_extra_joints_in_any_order(panda):
    rng = np.random.default_rng(2)
    names = panda.joint_names
    extras = ["panda_finger_joint1", "panda_finger_joint2", "conveyor"]
    for _ in range(CASES):
        q = rng.uniform(panda.lower, panda.upper)
        all_names = list(names) + extras
        all_positions = list(q) + list(rng.uniform(-1, 1, len(extras)))
        order = rng.permutation(len(all_names))
        msg = JointState(name=[all_names[i] for i in order],
                         position=[all_positions[i] for i in order])
        np.testing.assert_array_equal(joint_state_to_configuration(msg, names), q)


def test_configuration_to_joint_state_keeps_the_stamp():
    stamp = Time(sec=12, nanosec=345)
    msg = configuration_to_joint_state(np.zeros(7), JOINTS, stamp=stamp)
    assert msg.header.stamp == stamp


def random_objects(rng: np.random.Generator) -> np.ndarray:
    m = int(rng.integers(1, 6))
    objects = np.column_stack([rng.uniform(-2, 2, (m, 2)), rng.uniform(-3 * np.pi, 3 * np.pi, m)])
    # the edges of (-pi, pi] and multiples of pi, where wrapping goes wrong first
    objects[0, 2] = rng.choice([np.pi, -np.pi, 3 * np.pi, -3 * np.pi, 0.0, objects[0, 2]])
    return objects


def test_objects_round_trip_with_yaw_wrapped():
    rng = np.random.default_rng(3)
    for _ in range(CASES):
        objects = random_objects(rng)
        ids = [f"object{i}" for i in range(len(objects))]
        z = rng.uniform(0, 1, len(objects))
        msg = objects_to_pose_array(objects, FRAME, z=z)
        assert msg.header.frame_id == FRAME
        np.testing.assert_array_equal([p.position.z for p in msg.poses], z)
        back = pose_array_to_objects(msg, ids, FRAME)
        assert back.shape == objects.shape
        np.testing.assert_array_equal(back[:, :2], objects[:, :2])
        for yaw, yaw_back in zip(objects[:, 2], back[:, 2], strict=True):
            assert -np.pi < yaw_back <= np.pi
            assert angle_error(yaw, yaw_back) < 1e-12


def test_pi_and_minus_pi_both_read_back_as_pi():
    msg = objects_to_pose_array(np.array([[0.0, 0.0, np.pi], [0.0, 0.0, -np.pi]]), FRAME)
    back = pose_array_to_objects(msg, IDS, FRAME)
    assert back[0, 2] == pytest.approx(np.pi, abs=1e-12) and back[0, 2] <= np.pi
    assert back[1, 2] == pytest.approx(np.pi, abs=1e-12) and back[1, 2] <= np.pi


def test_object_poses_message_round_trip():
    """msg -> objects -> msg for messages as a perception node sends them: any quaternion sign,
    any norm, small tilts within max_tilt; the yaw read is that of the object's x axis."""
    rng = np.random.default_rng(4)
    for _ in range(CASES):
        m = int(rng.integers(1, 6))
        ids = [f"object{i}" for i in range(m)]
        yaws = rng.uniform(-np.pi, np.pi, m)
        poses = []
        for yaw in yaws:
            tilt = rng.uniform(0, 0.045)
            axis = np.append(rng.normal(size=2), 0.0)
            q = quaternion_multiply(axis_angle([0, 0, 1], yaw), axis_angle(axis, tilt))
            q *= rng.choice([-1.0, 1.0]) * rng.uniform(0.2, 5.0)
            poses.append(Pose(position=Point(x=rng.uniform(-1, 1), y=rng.uniform(-1, 1), z=0.06),
                              orientation=Quaternion(x=q[0], y=q[1], z=q[2], w=q[3])))
        msg = PoseArray(header=Header(frame_id=FRAME), poses=poses)
        objects = pose_array_to_objects(msg, ids, FRAME)
        for pose, (x, y, yaw_read), yaw in zip(poses, objects, yaws, strict=True):
            assert (x, y) == (pose.position.x, pose.position.y)
            assert angle_error(yaw_read, x_axis_heading(pose.orientation)) < 1e-12
            assert angle_error(yaw_read, yaw) < 0.002  # the tilt moves the heading by O(tilt^2)
        again = objects_to_pose_array(objects, FRAME, z=[0.06] * m)
        np.testing.assert_allclose(pose_array_to_objects(again, ids, FRAME), objects,
                                   rtol=0, atol=1e-12)


def test_goal_round_trip():
    rng = np.random.default_rng(5)
    for _ in range(CASES):
        xy, z = rng.uniform(-2, 2, 2), rng.uniform(-1, 1)
        msg = goal_to_pose_stamped(xy, FRAME, z=z, stamp=Time(sec=3))
        assert (msg.header.frame_id, msg.header.stamp, msg.pose.position.z) == (FRAME,
                                                                                Time(sec=3), z)
        assert msg.pose.orientation == Quaternion(w=1.0)
        np.testing.assert_array_equal(pose_stamped_to_goal(msg, FRAME), xy)


def random_times(rng: np.random.Generator, count: int) -> np.ndarray:
    """Strictly increasing times from 0 that stress the nanosecond rounding: some just below a
    whole second (k - 1e-10), some a float's width from a half nanosecond (where rounding
    t * 1e9 in floating point goes wrong), the rest random."""
    times = [0.0]
    for _ in range(count - 1):
        t = times[-1] + rng.uniform(1e-3, 1.5)
        kind = rng.integers(4)
        if kind == 0 and math.ceil(t) - 1e-10 > times[-1] + 1e-6:
            t = math.ceil(t) - 1e-10  # e.g. 1.9999999999
        elif kind == 1:
            t = round(t, 9) + 0.5e-9 * rng.choice([-1.0, 1.0])
        times.append(t)
    return np.array(times)


def random_trajectory(rng: np.random.Generator) -> Trajectory:
    count = int(rng.integers(1, 30))
    return Trajectory(JOINTS, random_times(rng, count), rng.uniform(-3, 3, (count, 7)),
                      rng.uniform(-2, 2, (count, 7)))


def test_trajectory_round_trip_to_the_nanosecond():
    rng = np.random.default_rng(6)
    for _ in range(CASES):
        trajectory = random_trajectory(rng)
        msg = trajectory_to_msg(trajectory)
        assert msg.header.stamp == Time() and msg.header.frame_id == ""
        assert tuple(msg.joint_names) == JOINTS
        assert len(msg.points) == len(trajectory)
        for t, q, v, point in zip(trajectory.times, trajectory.positions, trajectory.velocities,
                                  msg.points, strict=True):
            assert list(point.positions) == list(q) and list(point.velocities) == list(v)
            d = point.time_from_start
            assert 0 <= d.nanosec < 10**9
            # nearest nanosecond, checked exactly on the float's binary value
            assert abs(Fraction(d.sec) + Fraction(d.nanosec, 10**9) - Fraction(t)) \
                <= Fraction(1, 2 * 10**9)
        back = msg_to_trajectory(msg)
        assert back.joint_names == JOINTS
        np.testing.assert_array_equal(back.positions, trajectory.positions)
        np.testing.assert_array_equal(back.velocities, trajectory.velocities)
        np.testing.assert_allclose(back.times, trajectory.times, rtol=0, atol=0.5e-9 + 1e-12)
        assert trajectory_to_msg(back) == msg  # idempotent once on the nanosecond grid


@pytest.mark.parametrize(("t", "sec", "nanosec"), [
    (1.9999999999, 2, 0),
    (0.9999999994, 0, 999999999),
    (1.0000000004, 1, 0),
    (1.0000000006, 1, 1),
    (0.5, 0, 500_000_000),
    (12345.678901234, 12345, 678901234),
    # a float's width from a half nanosecond: the float 5e-10 is 5.0000000000000003e-10 and
    # 1.9999999995 is 1.99999999949999996, so exact rounding goes up and down respectively
    (5e-10, 0, 1),
    (1.9999999995, 1, 999999999),
])
def test_time_from_start_rounding(t, sec, nanosec):
    msg = trajectory_to_msg(Trajectory(JOINTS, [0.0, t], np.zeros((2, 7)), np.zeros((2, 7))))
    assert msg.points[1].time_from_start == Duration(sec=sec, nanosec=nanosec)


def test_trajectory_with_times_closer_than_a_nanosecond_is_refused():
    trajectory = Trajectory(JOINTS, [0.0, 1.0, 1.0 + 2e-10], np.zeros((3, 7)), np.zeros((3, 7)))
    with pytest.raises(ValueError, match="less than 1 ns apart"):
        trajectory_to_msg(trajectory)


def random_status(rng: np.random.Generator) -> PlannerStatus:
    texts = ["", "plan 3: goal reached after 120 iterations", "a: b; c=d", "ünïcode ✓", " x "]
    return PlannerStatus(
        state=str(rng.choice(STATES)), message=str(rng.choice(texts)),
        outcome=str(rng.choice(["", "SUCCEEDED", "TIMEOUT", "NO_STATE", "CANCELLED"])),
        plan_id=str(rng.choice(["", "7", "20240101-120000-3"])),
        iterations=int(rng.integers(0, 10**7)), tree_size=int(rng.integers(0, 10**6)),
        best_goal_distance=float(rng.choice([math.inf, 0.0, rng.uniform(0, 2)])),
        elapsed=float(rng.uniform(0, 100)), fragile=bool(rng.random() < 0.3))


def test_status_round_trip():
    rng = np.random.default_rng(7)
    for _ in range(CASES):
        status = random_status(rng)
        msg = status_to_diagnostics(status, stamp=Time(sec=5), name="planner")
        assert msg.header.stamp == Time(sec=5)
        [diagnostic] = msg.status
        assert diagnostic.name == "planner"
        assert diagnostic.message.startswith(status.state)
        assert status.message in diagnostic.message
        assert {kv.key for kv in diagnostic.values} == {
            "state", "message", "outcome", "plan_id", "iterations", "tree_size",
            "best_goal_distance", "elapsed", "fragile"}
        assert diagnostics_to_status(msg) == status
        assert diagnostics_to_status(msg, name="planner") == status


def test_typed_status_round_trip():
    rng = np.random.default_rng(3)
    for _ in range(50):
        status = random_status(rng)
        msg = status_to_msg(status, stamp=Time(sec=5))
        assert msg.header.stamp.sec == 5 and msg.state == status.state
        assert msg_to_status(msg) == status
    bad = status_to_msg(PlannerStatus("idle"))
    bad.state = "dreaming"
    with pytest.raises(InputError, match="dreaming"):
        msg_to_status(bad)


@pytest.mark.parametrize(("state", "level"), [
    ("idle", DiagnosticStatus.OK), ("planning", DiagnosticStatus.OK),
    ("succeeded", DiagnosticStatus.OK), ("cancelled", DiagnosticStatus.WARN),
    ("failed", DiagnosticStatus.ERROR),
])
def test_status_levels(state, level):
    [diagnostic] = status_to_diagnostics(PlannerStatus(state, "why")).status
    assert diagnostic.level == level
    assert diagnostic.message == f"{state}: why"


def test_a_fragile_success_is_a_warning_and_a_bad_flag_names_its_field():
    [diagnostic] = status_to_diagnostics(PlannerStatus("succeeded", "FRAGILE",
                                                       fragile=True)).status
    assert diagnostic.level == DiagnosticStatus.WARN
    values = {kv.key: kv.value for kv in diagnostic.values}
    assert values["fragile"] == "True"
    diagnostic.values = [KeyValue(key=k, value="yes" if k == "fragile" else v)
                         for k, v in values.items()]
    with pytest.raises(InputError) as caught:
        diagnostics_to_status(DiagnosticArray(status=[diagnostic]))
    assert caught.value.field == "status.status[0].values[fragile]"
    assert "need True or False" in str(caught.value)


@pytest.mark.parametrize("kwargs", [
    {"state": "done"}, {"state": "idle", "iterations": -1}, {"state": "idle", "iterations": 1.5},
    {"state": "idle", "elapsed": math.nan}, {"state": "idle", "best_goal_distance": -0.1},
])
def test_planner_status_rejects_invalid_values(kwargs):
    with pytest.raises((ValueError, TypeError)):
        PlannerStatus(**kwargs)


# --------------------------------------------------------------------------------------------
# Rejections: one per way an input can be unusable, asserting the field and the key phrase
# --------------------------------------------------------------------------------------------


def joint_state(**changes) -> JointState:
    msg = JointState(name=list(JOINTS) + ["panda_finger_joint1"], position=[0.1] * 8)
    for key, value in changes.items():
        setattr(msg, key, value)
    return msg


def object_poses(frame: str = FRAME, count: int = 2, index: int = 1, position=None,
                 orientation=None) -> PoseArray:
    msg = objects_to_pose_array(np.array([[0.5, 0.1, 0.3], [0.6, 0.0, 0.0], [0.4, 0.2, 0.0]]
                                         [:count]), frame)
    if position is not None:
        msg.poses[index].position = Point(x=position[0], y=position[1], z=position[2])
    if orientation is not None:
        x, y, z, w = orientation
        msg.poses[index].orientation = Quaternion(x=x, y=y, z=z, w=w)
    return msg


def tilted(angle: float) -> tuple[float, float, float, float]:
    return tuple(quaternion_multiply(axis_angle([0, 0, 1], 0.3), axis_angle([1, 1, 0], angle)))


def goal(frame: str = FRAME, x: float = 0.5, y: float = 0.1, z: float = 0.0) -> PoseStamped:
    return PoseStamped(header=Header(frame_id=frame),
                       pose=Pose(position=Point(x=x, y=y, z=z), orientation=Quaternion(w=1.0)))


def trajectory_msg(times=((0, 0), (1, 0)), positions=7, velocities=7) -> JointTrajectory:
    return JointTrajectory(joint_names=list(JOINTS), points=[
        JointTrajectoryPoint(positions=[0.0] * positions, velocities=[0.0] * velocities,
                             time_from_start=Duration(sec=s, nanosec=ns)) for s, ns in times])


def diagnostics(*values: tuple[str, str]) -> DiagnosticArray:
    return DiagnosticArray(status=[DiagnosticStatus(
        name="rearrangement_planner", values=[KeyValue(key=k, value=v) for k, v in values])])


def joints(msg):
    return joint_state_to_configuration(msg, JOINTS)


def objects(msg):
    return pose_array_to_objects(msg, IDS, FRAME)


REJECTIONS = {
    "missing joint": (lambda: joints(joint_state(name=["panda_joint1", "panda_joint2",
                                                       "panda_joint4", "panda_joint5",
                                                       "panda_joint6", "panda_joint7",
                                                       "panda_finger_joint1", "other"])),
                      "joint_states.name", "'panda_joint3' missing"),
    "NaN joint": (lambda: joints(joint_state(position=[0.1, 0.1, math.nan] + [0.1] * 5)),
                  "joint_states.position[panda_joint3]", "must be finite"),
    "inf joint": (lambda: joints(joint_state(position=[0.1] * 6 + [math.inf, 0.1])),
                  "joint_states.position[panda_joint7]", "must be finite"),
    "length mismatch": (lambda: joints(joint_state(position=[0.1] * 7)),
                        "joint_states.position", "7 values for 8 names"),
    "duplicate joint": (lambda: joints(joint_state(name=list(JOINTS) + ["panda_joint2"])),
                        "joint_states.name", "'panda_joint2' appears twice"),
    "wrong count": (lambda: objects(object_poses(count=3)),
                    "object_poses.poses", "3 poses for 2 objects"),
    "wrong frame": (lambda: objects(object_poses(frame="world")),
                    "object_poses.header.frame_id", "is 'world'; object poses must be given in "
                                                    "the planning frame 'panda_link0'"),
    "empty frame": (lambda: objects(object_poses(frame="")),
                    "object_poses.header.frame_id", "is empty; object poses must be given in "
                                                    "the planning frame 'panda_link0'"),
    "NaN pose": (lambda: objects(object_poses(position=(0.6, math.nan, 0.0))),
                 "object_poses.poses[1].position", "of object 'can'"),
    "NaN orientation": (lambda: objects(object_poses(orientation=(0, 0, math.nan, 1))),
                        "object_poses.poses[1].orientation", "of object 'can'"),
    "zero quaternion": (lambda: objects(object_poses(orientation=(0, 0, 0, 0))),
                        "object_poses.poses[1].orientation", "'can' is a zero quaternion"),
    "tilted object": (lambda: objects(object_poses(index=0, orientation=tilted(0.1))),
                      "object_poses.poses[0].orientation",
                      "'target' is tilted by 0.100 rad (more than 0.05 rad); objects must "
                      "stand upright"),
    "NaN goal": (lambda: pose_stamped_to_goal(goal(x=math.nan), FRAME),
                 "goal.pose.position", "must be finite"),
    "goal in wrong frame": (lambda: pose_stamped_to_goal(goal(frame="map"), FRAME),
                            "goal.header.frame_id", "is 'map'; goal poses must be given in the "
                                                    "planning frame 'panda_link0'"),
    "goal in empty frame": (lambda: pose_stamped_to_goal(goal(frame=""), FRAME),
                            "goal.header.frame_id", "is empty"),
    "empty trajectory": (lambda: msg_to_trajectory(trajectory_msg(times=())),
                         "trajectory.points", "is empty"),
    "trajectory without velocities": (lambda: msg_to_trajectory(trajectory_msg(velocities=0)),
                                      "trajectory.points[0].velocities", "0 values for 7 joints"),
    "trajectory not from 0": (lambda: msg_to_trajectory(trajectory_msg(times=((0, 5), (1, 0)))),
                              "trajectory.points[0].time_from_start", "must be at 0 s"),
    "trajectory times repeat": (lambda: msg_to_trajectory(trajectory_msg(times=((0, 0), (0, 0)))),
                                "trajectory.points[1].time_from_start", "strictly increase"),
    "nanosec too large": (lambda: msg_to_trajectory(trajectory_msg(times=((0, 0),
                                                                          (0, 10**9)))),
                          "trajectory.points[1].time_from_start", "0 <= nanosec < 1e9"),
    "no status": (lambda: diagnostics_to_status(DiagnosticArray()),
                  "status.status", "no DiagnosticStatus with a 'state' value"),
    "status not an integer": (lambda: diagnostics_to_status(diagnostics(("state", "idle"),
                                                                        ("iterations", "many"))),
                              "status.status[0].values[iterations]", "need an integer"),
    "unknown state": (lambda: diagnostics_to_status(diagnostics(("state", "dreaming"))),
                      "status.status[0].values", "not a planner state"),
}


@pytest.mark.parametrize("case", list(REJECTIONS))
def test_rejection_names_field_and_problem(case):
    convert, field, phrase = REJECTIONS[case]
    with pytest.raises(InputError) as info:
        convert()
    assert info.value.field == field
    assert phrase in info.value.problem
    assert str(info.value) == f"{field}: {info.value.problem}"


def test_tilt_just_within_the_limit_is_accepted():
    [_, (x, y, yaw)] = objects(object_poses(orientation=tilted(0.049)))
    assert (x, y) == (0.6, 0.0)
    assert angle_error(yaw, 0.3) < 0.002


def test_huge_quaternions_are_read_without_overflow():
    """A quaternion is normalised with an overflow-safe norm: (0, 0, 1e200, 1e200) is a 90 degree
    yaw (the squared norm used to overflow to inf and read as yaw 0), a 90 degree tilt of the
    same size is refused, and one too large to normalise is refused, never misread."""
    [_, (_, _, yaw)] = objects(object_poses(orientation=(0.0, 0.0, 1e200, 1e200)))
    assert yaw == pytest.approx(math.pi / 2, abs=1e-12)
    with pytest.raises(InputError, match="tilted by 1.571 rad"):
        objects(object_poses(orientation=(1e200, 0.0, 0.0, 1e200)))
    with pytest.raises(InputError, match="too large to normalise") as info:
        objects(object_poses(orientation=(1e308, 1e308, 1e308, 1e308)))
    assert info.value.field == "object_poses.poses[1].orientation"


def test_a_rejection_names_the_input_without_copying_it(panda):
    """100,000 joint names: the error names what is missing and a few names, not all."""
    names = [f"joint_{i:06d}" for i in range(100_000)]
    with pytest.raises(InputError) as info:
        joint_state_to_configuration(JointState(name=names, position=[0.0] * len(names)),
                                     panda.joint_names)
    assert info.value.field == "joint_states.name" and "and 99990 more" in str(info.value)
    assert len(str(info.value)) < 600


# --------------------------------------------------------------------------------------------
# Markers
# --------------------------------------------------------------------------------------------


def check_marker_is_valid(marker: Marker) -> None:
    o = marker.pose.orientation
    assert math.isclose(math.sqrt(o.x**2 + o.y**2 + o.z**2 + o.w**2), 1.0, abs_tol=1e-12)
    assert marker.color.a > 0
    assert marker.scale.x > 0
    if marker.type != Marker.LINE_STRIP:
        assert marker.scale.y > 0 and marker.scale.z > 0
    else:
        assert len(marker.points) >= 2


def marker_yaw(marker: Marker) -> float:
    o = marker.pose.orientation
    return math.atan2(2 * (o.w * o.z + o.x * o.y), 1 - 2 * (o.y**2 + o.z**2))


def by_namespace(markers) -> dict[str, list[Marker]]:
    groups: dict[str, list[Marker]] = {}
    for m in markers:
        groups.setdefault(m.ns, []).append(m)
    return groups


def test_plan_markers(default_scene):
    scene = default_scene
    rng = np.random.default_rng(8)
    m = len(scene.objects)
    object_paths = scene.object_poses + np.cumsum(rng.normal(0, 0.01, (6, m, 3)), axis=0)
    ee_path = rng.uniform(0, 0.5, (11, 3))
    stamp = Time(sec=9)
    markers = plan_markers(scene, object_paths, ee_path, FRAME, stamp=stamp).markers

    first = markers[0]
    assert (first.action, first.ns, first.id) == (Marker.DELETEALL, "", 0)
    rest = markers[1:]
    assert all(mk.action == Marker.ADD for mk in rest)
    assert len({(mk.ns, mk.id) for mk in rest}) == len(rest)
    assert all(mk.header.frame_id == FRAME and mk.header.stamp == stamp for mk in markers)
    for mk in rest:
        check_marker_is_valid(mk)

    groups = by_namespace(rest)
    assert set(groups) == {"table", "obstacles", "objects", "goal", "ee_path", "object_paths"}
    assert [mk.type for mk in groups["table"]] == [Marker.CUBE]
    assert len(groups["obstacles"]) == len(scene.obstacles)
    assert [mk.type for mk in groups["goal"]] == [Marker.CYLINDER]
    [disc] = groups["goal"]
    assert (disc.scale.x, disc.pose.position.x, disc.pose.position.y) == pytest.approx(
        (2 * scene.goal.radius, *scene.goal.position))
    assert disc.color.a < 1

    [line] = groups["ee_path"]
    assert line.type == Marker.LINE_STRIP
    np.testing.assert_array_equal([(p.x, p.y, p.z) for p in line.points], ee_path)

    strips = sorted(groups["object_paths"], key=lambda mk: mk.id)
    assert len(strips) == m
    for i, strip in enumerate(strips):
        assert strip.type == Marker.LINE_STRIP
        np.testing.assert_array_equal([(p.x, p.y) for p in strip.points], object_paths[:, i, :2])

    drawn = sorted(groups["objects"], key=lambda mk: mk.id)
    assert len(drawn) == m
    for obj, mk, (x, y, yaw) in zip(scene.objects, drawn, object_paths[-1], strict=True):
        assert mk.type == (Marker.CYLINDER if obj.shape == "cylinder" else Marker.CUBE)
        assert (mk.pose.position.x, mk.pose.position.y) == (x, y)
        assert mk.pose.position.z == pytest.approx(scene.table.height + obj.height / 2)
        assert angle_error(marker_yaw(mk), yaw) < 1e-12
        assert (mk.scale.x, mk.scale.y, mk.scale.z) == tuple(obj.size)


def test_plan_markers_without_a_plan_show_the_scene(default_scene):
    markers = plan_markers(default_scene, None, None, FRAME).markers
    assert markers[0].action == Marker.DELETEALL
    groups = by_namespace(markers[1:])
    assert set(groups) == {"table", "obstacles", "objects", "goal"}
    for mk, (x, y, _) in zip(sorted(groups["objects"], key=lambda mk: mk.id),
                             default_scene.object_poses, strict=True):
        assert (mk.pose.position.x, mk.pose.position.y) == (x, y)


def test_plan_markers_reject_paths_of_the_wrong_shape(default_scene):
    with pytest.raises(ValueError, match="object_paths"):
        plan_markers(default_scene, np.zeros((4, 2, 3)), None, FRAME)
    with pytest.raises(ValueError, match="ee_path"):
        plan_markers(default_scene, None, np.zeros((4, 2)), FRAME)
