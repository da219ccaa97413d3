"""Replay recorded inputs into the planner node, like `ros2 bag play`, then plan (and execute).

    python -m rearrangement_planner.ros.sim.replay bags/default_3obj.mcap --rate 2 \
        --start-node --execute

Pieces, usable on their own (the tests and `make_bags` use them):

- `read_bag(path)` -> `Bag`: the topics (type, offered QoS) and messages of a rosbag2 MCAP file
  (profile ros2, cdr), the messages in log-time order (ties in file order), still serialized,
  and its metadata records. Read with the `mcap` library; messages are deserialized on demand
  with `rclpy.serialization`.
- `BagPlayer(node, bag, rate=, namespace=)`: one publisher per topic with the QoS the bag says
  the recorded publisher offered (reliability, durability, history depth), publishing the raw
  CDR bytes at their log times divided by `rate` (as `ros2 bag play --rate`); header stamps are
  left as recorded. `wait_for_subscribers()` first, so that nothing is published into the void.
- `PlannerClient(node, namespace)` (`ros/client.py`): the planner node's action
  `~/plan_rearrangement` and its `~/execute` service; `plan()` returns a `PlanReply`.
- `Session`: an rclpy context with its own executor thread, for running nodes in-process.
- `run_bag(bag, session, ...)`: the whole replay of one input bag: a planner node configured
  from the bag's `rearrangement_input` metadata (scene, seed, time limit, goal radius), the bag
  played into it, a goal of the action, and optionally open-loop execution (`~/execute`) in a
  `world_sim` started on the bag's ground-truth world; returns a `BagRun`.

- `OutcomeListener(node, topic)`: collects world_sim's `~/outcome` JSON messages.

Topics are the bag's, prefixed by `namespace` (e.g. "/b1" turns "/joint_states" into
"/b1/joint_states"), so that several replays can share one ROS domain.

Timing: messages are never published before their time; in a busy process they may be late
(`PlaybackReport.max_lag`): the player is a Python thread, and rclpy's MultiThreadedExecutor
handling a few hundred messages a second in the same process holds the GIL for long stretches
(stalls of up to ~1 s measured with 250 Hz joint states). `run_bag` then waits that much longer
before `~/plan`, so that the node has taken the last messages off its queues.
"""

from __future__ import annotations

import argparse
import contextlib
import importlib
import json
import os
import sys
import tempfile
import threading
import time
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml
from mcap.exceptions import McapError
from mcap.reader import make_reader

from rearrangement_planner.model.errors import RearrangementError
from rearrangement_planner.model.files import FileProblem, parse_yaml
from rearrangement_planner.model.resources import NODE_NAME, share_dir
from rearrangement_planner.ros.client import ClientError, PlannerClient, PlanReply, wait_until

INPUT_METADATA = "rearrangement_input"
"""The metadata record of an input bag (written by make_bags): `planner_parameters` (JSON: the
planner node parameters to replay it with), `world` (YAML scene of the ground truth the bag was
recorded from: true arm and object poses, the bag's goal), `description`."""
SETTLE = 0.3
"""Seconds between the end of playback and ~/plan: the node's subscriptions take the last
messages off their queues meanwhile (a request right after the last publication races them
and plans from an older state). Keep it below the node's state_timeout (1 s)."""

INPUT_WAIT = 10.0
"""Seconds `run_bag` waits for the planner node to take the bag's last inputs."""


def _caught_up(planner: Any, bag: Bag) -> bool:
    """Whether the node's last joint state and object poses are the bag's last ones."""
    latest = planner.last_inputs()
    for key in ("joint_states", "object_poses"):
        topic = next(t for t in bag.topics if t.endswith(key))
        got = latest[key]
        if got is None or got.header.stamp != bag.last(topic).header.stamp:
            return False
    return True


class BagError(RearrangementError):
    """A bag cannot be read or replayed; the message names the file and the problem."""


# --------------------------------------------------------------------------------------------
# Reading
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Topic:
    name: str
    type_name: str
    """"pkg/msg/Type"."""
    offered_qos: list[dict[str, Any]]
    """The recorded publishers' QoS profiles (rosbag2 `offered_qos_profiles`), parsed."""
    count: int


@dataclass(frozen=True)
class BagMessage:
    topic: str
    log_time_ns: int
    data: bytes
    """The CDR bytes, as published."""


