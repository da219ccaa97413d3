"""planner_node instances of their own, over real DDS: the live view (with live_view_port the
node serves the scene at once, and a ~/plan call's answer and summary reach a Foxglove client
over a real WebSocket), and the action server letting finished goals go (RESULT_TIMEOUT)."""

from __future__ import annotations

import asyncio
import os
import socket
import sys
import threading
from pathlib import Path

os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
DOMAIN_ID = 150 + os.getpid() % 20

import pytest  # noqa: E402
import rclpy  # noqa: E402
from geometry_msgs.msg import PoseArray  # noqa: E402
from rclpy.context import Context  # noqa: E402
from rclpy.executors import MultiThreadedExecutor, SingleThreadedExecutor  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402
from sensor_msgs.msg import JointState  # noqa: E402
from std_srvs.srv import Trigger  # noqa: E402

from msg_adapters import configuration_to_joint_state, objects_to_pose_array  # noqa: E402
from rearrangement_planner.physics.validation import load_scene  # noqa: E402
from rearrangement_planner.ros.node import PlannerNode  # noqa: E402
from rearrangement_planner.ros.sim.replay import wait_until  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "io"))
from test_live import watch  # noqa: E402


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.fixture
def node_with_live_view(tmp_path):
    context = Context()
    rclpy.init(context=context, domain_id=DOMAIN_ID)
    port = free_port()
    planner = PlannerNode(context=context, parameter_overrides=[
        Parameter("scene", value="easy_push"), Parameter("seed", value=1),
        Parameter("live_view_port", value=port), Parameter("record", value=False),
        Parameter("judge_worlds", value=2), Parameter("both_planners", value=False)])
    executor = MultiThreadedExecutor(num_threads=4, context=context)
    executor.add_node(planner)
    client = rclpy.create_node("live_view_client", context=context)
    client_executor = SingleThreadedExecutor(context=context)
    client_executor.add_node(client)
    scene = load_scene("easy_push")
    joints = client.create_publisher(JointState, "/joint_states", 10)
    objects = client.create_publisher(PoseArray, "/rearrangement_planner/object_poses", 10)
    joint_msg = configuration_to_joint_state(scene.start_configuration, scene.robot.joint_names)
    objects_msg = objects_to_pose_array(scene.object_poses, "world")
    client.create_timer(0.05, lambda: (joints.publish(joint_msg), objects.publish(objects_msg)))
    threads = [threading.Thread(target=e.spin, daemon=True) for e in (executor, client_executor)]
    for thread in threads:
        thread.start()
    try:
        yield planner, client, port
    finally:
        executor.shutdown()
        client_executor.shutdown()
        planner.destroy_node()
        client.destroy_node()
        rclpy.shutdown(context=context)


def test_the_node_serves_the_scene_and_each_answer(node_with_live_view):
    planner, client, port = node_with_live_view
    plan = client.create_client(Trigger, "/rearrangement_planner/plan")
    assert plan.wait_for_service(timeout_sec=10.0)
    answers: list = []

    def call_plan():
        def run():
            future = plan.call_async(Trigger.Request())
            assert wait_until(future.done, 60.0)
            answers.append(future.result())
        threading.Thread(target=run, daemon=True).start()

    def answered(got) -> bool:          # the answer's paths, and its summary in the log
        return (any(update.entities for update in got["/plan"])
                and any("SUCCEEDED" in log.message for log in got["/log"]))

    received = asyncio.run(watch(f"ws://127.0.0.1:{port}", ["/scene", "/plan", "/log"],
                                 answered, call_plan))
    assert wait_until(lambda: answers, 30.0) and answers[0].success, answers
    ids = {e.id for update in received["/scene"] for e in update.entities}
    assert {"table", "goal", "arm", "object/target"} <= ids
    plan_ids = {e.id for update in received["/plan"] for e in update.entities}
    assert {"plan/path/target", "plan/tool", "plan/end/target"} <= plan_ids
    assert any(log.message.startswith("plan: SUCCEEDED") for log in received["/log"])


def test_a_finished_goal_is_let_go_after_the_result_timeout(monkeypatch, tmp_path):
    """A finished goal and its result stay RESULT_TIMEOUT s for a client to fetch (rclpy's
    900 s kept every goal a quarter of an hour); here 1 s."""
    from rearrangement_interfaces.action import PlanRearrangement
    from rearrangement_planner.ros import action
    from rearrangement_planner.ros.client import action_client

    monkeypatch.setattr(action, "RESULT_TIMEOUT", 1)
    context = Context()
    rclpy.init(context=context, domain_id=DOMAIN_ID)
    planner = PlannerNode(context=context, parameter_overrides=[
        Parameter("scene", value="easy_push"), Parameter("record", value=False)])
    client = rclpy.create_node("timeout_client", context=context)
    executors = [MultiThreadedExecutor(num_threads=4, context=context),
                 SingleThreadedExecutor(context=context)]
    executors[0].add_node(planner)
    executors[1].add_node(client)
    threads = [threading.Thread(target=e.spin, daemon=True) for e in executors]
    for thread in threads:
        thread.start()
    try:
        goals = action_client(client, PlanRearrangement,
                              "/rearrangement_planner/plan_rearrangement")
        assert goals.wait_for_server(timeout_sec=10.0)
        sent = goals.send_goal_async(PlanRearrangement.Goal(goal_object="nope"))
        assert wait_until(sent.done, 10.0) and sent.result().accepted
        result = sent.result().get_result_async()
        assert wait_until(result.done, 20.0)
        server = planner._plan_action._server
        assert wait_until(lambda: not server._goal_handles, 10.0), "the goal was kept"
    finally:
        for executor in executors:
            executor.shutdown()
        planner.destroy_node()
        client.destroy_node()
        rclpy.shutdown(context=context)
