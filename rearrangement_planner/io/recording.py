"""MCAP recording in the layout `ros2 bag record` (rosbag2, Jazzy) writes (docs/design.md).

A recording is one `.mcap` file with
  * profile ``ros2`` in the header;
  * one schema per message type, named ``pkg/msg/Type``, encoding ``ros2msg``: the type's
    complete definition, concatenated exactly as rosbag2's ``LocalMessageDefinitionSource``
    does (`message_definition`);
  * one channel per topic, message encoding ``cdr``, with the channel metadata
    ``offered_qos_profiles``: the publisher's QoS as the YAML list rosbag2 Jazzy writes
    (`offered_qos_profiles`), and ``topic_type_hash`` (`type_hash`);
  * metadata records (name -> {key: value} strings).

    with McapRecorder("plans/plan_0001.mcap") as recorder:
        recorder.write("/joint_states", "sensor_msgs/msg/JointState", msg, t_ns, qos="sensor")
        recorder.metadata("rearrangement_plan", {"seed": "0"})

Messages are encoded to CDR from the schema text by mcap-ros2-support's dynamic encoder, so
this module needs neither rclpy nor the message packages' Python code: only their installed
``.msg`` files, found under ``<prefix>/share/<pkg>/msg/`` for every prefix on
``AMENT_PREFIX_PATH`` and then `sys.prefix` (where the PyPI wheels install them). A message
may be a ROS message object or a plain dict (nested dicts/lists, numpy arrays allowed).

Any failure to record (unwritable path, full disk, unknown type, a message that does not fit
its type) raises `RecordingError`, so that a caller can report it and keep the plan.
"""

from __future__ import annotations

import array
import functools
import importlib.metadata
import json
import os
import re
import sys
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import IO, Any

from mcap.well_known import MessageEncoding, SchemaEncoding
from mcap.writer import CompressionType, Writer

from rearrangement_planner.model.errors import RearrangementError


class RecordingError(RearrangementError):
    """A recording could not be written. The message names the file and the problem."""


# --------------------------------------------------------------------------------------------
# Message definitions (rosbag2_cpp local_message_definition_source.cpp, ros2msg format; the
# format is specified in rosbag2 docs/message_definition_encoding.md)
# --------------------------------------------------------------------------------------------

_DELIMITER = "=" * 80 + "\n"
_MAX_DEPTH = 50   # rosbag2's ROSBAG2_CPP_LOCAL_MESSAGE_DEFINITION_SOURCE_MAX_RECURSION_DEPTH
_PRIMITIVES = frozenset({"bool", "byte", "char", "float32", "float64", "int8", "uint8", "int16",
                         "uint16", "int32", "uint32", "int64", "uint64", "string"})
# A field's type at the start of a line ("foo_msgs/Bar" in "foo_msgs/Bar[] bar"); comments,
# bounded strings and constants' values do not match. The same expression as rosbag2's.
_FIELD_TYPE = re.compile(r"(?:^|\n)\s*([a-zA-Z0-9_/]+)(?:\[[^\]]*\])?\s+")
_NAME = r"[a-zA-Z][a-zA-Z0-9_]*"
_TYPE_NAME = re.compile(rf"({_NAME})/(?:({_NAME})/)?({_NAME})")


def _split_type(type_name: str) -> tuple[str, str, str]:
    """("pkg", "msg", "Type") of "pkg/msg/Type" or "pkg/Type"."""
    match = _TYPE_NAME.fullmatch(type_name)
    if match is None:
        raise RecordingError(f"message type {type_name!r} is not a ROS type name; expected "
                             "'package/msg/Type', e.g. 'sensor_msgs/msg/JointState'")
    package, namespace, name = match.groups()
    return package, namespace or "msg", name


def _prefixes() -> list[Path]:
    """Install prefixes to search for message packages: AMENT_PREFIX_PATH, then sys.prefix."""
    prefixes = [Path(p) for p in os.environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep) if p]
    return [*prefixes, Path(sys.prefix)]


_ACTION_PARTS = ("Goal", "Result", "Feedback")
"""The messages of an action, in the order of their sections in its .action file."""


def _action_part(namespace: str, name: str) -> tuple[str, int] | None:
    """(action name, section index) of an action's message ("pkg/action/Move_Goal" is section
    0 of Move.action), or None for a message that is not one."""
    base, _, part = name.rpartition("_")
    if namespace != "action" or not base or part not in _ACTION_PARTS:
        return None
    return base, _ACTION_PARTS.index(part)