@dataclass(frozen=True)
class Bag:
    path: Path
    topics: dict[str, Topic]
    messages: tuple[BagMessage, ...]
    """In log-time order (ties in file order)."""
    metadata: dict[str, dict[str, str]]
    file_order_sorted: bool
    """Whether the file already held the messages in log-time order."""

    @property
    def start_ns(self) -> int:
        return self.messages[0].log_time_ns if self.messages else 0

    @property
    def duration(self) -> float:
        """Log time from the first to the last message, s."""
        return (self.messages[-1].log_time_ns - self.start_ns) * 1e-9 if self.messages else 0.0

    def decode(self, message: BagMessage) -> Any:
        """The message as its rclpy message object."""
        from rclpy.serialization import deserialize_message

        return deserialize_message(message.data, message_class(self.topics[message.topic]
                                                                 .type_name))

    def messages_on(self, topic: str) -> list[Any]:
        """Every message on `topic`, decoded, in log-time order."""
        return [self.decode(m) for m in self.messages if m.topic == topic]

    def last(self, topic: str) -> Any:
        """The last message on `topic` in log-time order (what a subscriber keeps)."""
        for m in reversed(self.messages):
            if m.topic == topic:
                return self.decode(m)
        raise BagError(f"{self.path}: no message on {topic}; topics are {sorted(self.topics)}")

    def input_metadata(self) -> dict[str, Any]:
        """The `rearrangement_input` record: planner_parameters (dict), world (scene dict),
        description (str). BagError when the bag has none (not made by make_bags)."""
        record = self.metadata.get(INPUT_METADATA)
        if record is None:
            raise BagError(f"{self.path}: no '{INPUT_METADATA}' metadata record (scene, seed, "
                           f"ground truth); only bags written by make_bags have one")
        try:
            return {"planner_parameters": json.loads(record["planner_parameters"]),
                    "world": parse_yaml(record["world"], "the bag's world"),
                    "description": record.get("description", "")}
        except (KeyError, ValueError, FileProblem) as exc:
            raise BagError(f"{self.path}: metadata '{INPUT_METADATA}' is malformed: "
                           f"{exc}") from None


def message_class(type_name: str) -> type:
    """The rclpy message class of "pkg/msg/Type" (or of an action's "pkg/action/Type_Goal",
    "_Result", "_Feedback", which the action's class holds)."""
    try:
        package, kind, name = type_name.split("/")
        module = importlib.import_module(f"{package}.{kind}")
        if kind == "action" and not hasattr(module, name):
            action, _, part = name.rpartition("_")
            return getattr(getattr(module, action), part)
        return getattr(module, name)
    except (ValueError, ImportError, AttributeError):
        raise BagError(f"message type {type_name!r} is not installed (expected "
                       f"'package/msg/Type' of an installed message package)") from None


def shipped_bags() -> dict[str, Path]:
    """The input bags shipped with the package: name -> path."""
    folder = share_dir() / "bags"
    return {p.stem: p for p in sorted(folder.glob("*.mcap"))} if folder.is_dir() else {}


def resolve_bag(name_or_path: str | os.PathLike[str]) -> Path:
    """A bag path, or the name of a shipped bag (`bags/<name>.mcap`)."""
    path = Path(name_or_path)
    if path.is_file():
        return path
    shipped = shipped_bags()
    if str(name_or_path) in shipped:
        return shipped[str(name_or_path)]
    raise BagError(f"no bag {str(name_or_path)!r}: not a file, nor a shipped bag "
                   f"({', '.join(shipped) or 'none found'})")


