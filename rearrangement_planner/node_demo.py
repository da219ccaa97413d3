"""`python -m rearrangement_planner.node_demo`: the planner node end to end, in one process.

Starts `planner_node` on a scene (its own executor thread), publishes the scene's start joint
state and object poses as a robot and a perception system would (10 Hz) and the scene's goal
on `~/goal`, calls `~/plan`, prints the one-line summary and where the MCAP went, and draws the
plan it received on `~/trajectory` (replayed through the physics for the object paths) as a top
view PNG. Exit code 0 when the plan succeeded, 1 otherwise, 2 for bad arguments.

ROS_DOMAIN_ID is taken from the environment; discovery defaults to this machine
(ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST) unless set.
"""

from __future__ import annotations

import argparse
import os
import sys
import threading
import time
from pathlib import Path

import numpy as np


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="python -m rearrangement_planner.node_demo",
        description="Run planner_node in-process on a scene: publish the scene's start state "
                    "and goal, call ~/plan, print the summary and draw the plan.")
    parser.add_argument("--scene", default="default",
                        help="shipped scene name or scene YAML path (default: default)")
    parser.add_argument("--seed", type=int, default=0, help="planner seed (default 0)")
    parser.add_argument("--time-limit", type=float, default=60.0, metavar="S",
                        help="planning budget in seconds (default 60)")
    parser.add_argument("--record-dir", type=Path, default=Path("out"),
                        help="folder for the MCAP recording (default: out/)")
    parser.add_argument("--plot", type=Path, default=None, metavar="OUT.png",
                        help="top view PNG of the plan (default: out/<scene>.png)")
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    # rclpy and the message packages only once the environment is set.
    import rclpy
    from rclpy.context import Context
    from rclpy.executors import MultiThreadedExecutor
    from rclpy.node import Node
    from rclpy.parameter import Parameter

    from .errors import RearrangementError
    from .node import EXECUTOR_THREADS, PlannerNode
    from .scene import load_scene

    try:
        if not args.time_limit > 0:
            raise RearrangementError(f"--time-limit must be positive, got {args.time_limit}")
        scene = load_scene(args.scene)
        args.record_dir.mkdir(parents=True, exist_ok=True)
    except (RearrangementError, OSError) as exc:
        print(f"node_demo: {exc}", file=sys.stderr)
        return 2
    plot_path = args.plot or args.record_dir / f"{Path(scene.source).stem}.png"

    context = Context()
    rclpy.init(context=context)
    executor = MultiThreadedExecutor(num_threads=EXECUTOR_THREADS, context=context)
    planner = demo = spinner = None
    try:
        planner = PlannerNode(context=context, parameter_overrides=[
            Parameter("scene", value=args.scene), Parameter("seed", value=args.seed),
            Parameter("time_limit", value=float(args.time_limit)),
            Parameter("record_dir", value=str(args.record_dir.resolve()))])
        demo = Node("planner_demo", context=context)
        executor.add_node(planner)
        executor.add_node(demo)
        spinner = threading.Thread(target=executor.spin, daemon=True)
        spinner.start()
        return _run(demo, planner, scene, args, plot_path)
    except RearrangementError as exc:
        print(f"node_demo: {exc}", file=sys.stderr)
        return 2
    finally:
        if planner is not None:
            planner.stop()
        executor.shutdown()
        if spinner is not None:
            spinner.join(timeout=5.0)
        for node in (planner, demo):
            if node is not None:
                node.destroy_node()
        rclpy.try_shutdown(context=context)


def _run(demo, planner, scene, args, plot_path: Path) -> int:
    from geometry_msgs.msg import PoseArray, PoseStamped
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
    from sensor_msgs.msg import JointState
    from std_srvs.srv import Trigger
    from trajectory_msgs.msg import JointTrajectory

    from msg_adapters import (
        configuration_to_joint_state,
        goal_to_pose_stamped,
        objects_to_pose_array,
    )

    frame = planner.get_parameter("planning_frame").value or scene.robot.config.base_frame
    joint_state = configuration_to_joint_state(scene.start_configuration, scene.robot.joint_names)
    objects = objects_to_pose_array(scene.object_poses, frame)
    joint_pub = demo.create_publisher(JointState, planner.resolve_topic_name("joint_states"), 10)
    objects_pub = demo.create_publisher(PoseArray, planner.resolve_topic_name("~/object_poses"),
                                        10)
    goal_pub = demo.create_publisher(PoseStamped, planner.resolve_topic_name("~/goal"), 10)
    demo.create_timer(0.1, lambda: (joint_pub.publish(joint_state), objects_pub.publish(objects)))
    received: list[JointTrajectory] = []
    demo.create_subscription(
        JointTrajectory, planner.resolve_topic_name("~/trajectory"), received.append,
        QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                   durability=DurabilityPolicy.TRANSIENT_LOCAL))
    plan = demo.create_client(Trigger, planner.resolve_service_name("~/plan"))

    if not (_wait(lambda: goal_pub.get_subscription_count() > 0, 10.0)
            and plan.wait_for_service(timeout_sec=10.0)):
        print("node_demo: the planner node's topics/services did not come up", file=sys.stderr)
        return 1
    goal_pub.publish(goal_to_pose_stamped(scene.goal.position, frame))
    time.sleep(0.5)   # a few rounds of joint state and object poses
    print(f"planning {scene.source} (seed {args.seed}, time limit {args.time_limit:g} s) ...",
          flush=True)
    future = plan.call_async(Trigger.Request())
    if not _wait(future.done, args.time_limit + 120.0):
        print("node_demo: ~/plan did not answer", file=sys.stderr)
        return 1
    response = future.result()
    print(response.message)
    mcap = response.message.split(", mcap ", 1)[-1].split("; ")[0]
    print(f"recording: {mcap}")
    if response.success:
        _wait(lambda: bool(received), 5.0)
    plan_id, _, rest = response.message.partition(": ")
    title = f"{Path(scene.source).stem}: {plan_id} of planner_node, {rest.split(' ')[0]}"
    _plot(scene, received[-1] if response.success and received else None, plot_path, title)
    print(f"top view: {plot_path}")
    return 0 if response.success else 1


def _plot(scene, msg, out_path: Path, title: str) -> None:
    """Top view of the plan in `msg` (replayed from the scene's start through the physics for
    the object paths), or of the start alone when there is none."""
    from msg_adapters import msg_to_trajectory

    from .physics import Physics
    from .plot import plot_top_view
    from .propagation import replay

    start = scene.initial_state()
    if msg is None:
        plot_top_view(scene, start.objects[None], np.zeros((0, 2)), out_path, title=title,
                      start_states_only=True)
        return
    positions = msg_to_trajectory(msg).positions
    states, problem = replay(Physics(scene), start, positions)
    if problem:
        print(f"warning: the trajectory replays only to point {len(states) - 1}: {problem}",
              file=sys.stderr)
    ee = np.array([scene.robot.tool_pose(q)[:2, 3] for q in positions])
    plot_top_view(scene, np.array([s.objects for s in states]), ee, out_path, title=title)


def _wait(predicate, timeout: float) -> bool:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if predicate():
            return True
        time.sleep(0.02)
    return bool(predicate())


if __name__ == "__main__":
    sys.exit(main())