def _find_share_file(type_name: str, extension: str) -> Path | None:
    """<prefix>/share/<pkg>/msg/<Type><extension> in the first prefix that has it (an action's
    message: <prefix>/share/<pkg>/action/<Action><extension>)."""
    package, namespace, name = _split_type(type_name)
    part = _action_part(namespace, name)
    if part is not None:
        name = part[0]
        extension = ".action" if extension == ".msg" else extension
    for prefix in _prefixes():
        path = prefix / "share" / package / namespace / f"{name}{extension}"
        if path.is_file():
            return path
    return None


_DEFINED: dict[str, str] = {}
"""Definitions known beside the installed packages' (`define`)."""


def define(texts: Mapping[str, str]) -> None:
    """Make the recorder know message types no installed package defines: `texts` maps
    "pkg/msg/Type" to its .msg text (`io.foxglove_ros2`: Foxglove's SceneUpdate)."""
    if all(_DEFINED.get(name) == text for name, text in texts.items()):
        return
    _DEFINED.update(texts)
    _load_spec.cache_clear()
    message_definition.cache_clear()


@functools.cache
def _load_spec(type_name: str) -> tuple[str, tuple[str, ...]]:
    """(.msg text, dependencies as sorted "pkg/Type") of `type_name` (an action's goal,
    result or feedback: its section of the .action file)."""
    package, namespace, name = _split_type(type_name)
    defined = _DEFINED.get(f"{package}/{namespace}/{name}")
    if defined is not None:
        return _dependencies(defined, package)
    path = _find_share_file(type_name, ".msg")
    if path is None:
        raise RecordingError(
            f"no message definition for {type_name!r}: share/{package}/{namespace}/{name}.msg "
            f"is under none of {[str(p) for p in _prefixes()]}; install the message package "
            "or add its install prefix to AMENT_PREFIX_PATH")
    try:
        text = path.read_bytes().decode("utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise RecordingError(f"cannot read the definition of {type_name} at {path}: "
                             f"{exc}") from exc
    part = _action_part(namespace, name)
    if part is not None:             # goal, result and feedback are separated by '---' lines
        sections = re.split(r"^---[ \t]*\n", text, flags=re.MULTILINE)
        if len(sections) != len(_ACTION_PARTS):
            raise RecordingError(f"{path} has {len(sections)} sections, not goal, result and "
                                 f"feedback")
        text = sections[part[1]]
    return _dependencies(text, package)


def _dependencies(text: str, package: str) -> tuple[str, tuple[str, ...]]:
    """(`text`, the types its fields use as sorted "pkg/Type")."""
    dependencies = set()
    for match in _FIELD_TYPE.finditer(text):
        field_type = match.group(1)
        if field_type in _PRIMITIVES:
            continue
        dependencies.add(field_type if "/" in field_type else f"{package}/{field_type}")
    return text, tuple(sorted(dependencies))   # rosbag2 keeps them in a std::set


@functools.cache
def message_definition(type_name: str) -> str:
    """The complete ``ros2msg`` definition of `type_name` ("pkg/msg/Type"), as rosbag2 writes
    it into a bag: the type's .msg text, then every type it uses, depth first and each once
    (in sorted order at each level), each preceded by a line of 80 '=' and a line
    "MSG: pkg/Type". Raises RecordingError when a definition cannot be found."""
    seen: set[str] = set()

    def full_text(name: str, depth: int) -> str:
        if depth <= 0:
            raise RecordingError(f"reached the maximum nesting depth resolving {type_name}")
        text, dependencies = _load_spec(name)
        parts = [text]
        for dependency in dependencies:
            if dependency not in seen:
                seen.add(dependency)
                parts.append(f"\n{_DELIMITER}MSG: {dependency}\n")
                parts.append(full_text(dependency, depth - 1))
        return "".join(parts)

    return full_text(type_name, _MAX_DEPTH)


@functools.cache
def type_hash(type_name: str) -> str:
    """The type description hash ("RIHS01_...") of `type_name` ("pkg/msg/Type") from the
    .json type description installed beside its .msg file, or "" where there is none (what
    rosbag2 writes into the ``topic_type_hash`` channel metadata when it knows no hash)."""
    package, namespace, name = _split_type(type_name)
    path = _find_share_file(type_name, ".json")
    if path is None:
        return ""
    try:
        hashes = json.loads(path.read_text(encoding="utf-8")).get("type_hashes", [])
    except (OSError, ValueError, AttributeError):
        return ""
    full_name = f"{package}/{namespace}/{name}"
    return next((h.get("hash_string", "") for h in hashes
                 if isinstance(h, dict) and h.get("type_name") == full_name), "")