def read_bag(path: str | os.PathLike[str]) -> Bag:
    """Read a rosbag2 MCAP file (see the module docstring). BagError names the problem."""
    path = resolve_bag(path)
    topics: dict[str, tuple[str, list[dict[str, Any]]]] = {}
    messages: list[BagMessage] = []
    counts: dict[str, int] = {}
    try:
        with open(path, "rb") as stream:
            reader = make_reader(stream)
            header = reader.get_header()
            if header.profile != "ros2":
                raise BagError(f"{path}: MCAP profile is {header.profile!r}, not 'ros2' (not a "
                               f"rosbag2 recording)")
            for schema, channel, message in reader.iter_messages(log_time_order=False):
                if channel.topic not in topics:
                    if channel.message_encoding != "cdr" or schema is None:
                        raise BagError(f"{path}: topic {channel.topic} has message encoding "
                                       f"{channel.message_encoding!r}; only cdr can be replayed")
                    topics[channel.topic] = (schema.name, _parse_qos(
                        channel.metadata.get("offered_qos_profiles", ""), path, channel.topic))
                counts[channel.topic] = counts.get(channel.topic, 0) + 1
                messages.append(BagMessage(channel.topic, message.log_time, bytes(message.data)))
            stream.seek(0)
            metadata = {m.name: dict(m.metadata) for m in make_reader(stream).iter_metadata()}
    except OSError as exc:
        raise BagError(f"cannot read {path}: {exc.strerror or exc}") from None
    except McapError as exc:
        raise BagError(f"{path} is not a readable MCAP file: {exc}") from None
    in_order = all(a.log_time_ns <= b.log_time_ns
                   for a, b in zip(messages, messages[1:], strict=False))
    ordered = tuple(sorted(messages, key=lambda m: m.log_time_ns))   # stable: ties in file order
    return Bag(path, {name: Topic(name, type_name, qos, counts[name])
                      for name, (type_name, qos) in topics.items()},
               ordered, metadata, in_order)


def _parse_qos(text: str, path: Path, topic: str) -> list[dict[str, Any]]:
    if not text:
        return []
    try:
        profiles = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        raise BagError(f"{path}: offered_qos_profiles of {topic} is not YAML: {exc}") from None
    if not isinstance(profiles, list) or not all(isinstance(p, dict) for p in profiles):
        raise BagError(f"{path}: offered_qos_profiles of {topic} is not a list of profiles")
    return profiles


# rosbag2 metadata version < 9 wrote the policies as the rmw enum values.
_RELIABILITY = {"reliable": "reliable", "best_effort": "best_effort", 1: "reliable",
                2: "best_effort"}
_DURABILITY = {"volatile": "volatile", "transient_local": "transient_local",
               1: "transient_local", 2: "volatile"}


def playback_qos(topic: Topic):
    """The QoS to publish `topic` with: the recorded publishers' reliability and durability
    when they all agree (as `ros2 bag play` does), else reliable and volatile; keep last with
    the recorded depth (at least 1; 10 when unknown or keep all)."""
    from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

    reliabilities = {_RELIABILITY.get(p.get("reliability")) for p in topic.offered_qos}
    durabilities = {_DURABILITY.get(p.get("durability")) for p in topic.offered_qos}
    reliability = reliabilities.pop() if len(reliabilities) == 1 else "reliable"
    durability = durabilities.pop() if len(durabilities) == 1 else "volatile"
    depths = [p["depth"] for p in topic.offered_qos
              if p.get("history") in ("keep_last", 1) and isinstance(p.get("depth"), int)]
    depth = max(1, max(depths)) if depths else 10
    return QoSProfile(
        history=HistoryPolicy.KEEP_LAST, depth=depth,
        reliability=(ReliabilityPolicy.BEST_EFFORT if reliability == "best_effort"
                     else ReliabilityPolicy.RELIABLE),
        durability=(DurabilityPolicy.TRANSIENT_LOCAL if durability == "transient_local"
                    else DurabilityPolicy.VOLATILE))


# --------------------------------------------------------------------------------------------
# Playing
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class PlaybackReport:
    published: dict[str, int]
    """Messages published per (namespaced) topic."""
    wall_time: float
    """Seconds from the first to the last publication."""
    max_lag: float
    """Largest delay (s) of a publication behind its scheduled wall time."""


