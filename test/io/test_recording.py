"""MCAP recording (docs/design.md): read back with independent readers (mcap, mcap-ros2-support) and
with rclpy's own CDR deserializer, so that the file is what `ros2 bag` and Foxglove expect."""

from __future__ import annotations

import array
import importlib
import json
import math
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import yaml
from builtin_interfaces.msg import Duration, Time
from geometry_msgs.msg import Point, Pose, PoseArray, PoseStamped, PoseWithCovarianceStamped
from mcap.reader import make_reader
from mcap_ros2.reader import read_ros2_messages
from rclpy.serialization import deserialize_message, serialize_message
from sensor_msgs.msg import Image, JointState
from std_msgs.msg import Byte, ColorRGBA
from visualization_msgs.msg import Marker, MarkerArray

from msg_adapters.conversions import (
    configuration_to_joint_state,
    goal_to_pose_stamped,
    trajectory_to_msg,
)
from msg_adapters.markers import plan_markers
from rearrangement_planner.io.plan_record import METADATA_NAME, MOTION_PERIOD, TOPICS, record_plan
from rearrangement_planner.io.recording import (
    McapRecorder,
    RecordingError,
    message_definition,
    offered_qos_profiles,
)
from rearrangement_planner.model.errors import RearrangementError
from rearrangement_planner.physics.validation import load_scene, parse_scene
from rearrangement_planner.planning import PCRRTOptions, PlanRequest, plan_scene

START_NS = 1_700_000_000_123_456_789
FRAME = "world"
PARAMETERS = {"time_limit": 30.0, "seed": 0, "goal_radius": 0.1, "max_iterations": math.inf,
              "object_ids": ["a", "b"], "record_dir": Path("/tmp/plans")}
TYPES = {
    TOPICS["joint_state"]: "sensor_msgs/msg/JointState",
    TOPICS["object_poses"]: "geometry_msgs/msg/PoseArray",
    TOPICS["goal"]: "geometry_msgs/msg/PoseStamped",
    TOPICS["trajectory"]: "trajectory_msgs/msg/JointTrajectory",
    TOPICS["predicted_object_poses"]: "geometry_msgs/msg/PoseArray",
    TOPICS["markers"]: "visualization_msgs/msg/MarkerArray",
    TOPICS["scene_3d"]: "foxglove_msgs/msg/SceneUpdate",
    TOPICS["plan_3d"]: "foxglove_msgs/msg/SceneUpdate",
    TOPICS["motion_3d"]: "foxglove_msgs/msg/SceneUpdate",
}
"""The recorded topics' types; Foxglove's 3D scene (`io.foxglove_ros2`) has no rclpy package
here, so only mcap_ros2 decodes it."""
QOS = {TOPICS["joint_state"]: ("best_effort", "volatile", 5),
       TOPICS["trajectory"]: ("reliable", "transient_local", 1)}   # others: reliable, volatile, 10
METADATA_KEYS = {"plan_id", "planner", "seed", "outcome", "message", "fragile", "parameters",
                 "scene", "statistics"}


@pytest.fixture(scope="module")
def solved(tmp_path_factory):
    output = plan_scene(PlanRequest.first_plan(load_scene("easy_push"), "pc-rrt",
                                                  PCRRTOptions(time_limit=30), seed=0))
    assert output.solved, output.result.message
    path = record_plan(tmp_path_factory.mktemp("rec") / "deep" / "dir" / "solved.mcap", output,
                       plan_id="plan-0001", parameters=PARAMETERS, planning_frame=FRAME,
                       start_time_ns=START_NS)
    return output, path


@pytest.fixture(scope="module")
def failed(tmp_path_factory):
    output = plan_scene(PlanRequest.first_plan(load_scene("clutter"), "pc-rrt",
                                                  PCRRTOptions(time_limit=0.3), seed=0))
    assert not output.solved
    path = record_plan(tmp_path_factory.mktemp("rec") / "failed.mcap", output,
                       plan_id="plan-0002", parameters={}, planning_frame=FRAME,
                       start_time_ns=START_NS)
    return output, path