# --------------------------------------------------------------------------------------------
# Offered QoS profiles (rosbag2_storage qos.cpp, metadata version >= 9 as in Jazzy: policies by
# name; a list of profiles dumped by yaml-cpp)
# --------------------------------------------------------------------------------------------
# rosbag2's MCAP plugin decodes these with the bag's metadata version: its own (9 in Jazzy) when
# the file has no "rosbag2" metadata record. Never write a "rosbag2" record without the key
# "serialized_metadata": the plugin then assumes version 8 and expects integer policies.

# Deadline, lifespan and liveliness lease as DDS reports an unset (infinite) duration:
# RMW_DURATION_INFINITE = INT64_MAX ns = 9223372036 s + 854775807 ns.
_INFINITE = "\n    sec: 9223372036\n    nsec: 854775807"

QOS_PROFILES: dict[str, tuple[str, int, str, str]] = {
    # name: (reliability, depth, durability, description)
    "reliable": ("reliable", 10, "volatile", "rclpy's default: reliable, volatile, keep last 10"),
    "transient_local": ("reliable", 1, "transient_local",
                        "latched: reliable, transient local, keep last 1"),
    "sensor": ("best_effort", 5, "volatile",
               "qos_profile_sensor_data: best effort, volatile, keep last 5"),
}


def offered_qos_profiles(qos: str) -> str:
    """The ``offered_qos_profiles`` channel metadata of one publisher with QoS `qos` (a key of
    QOS_PROFILES), in the text rosbag2 Jazzy writes (a YAML sequence of one profile)."""
    if qos not in QOS_PROFILES:
        raise RecordingError(f"unknown QoS {qos!r}; choose one of {sorted(QOS_PROFILES)}")
    reliability, depth, durability, _ = QOS_PROFILES[qos]
    return ("- history: keep_last\n"
            f"  depth: {depth}\n"
            f"  reliability: {reliability}\n"
            f"  durability: {durability}\n"
            f"  deadline:{_INFINITE}\n"
            f"  lifespan:{_INFINITE}\n"
            "  liveliness: automatic\n"
            f"  liveliness_lease_duration:{_INFINITE}\n"
            "  avoid_ros_namespace_conventions: false")


# --------------------------------------------------------------------------------------------
# Encoding
# --------------------------------------------------------------------------------------------

def _encoder(type_name: str) -> Callable[[Any], bytes]:
    # mcap-ros2-support's dynamic CDR encoder (what mcap_ros2.writer.Writer uses internally;
    # that Writer cannot set channel metadata, so the mcap Writer is driven directly here).
    from mcap_ros2._dynamic import serialize_dynamic

    try:
        encoders = serialize_dynamic(type_name, message_definition(type_name))
    except RecordingError:
        raise
    except Exception as exc:   # the vendored rosidl parser raises assorted errors
        raise RecordingError(f"cannot parse the definition of {type_name}: {exc}") from exc
    if type_name not in encoders:
        raise RecordingError(f"the definition of {type_name} did not yield an encoder")
    return encoders[type_name]


def _plain(value: Any) -> Any:
    """`value` as the plain data the CDR encoder accepts: ROS message objects become dicts
    (via their generated ``get_fields_and_field_types``), numpy arrays and tuples lists,
    rclpy's ``byte`` values (1-byte bytes) ints and its ``byte[]`` (lists of them) bytes."""
    fields = getattr(value, "get_fields_and_field_types", None)
    if callable(fields):
        return {name: _plain_field(getattr(value, name), kind) for name, kind in fields().items()}
    if isinstance(value, Mapping):
        return {key: _plain(item) for key, item in value.items()}
    if isinstance(value, (bytes, bytearray, array.array, str)):
        return value
    if hasattr(value, "tolist"):   # numpy arrays and scalars
        return value.tolist()
    if isinstance(value, (list, tuple)):
        if value and all(isinstance(item, bytes) and len(item) == 1 for item in value):
            return b"".join(value)
        return [_plain(item) for item in value]
    return value


def _plain_field(value: Any, kind: str) -> Any:
    if kind == "octet" and isinstance(value, bytes):
        return value[0]
    return _plain(value)


# --------------------------------------------------------------------------------------------
# The recorder
# --------------------------------------------------------------------------------------------

def _library() -> str:
    def version(dist: str) -> str:
        try:
            return importlib.metadata.version(dist)
        except importlib.metadata.PackageNotFoundError:
            return "unknown"

    return (f"rearrangement_planner {version('rearrangement_planner')}; mcap "
            f"{version('mcap')}; mcap-ros2-support {version('mcap-ros2-support')}")


def _os_problem(exc: OSError) -> str:
    return exc.strerror or str(exc)