class BagPlayer:
    """Publishes a bag's messages through `node` in log-time order, `rate` times as fast as
    recorded, each topic with its recorded QoS (`playback_qos`)."""

    def __init__(self, node, bag: Bag, *, rate: float = 1.0, namespace: str = "",
                 topics: list[str] | None = None):
        if not rate > 0:
            raise BagError(f"rate must be positive, got {rate}")
        unknown = sorted(set(topics or ()) - set(bag.topics))
        if unknown:
            raise BagError(f"{bag.path}: no topics {unknown}; it has {sorted(bag.topics)}")
        self.bag = bag
        self.rate = float(rate)
        self.namespace = namespace.rstrip("/")
        self.topics = list(topics) if topics else sorted(bag.topics)
        self._publishers = {
            name: node.create_publisher(message_class(bag.topics[name].type_name),
                                        self.topic_name(name), playback_qos(bag.topics[name]))
            for name in self.topics}

    def topic_name(self, topic: str) -> str:
        """The name a bag topic is published on."""
        return f"{self.namespace}{topic}" if topic.startswith("/") else \
            f"{self.namespace}/{topic}"

    def wait_for_subscribers(self, timeout: float = 10.0) -> list[str]:
        """Wait until every topic has a matched subscriber; returns those still without one."""
        deadline = time.monotonic() + timeout
        while True:
            missing = [self.topic_name(t) for t, p in self._publishers.items()
                       if p.get_subscription_count() == 0]
            if not missing or time.monotonic() > deadline:
                return missing
            time.sleep(0.02)

    def play(self, stop: threading.Event | None = None) -> PlaybackReport:
        """Publish every message at (log time - first log time) / rate after the start."""
        messages = [m for m in self.bag.messages if m.topic in self._publishers]
        published = {self.topic_name(t): 0 for t in self._publishers}
        if not messages:
            return PlaybackReport(published, 0.0, 0.0)
        first = messages[0].log_time_ns
        t0 = time.monotonic()
        max_lag = 0.0
        for message in messages:
            if stop is not None and stop.is_set():
                break
            due = t0 + (message.log_time_ns - first) * 1e-9 / self.rate
            wait = due - time.monotonic()
            if wait > 0:
                time.sleep(wait)
            else:
                max_lag = max(max_lag, -wait)
            self._publishers[message.topic].publish(message.data)
            published[self.topic_name(message.topic)] += 1
        return PlaybackReport(published, time.monotonic() - t0, max_lag)


# --------------------------------------------------------------------------------------------
# The planner node's services
# --------------------------------------------------------------------------------------------


class OutcomeListener:
    """Collects world_sim's `~/outcome` (JSON) messages."""

    def __init__(self, node, topic: str = "/world_sim/outcome"):
        from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
        from std_msgs.msg import String

        self._lock = threading.Lock()
        self.outcomes: list[dict[str, Any]] = []
        self._subscription = node.create_subscription(
            String, topic, self._on_outcome,
            QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE,
                       durability=DurabilityPolicy.TRANSIENT_LOCAL))

    def _on_outcome(self, msg) -> None:
        with self._lock:
            self.outcomes.append(json.loads(msg.data))

    def count(self) -> int:
        with self._lock:
            return len(self.outcomes)

    def wait_next(self, seen: int, timeout: float) -> dict[str, Any]:
        """The first outcome after the first `seen` ones."""
        if not wait_until(lambda: self.count() > seen, timeout):
            raise BagError(f"no outcome on {self._subscription.topic_name} in {timeout:g} s")
        with self._lock:
            return self.outcomes[seen]


# --------------------------------------------------------------------------------------------
# In-process sessions and the whole replay of one bag
# --------------------------------------------------------------------------------------------


SWITCH_INTERVAL = 1e-4
"""The interpreter's GIL switch interval (s) while a Session is open. Several nodes in one
process hand the GIL around on every timer and message, and at Python's default 5 ms a
thread woken by its timer queues behind the others: measured, world_sim at time scale 20 ran
an 11 s plan in 5.5 s instead of 0.6 s, and a bag player fell 2-3 s behind schedule."""