def _summary(path: Path):
    with open(path, "rb") as f:
        reader = make_reader(f)
        return reader.get_header(), reader.get_summary(), list(reader.iter_metadata())


def _raw_messages(path: Path) -> list[tuple[str, str, int, bytes]]:
    """(topic, schema name, log time, CDR bytes) of every message, in log-time order."""
    with open(path, "rb") as f:
        reader = make_reader(f)
        return [(channel.topic, schema.name, message.log_time, message.data)
                for schema, channel, message in reader.iter_messages(log_time_order=True)]


def _ros_type(type_name: str) -> type:
    package, namespace, name = type_name.split("/")
    return getattr(importlib.import_module(f"{package}.{namespace}"), name)


def _decoded(path: Path, topic: str) -> list:
    """rclpy messages on `topic`, deserialized from the recorded CDR bytes by rclpy itself."""
    return [deserialize_message(data, _ros_type(type_name))
            for t, type_name, _, data in _raw_messages(path) if t == topic]


def _through_cdr(message):
    """`message` after a trip through rclpy's CDR (float32 fields lose precision)."""
    return deserialize_message(serialize_message(message), type(message))


def _ns(stamp) -> int:
    return stamp.sec * 1_000_000_000 + stamp.nanosec


# --------------------------------------------------------------------------------------------
# File structure
# --------------------------------------------------------------------------------------------


@pytest.mark.parametrize("which", ["solved", "failed"])
def test_file_follows_the_ros2_profile(which, request):
    output, path = request.getfixturevalue(which)
    header, summary, _ = _summary(path)
    assert header.profile == "ros2"
    assert "rearrangement_planner" in header.library
    expected = set(TYPES) if output.solved else set(TYPES) - {
        TOPICS["trajectory"], TOPICS["predicted_object_poses"], TOPICS["plan_3d"],
        TOPICS["motion_3d"]}
    channels = {c.topic: c for c in summary.channels.values()}
    assert set(channels) == expected
    for topic, channel in channels.items():
        schema = summary.schemas[channel.schema_id]
        assert channel.message_encoding == "cdr"
        assert schema.encoding == "ros2msg"
        assert schema.name == TYPES[topic]
        assert schema.data.decode() == message_definition(TYPES[topic])
        profiles = yaml.safe_load(channel.metadata["offered_qos_profiles"])
        assert isinstance(profiles, list) and len(profiles) == 1
        profile = profiles[0]
        reliability, durability, depth = QOS.get(topic, ("reliable", "volatile", 10))
        assert (profile["reliability"], profile["durability"], profile["depth"]) == (
            reliability, durability, depth), topic
        assert profile["history"] == "keep_last"
        assert profile["liveliness"] == "automatic"
        assert profile["avoid_ros_namespace_conventions"] is False
        for key in ("deadline", "lifespan", "liveliness_lease_duration"):
            assert profile[key] == {"sec": 9223372036, "nsec": 854775807}
        if TYPES[topic].startswith("foxglove_msgs/"):       # no installed type description
            assert channel.metadata["topic_type_hash"] == ""
            continue
        description = json.loads(_share_file(TYPES[topic], ".json").read_text())
        assert channel.metadata["topic_type_hash"] == description["type_hashes"][0]["hash_string"]
        assert channel.metadata["topic_type_hash"].startswith("RIHS01_")
    counts = summary.statistics.channel_message_counts
    for channel_id, channel in summary.channels.items():
        if channel.topic == TOPICS["motion_3d"]:      # a frame every MOTION_PERIOD s or so
            assert counts[channel_id] >= output.trajectory.duration / (2 * MOTION_PERIOD)
            continue
        n = len(output.trajectory.times) if channel.topic == TOPICS["predicted_object_poses"] else 1
        assert counts[channel_id] == n, channel.topic