class McapRecorder:
    """Writes one rosbag2-compatible MCAP file (see the module docstring). A context manager;
    `close` finishes the file (summary and index) and is idempotent."""

    def __init__(self, path: str | os.PathLike[str]):
        self.path = Path(path)
        self._stream: IO[bytes] | None = None
        self._schemas: dict[str, int] = {}
        self._encoders: dict[str, Callable[[Any], bytes]] = {}
        self._channels: dict[str, tuple[int, str]] = {}
        self._sequence: dict[int, int] = {}
        try:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            self._stream = open(self.path, "wb")   # closed in close()
            self._writer = Writer(self._stream, compression=CompressionType.ZSTD)
            self._writer.start(profile="ros2", library=_library())
        except OSError as exc:
            self._close_stream()
            raise RecordingError(f"cannot record to {self.path}: {_os_problem(exc)}") from exc

    @property
    def closed(self) -> bool:
        return self._stream is None

    def write(self, topic: str, type_name: str, message: Any, log_time_ns: int,
              qos: str = "reliable") -> None:
        """Append `message` (a ROS message object or a dict) of type `type_name`
        ("pkg/msg/Type") on `topic`, logged and published at `log_time_ns` (ns since the
        epoch). The first message on a topic creates its channel with QoS `qos` (a key of
        QOS_PROFILES)."""
        if self._stream is None:
            raise RecordingError(f"cannot record to {self.path}: the recording is closed")
        channel_id = self._channel(topic, type_name, qos)
        try:
            data = self._encoders[type_name](_plain(message))
        except Exception as exc:   # the encoder raises ValueError, TypeError, struct.error ...
            raise RecordingError(f"cannot record to {self.path}: the message on {topic} does "
                                 f"not fit {type_name}: {exc}") from exc
        sequence = self._sequence[channel_id]
        self._sequence[channel_id] = sequence + 1
        try:
            self._writer.add_message(channel_id, log_time=int(log_time_ns), data=data,
                                     publish_time=int(log_time_ns), sequence=sequence)
        except OSError as exc:
            raise RecordingError(f"cannot record to {self.path}: {_os_problem(exc)}") from exc

    def _channel(self, topic: str, type_name: str, qos: str) -> int:
        known = self._channels.get(topic)
        if known is not None:
            if known[1] != type_name:
                raise RecordingError(f"cannot record to {self.path}: topic {topic} carries "
                                     f"{known[1]}, not {type_name}")
            return known[0]
        metadata = {"offered_qos_profiles": offered_qos_profiles(qos),
                     "topic_type_hash": type_hash(type_name)}
        if type_name not in self._schemas:
            self._encoders[type_name] = _encoder(type_name)
            try:
                self._schemas[type_name] = self._writer.register_schema(
                    type_name, SchemaEncoding.ROS2, message_definition(type_name).encode())
            except OSError as exc:
                raise RecordingError(f"cannot record to {self.path}: "
                                     f"{_os_problem(exc)}") from exc
        try:
            channel_id = self._writer.register_channel(
                topic, MessageEncoding.CDR, self._schemas[type_name], metadata)
        except OSError as exc:
            raise RecordingError(f"cannot record to {self.path}: {_os_problem(exc)}") from exc
        self._channels[topic] = (channel_id, type_name)
        self._sequence[channel_id] = 0
        return channel_id

    def metadata(self, name: str, data: Mapping[str, str]) -> None:
        """Add a metadata record `name` with string keys and values."""
        if self._stream is None:
            raise RecordingError(f"cannot record to {self.path}: the recording is closed")
        bad = [key for key, value in data.items()
               if not isinstance(key, str) or not isinstance(value, str)]
        if bad:
            raise RecordingError(f"cannot record to {self.path}: metadata {name!r} keys and "
                                 f"values must be strings; {bad} are not")
        try:
            self._writer.add_metadata(name, dict(data))
        except OSError as exc:
            raise RecordingError(f"cannot record to {self.path}: {_os_problem(exc)}") from exc

    def close(self) -> None:
        """Finish and close the file. Idempotent."""
        if self._stream is None:
            return
        try:
            self._writer.finish()
            self._stream.flush()
        except OSError as exc:
            raise RecordingError(f"cannot record to {self.path}: {_os_problem(exc)}") from exc
        finally:
            self._close_stream()

    def _close_stream(self) -> None:
        stream, self._stream = self._stream, None
        if stream is not None:
            try:
                stream.close()
            except OSError:
                pass   # a failed flush was reported by the caller of close()

    def __enter__(self) -> McapRecorder:
        return self

    def __exit__(self, exc_type, exc, traceback) -> None:
        if exc is None:
            self.close()
            return
        try:   # leave a readable file behind, but let the original error propagate
            self.close()
        except RecordingError:
            pass