class Session:
    """An rclpy context (own domain id if given) with a MultiThreadedExecutor spinning in a
    thread and a helper node (`session.node`) for players and clients; the GIL switch interval
    is SWITCH_INTERVAL while it is open. A context manager."""

    def __init__(self, domain_id: int | None = None, name: str = "replay"):
        os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
        self._switch_interval = sys.getswitchinterval()
        sys.setswitchinterval(SWITCH_INTERVAL)
        import rclpy
        from rclpy.context import Context
        from rclpy.executors import MultiThreadedExecutor

        from rearrangement_planner.ros.node import EXECUTOR_THREADS

        self.context = Context()
        if domain_id is None:
            rclpy.init(context=self.context)
        else:
            rclpy.init(context=self.context, domain_id=domain_id)
        self.executor = MultiThreadedExecutor(num_threads=EXECUTOR_THREADS + 2,
                                              context=self.context)
        self.node = rclpy.create_node(name, context=self.context)
        self._nodes = [self.node]
        self._closing = False
        self.failures: list[str] = []
        """The callbacks that failed while the session spun, as 'Type: message' (logged too)."""
        self._pause, self._paused = threading.Event(), threading.Event()
        self.executor.add_node(self.node)
        self._thread = threading.Thread(target=self._spin, daemon=True)
        self._thread.start()

    def _spin(self) -> None:
        """Spin until closed. A callback that fails (e.g. a timer of a node being destroyed,
        whose publisher is already gone) is logged; it must not stop the other nodes."""
        from rclpy.executors import ExternalShutdownException, ShutdownException

        while not self._closing:
            self._paused.clear()
            if self._pause.is_set():            # `remove`: submit nothing while it runs
                self._paused.set()
                time.sleep(0.001)
                continue
            try:
                self.executor.spin_once(timeout_sec=0.1)
            except (ExternalShutdownException, ShutdownException):
                return
            except Exception as exc:  # noqa: BLE001 - keep serving the other nodes
                if not self._closing:
                    self.failures.append(f"{type(exc).__name__}: {exc}")
                    self.node.get_logger().warning(f"a callback failed: {self.failures[-1]}")

    def add(self, node):
        """Spin `node` (created with context=session.context) in this session; returns it."""
        self._nodes.append(node)
        self.executor.add_node(node)
        return node

    @contextlib.contextmanager
    def paused(self) -> Iterator[None]:
        """Inside, the spin thread submits nothing and no callback is running: a node's
        entities can be destroyed (while it spins, a callback running or the executor
        building its wait set met them destroyed: "InvalidHandle: cannot use
        Destroyable")."""
        self._pause.set()
        try:
            self._paused.wait(timeout=5.0)
            running = [task for task in list(getattr(self.executor, "_futures", ()))
                       if not task.done()]
            wait_until(lambda: all(task.done() for task in running), 5.0)
            yield
        finally:
            self._pause.clear()

    def remove(self, node) -> None:
        """Stop spinning `node` and destroy it (`paused`)."""
        with self.paused():
            if node in self._nodes:
                self._nodes.remove(node)
                self.executor.remove_node(node)
            stop = getattr(node, "stop", None)
            if callable(stop):
                stop()
            node.destroy_node()

    def close(self) -> None:
        import rclpy

        for node in list(self._nodes):
            stop = getattr(node, "stop", None)
            if callable(stop):
                stop()
        # Stop spinning before shutting the executor down: a callback still running when the
        # executor drops its guard condition (a done callback creating a task) fails with
        # "'NoneType' object has no attribute 'trigger'" (the likely cause of that message
        # after `make demo`, seen now and then; not reproduced on demand).
        self._closing = True
        self._thread.join(timeout=5.0)
        # Callbacks still running in the executor's threads finish before any node is
        # destroyed (rclpy's MultiThreadedExecutor.shutdown does not wait for them: a long
        # MuJoCo update of world_sim then met its destroyed node, and its task printed "The
        # following exception was never retrieved: cannot use Destroyable ..." at exit).
        running = list(getattr(self.executor, "_futures", ()))
        wait_until(lambda: all(task.done() for task in running), 5.0)
        for task in running:
            if task.done() and task.exception() is not None:
                self.node.get_logger().warning(f"a callback failed: {task.exception()}")
        self.executor.shutdown()
        for node in self._nodes:
            node.destroy_node()
        self._nodes.clear()
        rclpy.try_shutdown(context=self.context)
        sys.setswitchinterval(self._switch_interval)

    def __enter__(self) -> Session:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


@dataclass
class BagRun:
    """What one replay of an input bag produced."""

    bag: Bag
    parameters: dict[str, Any]
    """The planner node parameters used."""
    playback: PlaybackReport
    plan: PlanReply
    outcome: dict[str, Any] | None = None
    """world_sim's outcome of the open-loop execution (with execute=True and a plan); with
    `replan`, of the last execution."""
    outcomes: list[dict[str, Any]] = field(default_factory=list)
    """With `replan`: world_sim's outcome of every execution (plans and retreats)."""
    execute_message: str = ""
    timings: dict[str, float] = field(default_factory=dict)