def test_every_message_decodes_with_mcap_ros2_and_rclpy(solved):
    _, path = solved
    decoded = list(read_ros2_messages(path))
    raw = _raw_messages(path)
    assert len(decoded) == len(raw) > 0
    for (topic, type_name, log_time, data), message in zip(raw, decoded, strict=True):
        assert message.channel.topic == topic and message.log_time_ns == log_time
        if type_name.startswith("foxglove_msgs/"):
            continue
        ros = deserialize_message(data, _ros_type(type_name))
        if hasattr(ros, "header"):
            assert message.ros_msg.header.frame_id == ros.header.frame_id
            assert _ns(message.ros_msg.header.stamp) == _ns(ros.header.stamp)


# --------------------------------------------------------------------------------------------
# Content
# --------------------------------------------------------------------------------------------


def test_trajectory_is_the_planned_one(solved):
    output, path = solved
    [message] = [m for m in read_ros2_messages(path, topics=[TOPICS["trajectory"]])]
    assert message.log_time_ns == START_NS
    trajectory = message.ros_msg
    assert list(trajectory.joint_names) == list(output.trajectory.joint_names)
    positions = np.array([p.positions for p in trajectory.points])
    velocities = np.array([p.velocities for p in trajectory.points])
    times = np.array([_ns(p.time_from_start) * 1e-9 for p in trajectory.points])
    np.testing.assert_allclose(positions, output.trajectory.positions, rtol=0, atol=1e-12)
    np.testing.assert_allclose(velocities, output.trajectory.velocities, rtol=0, atol=1e-12)
    np.testing.assert_allclose(times, output.trajectory.times, rtol=0, atol=1e-9)
    [ros] = _decoded(path, TOPICS["trajectory"])
    assert ros == trajectory_to_msg(output.trajectory)


def test_predicted_object_poses_follow_the_trajectory(solved):
    output, path = solved
    messages = list(read_ros2_messages(path, topics=[TOPICS["predicted_object_poses"]]))
    assert len(messages) == len(output.trajectory.times) == len(output.trajectory_states)
    scene = output.scene
    heights = [scene.table.height + 0.5 * o.height for o in scene.objects]
    for message, t, state in zip(messages, output.trajectory.times, output.trajectory_states,
                                 strict=True):
        assert message.log_time_ns == START_NS + round(t * 1e9)
        assert _ns(message.ros_msg.header.stamp) == message.log_time_ns
        assert message.ros_msg.header.frame_id == FRAME
        poses = message.ros_msg.poses
        assert len(poses) == len(scene.objects)
        for pose, (x, y, yaw), z in zip(poses, state.objects, heights, strict=True):
            q = pose.orientation
            recorded_yaw = math.atan2(2 * (q.w * q.z + q.x * q.y), 1 - 2 * (q.y**2 + q.z**2))
            assert (pose.position.x, pose.position.y, pose.position.z) == pytest.approx(
                (x, y, z), abs=1e-12)
            assert math.remainder(recorded_yaw - yaw, 2 * math.pi) == pytest.approx(0, abs=1e-9)
    final = messages[-1].ros_msg.poses[scene.goal_index].position
    assert scene.goal.reached(np.array([final.x, final.y]))


