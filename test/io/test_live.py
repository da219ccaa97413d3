"""The live view (`io/live.py`) for real: a WebSocket client speaks Foxglove's protocol to the
server, subscribes, and decodes the scene and the search with the schemas the server
advertises; a recording carries the same SceneUpdates, read back with the `mcap` reader."""

from __future__ import annotations

import asyncio
import base64
import json
import struct

import numpy as np
import pytest
import websockets
from google.protobuf import descriptor_pb2, descriptor_pool, message_factory

from rearrangement_planner.io.live import LiveView, LiveViewError
from rearrangement_planner.physics.validation import load_scene
from rearrangement_planner.planning.machinery.interface import Progress


def decoder(schema_name: str, schema: bytes):
    """The protobuf class of `schema_name` from a FileDescriptorSet."""
    pool = descriptor_pool.DescriptorPool()
    for file in descriptor_pb2.FileDescriptorSet.FromString(schema).file:
        pool.Add(file)
    return message_factory.GetMessageClass(pool.FindMessageTypeByName(schema_name))


async def watch(url: str, topics: list[str], count, act=None) -> dict[str, list]:
    """Connect to `url`, subscribe to `topics`, call `act()` once subscribed, and return the
    messages received, decoded, by topic: the first `count`, or (`count` a function of them)
    until `count(received)` is true."""
    async with websockets.connect(url, subprotocols=["foxglove.sdk.v1"]) as ws:
        channels = {}
        while not set(topics) <= set(channels):
            message = json.loads(await asyncio.wait_for(ws.recv(), 10.0))
            if message.get("op") == "advertise":
                for channel in message["channels"]:
                    channels[channel["topic"]] = channel
        subscriptions = {i: channels[topic] for i, topic in enumerate(topics, start=1)}
        await ws.send(json.dumps({"op": "subscribe", "subscriptions": [
            {"id": i, "channelId": c["id"]} for i, c in subscriptions.items()]}))
        await asyncio.sleep(0.3)
        if act is not None:
            act()
        received: dict[str, list] = {topic: [] for topic in topics}
        done = count if callable(count) else (
            lambda got: sum(map(len, got.values())) >= count)
        while not done(received):
            data = await asyncio.wait_for(ws.recv(), 30.0)
            if isinstance(data, str) or data[0] != 1:        # 1: message data
                continue
            subscription, _ = struct.unpack_from("<IQ", data, 1)
            channel = subscriptions[subscription]
            cls = decoder(channel["schemaName"], base64.b64decode(channel["schema"]))
            received[channel["topic"]].append(cls.FromString(data[13:]))
        return received


@pytest.fixture(scope="module")
def easy(panda):
    return load_scene("easy_push", robot=panda)


def test_a_client_sees_the_scene_and_the_search(easy):
    live = LiveView(port=0)
    try:
        live.scene(easy)          # before anyone connects: replayed to the subscriber
        asked = []

        def tree():
            asked.append(True)
            return np.array([[0.45, 0.1], [0.5, 0.05], [0.58, -0.02]])

        def search():
            live.search(easy, Progress(120, 118, 0.08, 0.5, tree))

        received = asyncio.run(watch(live.url, ["/scene", "/search"], 2, search))
    finally:
        live.close()
    (scene,) = received["/scene"]
    ids = {e.id for e in scene.entities}
    assert {"table", "goal", "arm", "object/target"} <= ids
    target = next(e for e in scene.entities if e.id == "object/target")
    assert target.cubes[0].pose.position.x == pytest.approx(easy.object_poses[0, 0])
    (search,) = received["/search"]
    assert search.entities[0].texts[0].text == "120 iterations"
    assert len(search.entities[0].spheres) == 4                 # 3 nodes and the best
    assert asked == [True]


def test_nothing_is_built_while_nobody_watches(easy):
    live = LiveView(port=0)
    try:
        def tree():
            raise AssertionError("the tree was copied for nobody")

        live.search(easy, Progress(1, 1, 0.1, 0.1, tree))
        assert not live.watched("search")
    finally:
        live.close()


def test_a_taken_port_is_a_clear_error(easy):
    live = LiveView(port=0)
    try:
        with pytest.raises(LiveViewError, match=f"cannot serve on 127.0.0.1:{live.port}"):
            LiveView(port=live.port)
    finally:
        live.close()


def test_a_recording_carries_the_scene_and_the_paths_as_scene_updates(easy, tmp_path):
    """Recorded as foxglove_msgs/msg/SceneUpdate (ros2msg, CDR) like every other topic: the
    mcap reader with the ROS 2 decoder reads the whole file, the 3D scene included."""
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory

    from rearrangement_planner.io.plan_record import record_plan
    from rearrangement_planner.planning import PCRRTOptions, PlanRequest, plan_scene

    output = plan_scene(PlanRequest.first_plan(easy, "pc-rrt", PCRRTOptions(time_limit=30),
                                               seed=1))
    path = record_plan(tmp_path / "plan.mcap", output, plan_id="p", parameters={},
                       planning_frame="world")
    updates: dict[str, list] = {}
    with open(path, "rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        for schema, channel, _, decoded in reader.iter_decoded_messages():
            if schema.name == "foxglove_msgs/msg/SceneUpdate":
                assert schema.encoding == "ros2msg" and channel.message_encoding == "cdr"
                updates.setdefault(channel.topic, []).append(decoded)
    scene = updates["/rearrangement_planner/scene_3d"][0]
    assert {"table", "goal", "arm", "object/target"} <= {e.id for e in scene.entities}
    plan = updates["/rearrangement_planner/plan_3d"][0]
    assert {e.id for e in plan.entities} == {"plan/path/target", "plan/tool"}
    motion = updates["/rearrangement_planner/motion_3d"]
    assert len(motion) >= output.trajectory.duration / 1.0       # a frame every 0.5-1 s
    last = next(e for e in motion[-1].entities if e.id == "object/target")
    assert last.cubes[0].pose.position.x == pytest.approx(
        output.trajectory_states[-1].objects[0, 0])


def test_the_shipped_layout_shows_the_live_view_and_the_recordings_3d_topics():
    from rearrangement_planner.io.live import TOPICS
    from rearrangement_planner.io.plan_record import TOPICS as RECORDED
    from rearrangement_planner.model.resources import config_dir

    layout = json.loads((config_dir() / "foxglove_layout.json").read_text())
    shown = layout["configById"]["3D!planner"]["topics"]
    assert {f"/{t}" for t in TOPICS} <= set(shown)
    assert {RECORDED[k] for k in ("scene_3d", "plan_3d", "motion_3d")} <= set(shown)
    assert layout["configById"]["RosOut!log"]["topicToRender"] == "/log"