def run_bag(bag: Bag | str | os.PathLike[str], session: Session, *, rate: float = 1.0,
            namespace: str = "", record_dir: str | os.PathLike[str] | None = None,
            overrides: dict[str, Any] | None = None, execute: bool = False,
            time_scale: float = 10.0, world_overrides: dict[str, Any] | None = None,
            settle: float = SETTLE, replan: int = 0) -> BagRun:
    """Replay one input bag end to end in `session` (module docstring): planner node from the
    bag's `planner_parameters` (plus `overrides`, plus `record_dir`), playback at `rate`,
    `settle` s later `~/plan`; with `execute`, a world_sim on the bag's ground-truth world
    (plus `world_overrides`) executes the plan at `time_scale` and its outcome is returned.
    With `replan` N > 0 the world_sim starts once the bag has played, and the goal executes
    and closes the loop (`replan_attempts` N) in it: the first plan starts from world_sim's
    state (the bag's ground truth), the re-plans from what world_sim shows after each
    execution. Every node lives in `namespace`; all are destroyed before returning."""
    from rclpy.parameter import Parameter

    from rearrangement_planner.ros.node import PlannerNode

    bag = bag if isinstance(bag, Bag) else read_bag(bag)
    info = bag.input_metadata()
    parameters = dict(info["planner_parameters"])
    parameters.update(overrides or {})
    if record_dir is not None:
        parameters["record_dir"] = str(Path(record_dir).resolve())
    ns = namespace.rstrip("/")
    timings: dict[str, float] = {}
    planner = world = None
    workdir = tempfile.TemporaryDirectory(prefix="replay_world_")
    try:
        t0 = time.monotonic()
        planner = session.add(PlannerNode(
            context=session.context, namespace=ns or None,
            parameter_overrides=[Parameter(k, value=v) for k, v in parameters.items()]))
        player = BagPlayer(session.node, bag, rate=rate, namespace=ns)
        client = PlannerClient(session.node, f"{ns}/{NODE_NAME}")
        client.wait_ready()
        missing = player.wait_for_subscribers()
        if missing:
            raise BagError(f"nothing subscribes to {', '.join(missing)}; is the planner node in "
                           f"namespace {ns or '/'}?")
        timings["setup"] = time.monotonic() - t0
        playback = player.play()
        timings["playback"] = playback.wall_time
        # Plan from the bag's last state: wait until the node has taken the last joint state
        # and object poses the player sent (a busy process lags; a message the node rejects
        # or best-effort lost ends the wait at INPUT_WAIT), then the settle time.
        wait_until(lambda: _caught_up(planner, bag), INPUT_WAIT)
        if replan:
            return _closed_loop_run(bag, session, client, planner, parameters, playback, ns,
                                    workdir.name, time_scale, world_overrides, replan, timings)
        time.sleep(settle)
        reply = client.plan(timeout=float(parameters.get("time_limit", 30.0)) + 60.0)
        timings["plan"] = reply.wall_time
        run = BagRun(bag, parameters, playback, reply, timings=timings)
        if not (execute and reply.success):
            return run
        t1 = time.monotonic()
        world = _world_sim(session, info, ns, workdir.name, time_scale, world_overrides)
        listener = OutcomeListener(session.node, f"{ns}/world_sim/outcome")
        seen = listener.count()
        executed = client.execute()
        run.execute_message = executed.message
        if not executed.success:
            raise BagError(f"~/execute failed: {executed.message}")
        duration = reply.trajectory.points[-1].time_from_start.sec + 1
        run.outcome = listener.wait_next(seen, duration / time_scale * 3 + 30.0)
        timings["execute"] = time.monotonic() - t1
        return run
    finally:
        for node in (world, planner):
            if node is not None:
                session.remove(node)
        workdir.cleanup()


def _world_sim(session: Session, info: dict, ns: str, folder: str, time_scale: float,
               overrides: dict[str, Any] | None) -> Any:
    """A world_sim on the bag's ground-truth world in `ns`, connected to the planner."""
    from rclpy.parameter import Parameter

    from rearrangement_planner.ros.sim.world_sim import WorldSim

    world_file = Path(folder) / "world.yaml"
    world_file.write_text(yaml.safe_dump(info["world"], sort_keys=False))
    settings = {"scene": str(world_file), "time_scale": float(time_scale)}
    settings.update(overrides or {})
    world = session.add(WorldSim(
        context=session.context, namespace=ns or None,
        parameter_overrides=[Parameter(k, value=v) for k, v in settings.items()]))
    if not wait_until(lambda: world.command_publisher_count() > 0, 10.0):
        session.remove(world)
        raise BagError(f"world_sim does not see the planner's {ns}/joint_trajectory")
    return world


