"""Foxglove's 3D messages as ROS 2 messages (`foxglove_msgs/msg/SceneUpdate` and what it holds),
so that a recording carries them as CDR with ros2msg schemas like every other topic: rosbag2,
mcap_ros2 and Foxglove read the whole file alike, and Foxglove draws the scene.

    definitions()                    # {"foxglove_msgs/msg/SceneUpdate": ".msg text", ...}
    as_ros2(scene3d.scene_update(scene))   # the dict the CDR encoder takes

The definitions are derived from the protobuf schema the Foxglove SDK ships
(`foxglove.messages.SceneUpdate.get_schema()`), with Foxglove's ROS 2 conventions: its Pose,
Vector3, Quaternion and Point3 are geometry_msgs' (Point for Point3), its Timestamp and Duration
builtin_interfaces', an enum a uint8 field with one constant per value, and the fields in the
protobuf order. No ROS package of Foxglove's is needed; `recording` registers these texts.
"""

from __future__ import annotations

import functools
from typing import Any

from foxglove import messages as fg
from google.protobuf import descriptor_pb2, descriptor_pool, message_factory
from google.protobuf.descriptor import Descriptor, FieldDescriptor

PACKAGE = "foxglove_msgs"
SCENE_UPDATE = f"{PACKAGE}/msg/SceneUpdate"
MAPPED = {"foxglove.Pose": "geometry_msgs/Pose", "foxglove.Vector3": "geometry_msgs/Vector3",
          "foxglove.Quaternion": "geometry_msgs/Quaternion",
          "foxglove.Point3": "geometry_msgs/Point",
          "google.protobuf.Timestamp": "builtin_interfaces/Time",
          "google.protobuf.Duration": "builtin_interfaces/Duration"}
"""Protobuf messages that are standard ROS 2 messages."""
SCALARS = {FieldDescriptor.TYPE_DOUBLE: "float64", FieldDescriptor.TYPE_FLOAT: "float32",
           FieldDescriptor.TYPE_BOOL: "bool", FieldDescriptor.TYPE_STRING: "string",
           FieldDescriptor.TYPE_FIXED32: "uint32", FieldDescriptor.TYPE_UINT32: "uint32",
           FieldDescriptor.TYPE_INT32: "int32", FieldDescriptor.TYPE_FIXED64: "uint64",
           FieldDescriptor.TYPE_UINT64: "uint64", FieldDescriptor.TYPE_INT64: "int64",
           FieldDescriptor.TYPE_ENUM: "uint8"}
TIME_FIELDS = {"seconds": "sec", "nanos": "nanosec"}


@functools.cache
def _scene_update_class() -> Any:
    """The protobuf class of foxglove.SceneUpdate, from the SDK's schema."""
    pool = descriptor_pool.DescriptorPool()
    schema = fg.SceneUpdate.get_schema()
    for file in descriptor_pb2.FileDescriptorSet.FromString(bytes(schema.data)).file:
        pool.Add(file)
    return message_factory.GetMessageClass(pool.FindMessageTypeByName(schema.name))


@functools.cache
def definitions() -> dict[str, str]:
    """The .msg text of SceneUpdate and of every Foxglove message it holds, by "pkg/msg/Type"."""
    texts: dict[str, str] = {}

    def define(message: Descriptor) -> None:
        name = f"{PACKAGE}/msg/{message.name}"
        if message.full_name in MAPPED or name in texts:
            return
        lines = []
        for enum in message.enum_types:
            lines += [f"uint8 {value.name}={value.number}" for value in enum.values]
        if message.enum_types:
            lines.append("")
        for field in message.fields:
            lines.append(f"{_ros_type(field)} {field.name}")
            if field.type == FieldDescriptor.TYPE_MESSAGE:
                define(field.message_type)
        texts[name] = "\n".join(lines) + "\n"

    define(_scene_update_class().DESCRIPTOR)
    return texts


def _ros_type(field: FieldDescriptor) -> str:
    if field.type == FieldDescriptor.TYPE_MESSAGE:
        full = field.message_type.full_name
        kind = MAPPED.get(full, f"{PACKAGE}/{field.message_type.name}")
    elif field.type == FieldDescriptor.TYPE_BYTES:
        return "uint8[]"
    else:
        kind = SCALARS[field.type]
    repeated = field.is_repeated
    return f"{kind}[]" if repeated else kind


def as_ros2(update: fg.SceneUpdate) -> dict[str, Any]:
    """`update` as the plain dict of a foxglove_msgs/msg/SceneUpdate."""
    return _plain(_scene_update_class().FromString(bytes(update.encode())))


def _plain(message: Any) -> dict[str, Any]:
    timestamp = message.DESCRIPTOR.full_name in ("google.protobuf.Timestamp",
                                                 "google.protobuf.Duration")
    out: dict[str, Any] = {}
    for field in message.DESCRIPTOR.fields:
        value = getattr(message, field.name)
        name = TIME_FIELDS.get(field.name, field.name) if timestamp else field.name
        if field.type == FieldDescriptor.TYPE_MESSAGE:
            out[name] = ([_plain(v) for v in value]
                         if field.is_repeated else _plain(value))
        elif field.is_repeated:
            out[name] = list(value)
        else:
            out[name] = bytes(value) if field.type == FieldDescriptor.TYPE_BYTES else value
    return out