def test_inputs_default_to_the_start_state_and_goal(solved):
    output, path = solved
    scene, stamp = output.scene, Time(sec=START_NS // 10**9, nanosec=START_NS % 10**9)
    start = output.result.states[0]
    [joint_state] = _decoded(path, TOPICS["joint_state"])
    assert joint_state == configuration_to_joint_state(start.q, scene.robot.joint_names, stamp)
    [goal] = _decoded(path, TOPICS["goal"])
    assert goal == goal_to_pose_stamped(scene.goal.position, FRAME, scene.table.height, stamp)
    [poses] = _decoded(path, TOPICS["object_poses"])
    assert poses.header.frame_id == FRAME and _ns(poses.header.stamp) == START_NS
    np.testing.assert_allclose([[p.position.x, p.position.y] for p in poses.poses],
                               start.objects[:, :2], rtol=0, atol=1e-12)


def test_markers_show_the_scene_and_the_plan(solved, failed):
    output, path = solved
    [markers] = _decoded(path, TOPICS["markers"])
    object_paths = np.array([s.objects for s in output.trajectory_states])
    ee_path = np.array([output.scene.robot.tool_pose(q)[:3, 3]
                        for q in output.trajectory.positions])
    stamp = Time(sec=START_NS // 10**9, nanosec=START_NS % 10**9)
    assert markers == _through_cdr(
        plan_markers(output.scene, object_paths, ee_path, FRAME, stamp))
    assert {"ee_path", "object_paths"} <= {m.ns for m in markers.markers}
    output, path = failed
    [markers] = _decoded(path, TOPICS["markers"])
    assert markers == _through_cdr(plan_markers(output.scene, None, None, FRAME, stamp))


@pytest.mark.parametrize("which", ["solved", "failed"])
def test_metadata_record_holds_parameters_scene_and_statistics(which, request):
    output, path = request.getfixturevalue(which)
    _, summary, metadata = _summary(path)
    [record] = [m for m in metadata if m.name == METADATA_NAME]
    assert set(record.metadata) == METADATA_KEYS
    data = record.metadata
    assert data["plan_id"] == ("plan-0001" if which == "solved" else "plan-0002")
    assert data["planner"] == "pc-rrt"
    assert int(data["seed"]) == output.result.seed == 0
    assert data["outcome"] == output.result.outcome.value
    assert data["message"] == output.result.message
    assert data["fragile"] == "false"           # not robust-selected: never fragile
    parameters = json.loads(data["parameters"], parse_constant=pytest.fail)
    if which == "solved":
        assert parameters == {**PARAMETERS, "max_iterations": "inf",
                              "record_dir": "/tmp/plans"}
    scene = yaml.safe_load(data["scene"])
    assert scene == output.scene.to_dict()
    rebuilt = parse_scene(scene, name="recorded")
    assert rebuilt.object_names == output.scene.object_names
    statistics = json.loads(data["statistics"], parse_constant=pytest.fail)
    expected = output.to_dict()
    del expected["trajectory"]
    assert statistics == json.loads(json.dumps(expected))
    assert statistics["solved"] is output.solved


def test_given_inputs_are_recorded_as_given(solved, tmp_path):
    output, _ = solved
    joint_state = JointState(name=["extra", *output.scene.robot.joint_names],
                             position=[9.0, *output.scene.start_configuration],
                             velocity=array.array("d", [0.5] * 8))
    joint_state.header.stamp = Time(sec=12, nanosec=34)
    poses = PoseArray(poses=[Pose(position=Point(x=0.1 * i)) for i in range(3)])
    poses.header.frame_id = FRAME
    goal = PoseStamped()
    goal.header.frame_id = FRAME
    goal.pose.position.x = 0.7
    path = record_plan(tmp_path / "given.mcap", output, plan_id="p", parameters={},
                       planning_frame=FRAME, joint_state=joint_state, object_poses=poses,
                       goal=goal)
    assert _decoded(path, TOPICS["joint_state"]) == [joint_state]
    assert _decoded(path, TOPICS["object_poses"]) == [poses]
    assert _decoded(path, TOPICS["goal"]) == [goal]


def test_start_time_defaults_to_now(solved, tmp_path):
    output, _ = solved
    before = time.time_ns()
    path = record_plan(tmp_path / "now.mcap", output, plan_id="p", parameters={},
                       planning_frame=FRAME)
    after = time.time_ns()
    [message] = list(read_ros2_messages(path, topics=[TOPICS["trajectory"]]))
    assert before <= message.log_time_ns <= after


# --------------------------------------------------------------------------------------------
# Message definitions and QoS text
# --------------------------------------------------------------------------------------------


def _share_file(type_name: str, extension: str) -> Path:
    package, namespace, name = type_name.split("/")
    return Path(sys.prefix) / "share" / package / namespace / f"{name}{extension}"


def _msg_file(package: str, name: str) -> str:
    return _share_file(f"{package}/msg/{name}", ".msg").read_text()


def test_message_definition_concatenates_each_nested_type_once():
    text = message_definition("visualization_msgs/msg/MarkerArray")
    lines = text.split("\n")
    assert lines.count("MSG: visualization_msgs/Marker") == 1
    assert lines.count("MSG: std_msgs/Header") == 1
    blocks = text.split("\n" + "=" * 80 + "\n")
    assert blocks[0] == _msg_file("visualization_msgs", "MarkerArray")
    names = []
    for block in blocks[1:]:
        first, _, body = block.partition("\n")
        assert first.startswith("MSG: ")
        package, name = first[len("MSG: "):].split("/")
        assert body == _msg_file(package, name), first
        names.append(f"{package}/{name}")
    # rosbag2's order: each type's dependencies sorted by name, depth first, each type once
    assert names == ["visualization_msgs/Marker", "builtin_interfaces/Duration",
                     "geometry_msgs/Point", "geometry_msgs/Pose", "geometry_msgs/Quaternion",
                     "geometry_msgs/Vector3", "sensor_msgs/CompressedImage", "std_msgs/Header",
                     "builtin_interfaces/Time", "std_msgs/ColorRGBA", "visualization_msgs/MeshFile",
                     "visualization_msgs/UVCoordinate"]
    assert {"visualization_msgs/Marker", "std_msgs/Header", "builtin_interfaces/Time",
            "builtin_interfaces/Duration", "geometry_msgs/Pose", "geometry_msgs/Point",
            "std_msgs/ColorRGBA"} <= set(names)
    assert message_definition("visualization_msgs/MarkerArray") == text


def test_message_definition_of_a_flat_type_is_its_msg_file():
    assert message_definition("builtin_interfaces/msg/Time") == _msg_file("builtin_interfaces",
                                                                          "Time")


@pytest.mark.parametrize("type_name", ["no_such_msgs/msg/Thing", "std_msgs/msg/NoSuchType",
                                       "not a type", "std_msgs"])
def test_unknown_message_type_is_a_recording_error(type_name):
    with pytest.raises(RecordingError, match="no message definition|not a ROS type name"):
        message_definition(type_name)
    assert issubclass(RecordingError, RearrangementError)


def test_offered_qos_profiles_text_is_rosbag2_jazzy_yaml():
    infinite = "\n    sec: 9223372036\n    nsec: 854775807"
    assert offered_qos_profiles("transient_local") == (
        "- history: keep_last\n  depth: 1\n  reliability: reliable\n"
        "  durability: transient_local\n"
        f"  deadline:{infinite}\n  lifespan:{infinite}\n  liveliness: automatic\n"
        f"  liveliness_lease_duration:{infinite}\n  avoid_ros_namespace_conventions: false")
    with pytest.raises(RecordingError, match="unknown QoS 'latched'"):
        offered_qos_profiles("latched")


# --------------------------------------------------------------------------------------------
# The recorder on its own
# --------------------------------------------------------------------------------------------


def test_recorder_encodes_message_objects_and_dicts(tmp_path):
    joint_state = JointState(name=["a", "b"], position=np.array([1.0, -2.5]),
                             velocity=array.array("d", [0.25, 0.5]))
    joint_state.header.frame_id = "base"
    covariance = PoseWithCovarianceStamped()
    covariance.pose.covariance[7] = 3.5   # a fixed-size float64[36]: a numpy array in rclpy
    marker = Marker(ns="n", id=4, type=Marker.LINE_STRIP, lifetime=Duration(sec=2, nanosec=3),
                    points=[Point(x=1.0), Point(y=2.0)], colors=[ColorRGBA(r=1.0, a=1.0)])
    image = Image(height=1, width=3, encoding="mono8", step=3,
                  data=array.array("B", [1, 2, 250]))
    written = {
        "/js": ("sensor_msgs/msg/JointState", joint_state),
        "/cov": ("geometry_msgs/msg/PoseWithCovarianceStamped", covariance),
        "/markers": ("visualization_msgs/msg/MarkerArray", MarkerArray(markers=[marker])),
        "/image": ("sensor_msgs/msg/Image", image),
        "/byte": ("std_msgs/msg/Byte", Byte(data=b"\x07")),
    }
    path = tmp_path / "objects.mcap"
    with McapRecorder(path) as recorder:
        for i, (topic, (type_name, message)) in enumerate(written.items()):
            recorder.write(topic, type_name, message, 1000 + i)
        recorder.write("/dict", "sensor_msgs/msg/JointState",
                       {"header": {"frame_id": "d", "stamp": {"sec": 3}}, "name": ["x"],
                        "position": np.array([4.0])}, 2000)
    for topic, (_, message) in written.items():
        assert _decoded(path, topic) == [message], topic
    [from_dict] = _decoded(path, "/dict")
    assert from_dict.header.frame_id == "d" and from_dict.header.stamp.sec == 3
    assert list(from_dict.name) == ["x"] and list(from_dict.position) == [4.0]


def test_recorder_rejects_misuse_with_recording_errors(tmp_path):
    recorder = McapRecorder(tmp_path / "misuse.mcap")
    recorder.write("/a", "std_msgs/msg/String", {"data": "x"}, 1)
    with pytest.raises(RecordingError, match="/a carries std_msgs/msg/String"):
        recorder.write("/a", "std_msgs/msg/Int32", {"data": 1}, 2)
    with pytest.raises(RecordingError, match="does not fit std_msgs/msg/Float64"):
        recorder.write("/b", "std_msgs/msg/Float64", {"data": "not a number"}, 3)
    with pytest.raises(RecordingError, match="no message definition"):
        recorder.write("/c", "nope_msgs/msg/Nothing", {}, 4)
    with pytest.raises(RecordingError, match="must be strings"):
        recorder.metadata("m", {"k": 1})
    recorder.close()
    recorder.close()   # idempotent
    assert recorder.closed
    with pytest.raises(RecordingError, match="closed"):
        recorder.write("/a", "std_msgs/msg/String", {"data": "y"}, 5)
    [message] = list(read_ros2_messages(tmp_path / "misuse.mcap"))
    assert message.ros_msg.data == "x"


def test_path_under_a_file_is_a_recording_error(solved, tmp_path):
    output, _ = solved
    blocker = tmp_path / "not_a_dir"
    blocker.write_text("")
    path = blocker / "plans" / "p.mcap"
    with pytest.raises(RecordingError, match=str(path)):
        record_plan(path, output, plan_id="p", parameters={}, planning_frame=FRAME)
    with pytest.raises(RecordingError, match=str(tmp_path)):
        McapRecorder(tmp_path)   # a directory


def test_full_disk_is_a_recording_error(solved):
    output, _ = solved
    with pytest.raises(RecordingError, match="/dev/full.*No space left"):
        record_plan("/dev/full", output, plan_id="p", parameters={}, planning_frame=FRAME)


def test_core_recorder_needs_no_ros_python_packages(tmp_path):
    script = f"""
import sys
from rearrangement_planner.io.recording import McapRecorder
with McapRecorder({str(tmp_path / "core.mcap")!r}) as recorder:
    recorder.write("/js", "sensor_msgs/msg/JointState", {{"name": ["a"], "position": [1.0]}}, 1)
ros = sorted(m for m in sys.modules if m.split(".")[0] in
             ("rclpy", "msg_adapters", "sensor_msgs", "std_msgs", "builtin_interfaces"))
assert not ros, ros
"""
    subprocess.run([sys.executable, "-c", script], check=True, cwd=Path(__file__).parents[2])
    [message] = _decoded(tmp_path / "core.mcap", "/js")
    assert list(message.position) == [1.0]