def _closed_loop_run(bag: Bag, session: Session, client: PlannerClient, planner: Any,
                     parameters: dict[str, Any], playback: PlaybackReport, ns: str,
                     folder: str, time_scale: float, overrides: dict[str, Any] | None,
                     replan: int, timings: dict[str, float]) -> BagRun:
    """`run_bag` with `replan` (its docstring): world_sim, then one goal that executes and
    re-plans up to `replan` times; world_sim's outcomes of every execution."""
    from rearrangement_interfaces.action import PlanRearrangement

    world = _world_sim(session, bag.input_metadata(), ns, folder, time_scale, overrides)
    try:
        listener = OutcomeListener(session.node, f"{ns}/world_sim/outcome")
        time.sleep(SETTLE)              # world_sim's state replaces the bag's last one
        seen = listener.count()
        budget = float(parameters.get("time_limit", 30.0)) + 60.0
        reply = client.plan(PlanRearrangement.Goal(execute=True, replan_attempts=replan),
                            timeout=(replan + 1) * budget)
        timings["plan"] = reply.wall_time
        wait_until(lambda: listener.count() > seen, 10.0)
        time.sleep(1.0)                 # the last execution's outcome follows the answer
        outcomes = listener.outcomes[seen:]
        return BagRun(bag, parameters, playback, reply, outcomes[-1] if outcomes else None,
                      timings=timings, outcomes=outcomes)
    finally:
        session.remove(world)


# --------------------------------------------------------------------------------------------
# Command line
# --------------------------------------------------------------------------------------------


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="python -m rearrangement_planner.ros.sim.replay",
        description="Play an input bag into planner_node (like `ros2 bag play`), call ~/plan "
                    "and print its summary; optionally start the node in-process and execute "
                    "the plan open loop in world_sim.")
    parser.add_argument("bag", help="bag file, or the name of a shipped bag (bags/<name>.mcap)")
    parser.add_argument("--rate", type=float, default=1.0,
                        help="playback rate factor, like ros2 bag play --rate (default 1)")
    parser.add_argument("--namespace", default="",
                        help="prefix of every topic and of the nodes (default: none)")
    parser.add_argument("--play-only", action="store_true",
                        help="only play the bag (no ~/plan)")
    parser.add_argument("--start-node", action="store_true",
                        help="run planner_node in this process, with the bag's planner "
                             "parameters (scene, seed, time limit, goal radius); otherwise "
                             "a running planner_node is used as it is configured")
    parser.add_argument("--execute", action="store_true",
                        help="with --start-node: execute the plan open loop in an in-process "
                             "world_sim on the bag's ground truth and print its outcome")
    parser.add_argument("--time-scale", type=float, default=10.0,
                        help="world_sim time scale for --execute (default 10)")
    parser.add_argument("--record-dir", type=Path, default=None,
                        help="with --start-node: folder of the plan's MCAP (default: the "
                             "node's record_dir)")
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        if not args.rate > 0 or not args.time_scale > 0:
            raise BagError("--rate and --time-scale must be positive")
        if args.execute and not args.start_node:
            raise BagError("--execute needs --start-node (world_sim and planner_node run in "
                           "this process)")
        bag = read_bag(args.bag)
    except BagError as exc:
        print(f"replay: {exc}", file=sys.stderr)
        return 2
    print(f"{bag.path}: {bag.duration:.2f} s, "
          + ", ".join(f"{t.name} ({t.count})" for t in bag.topics.values()), flush=True)
    with Session() as session:
        try:
            if args.start_node:
                run = run_bag(bag, session, rate=args.rate, namespace=args.namespace,
                              record_dir=args.record_dir, execute=args.execute,
                              time_scale=args.time_scale)
                print(run.plan.message)
                if run.outcome is not None:
                    print(run.outcome["message"])
                    return 0 if run.outcome["status"] == "SUCCEEDED" else 1
                return 0 if run.plan.success else 1
            player = BagPlayer(session.node, bag, rate=args.rate, namespace=args.namespace)
            missing = player.wait_for_subscribers(timeout=5.0)
            if missing:
                print(f"replay: no subscriber yet on {', '.join(missing)}", file=sys.stderr)
            report = player.play()
            print(f"played {sum(report.published.values())} messages in "
                  f"{report.wall_time:.2f} s")
            if args.play_only:
                return 0
            time.sleep(SETTLE)
            reply = PlannerClient(session.node, f"{args.namespace.rstrip('/')}/{NODE_NAME}"
                                  ).plan()
            print(reply.message)
            return 0 if reply.success else 1
        except (BagError, ClientError) as exc:
            print(f"replay: {exc}", file=sys.stderr)
            return 1


if __name__ == "__main__":
    sys.exit(main())
