"""How much CPU planner_node takes while it waits for a goal, at a robot's input rates: a
benchmark command, not a test (docs/benchmark.md, "The node at a robot's rates").

    .venv/bin/python test/ros/idle_cpu.py [--rates 1 100 1000] [--seconds 20]

For each joint_states rate it starts planner_node (easy_push) in a process of its own, on a
ROS domain of its own and localhost discovery, publishes joint_states at that rate and the
object poses at 30 Hz from this process, waits for the node to log that it is ready (its
compiled core loaded), and reads the node process's CPU time (user + system, /proc/PID/stat)
over `--seconds`: the share of one core.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np

DOMAIN_ID = 87
ROOT = Path(__file__).resolve().parents[2]


def cpu_seconds(pid: int) -> float:
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")   # utime + stime


def measure(rate: float, seconds: float) -> dict[str, float]:
    import rclpy
    from geometry_msgs.msg import PoseArray
    from rclpy.context import Context
    from sensor_msgs.msg import JointState

    from msg_adapters import objects_to_pose_array
    from rearrangement_planner.physics.validation import load_scene

    scene = load_scene("easy_push")
    env = {**os.environ, "ROS_DOMAIN_ID": str(DOMAIN_ID),
           "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST"}
    node = subprocess.Popen([str(Path(sys.executable).parent / "planner_node"), "--ros-args",
                             "-p", "scene:=easy_push", "-p", "record:=false"], env=env,
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    ready = threading.Event()

    def read_log() -> None:          # the node logs "ready: ... call ~/plan" once warmed up
        for line in node.stderr:
            if "ready: scene" in line and "call " in line:
                ready.set()

    threading.Thread(target=read_log, daemon=True).start()
    context = Context()
    rclpy.init(context=context, domain_id=DOMAIN_ID)
    try:
        pub = rclpy.create_node("idle_cpu_inputs", context=context)
        joints = pub.create_publisher(JointState, "/joint_states", 10)
        objects = pub.create_publisher(PoseArray, "/rearrangement_planner/object_poses", 10)
        state = JointState(name=list(scene.robot.joint_names),
                           position=[float(v) for v in scene.start_configuration])
        poses = objects_to_pose_array(scene.object_poses, "world")
        if not ready.wait(600.0):           # loading (or compiling) its core is not waiting
            raise RuntimeError("planner_node did not log that it is ready within 600 s")
        time.sleep(3.0)
        start_cpu, start, sent = cpu_seconds(node.pid), time.monotonic(), 0
        next_joint = next_objects = start
        while (now := time.monotonic()) < start + seconds:
            if now >= next_joint:
                state.header.stamp = pub.get_clock().now().to_msg()
                joints.publish(state)
                sent += 1
                next_joint += 1.0 / rate
            if now >= next_objects:
                objects.publish(poses)
                next_objects += 1.0 / 30.0
            time.sleep(max(0.0, min(next_joint, next_objects) - time.monotonic()))
        elapsed = time.monotonic() - start
        used = cpu_seconds(node.pid) - start_cpu
        pub.destroy_node()
    finally:
        rclpy.try_shutdown(context=context)
        node.terminate()
        node.wait(20.0)
    return {"rate_hz": rate, "sent_hz": round(sent / elapsed, 1),
            "cpu_share_of_a_core": round(used / elapsed, 3)}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--rates", type=float, nargs="+", default=[1.0, 100.0, 1000.0])
    parser.add_argument("--seconds", type=float, default=20.0)
    args = parser.parse_args()
    for rate in args.rates:
        print(measure(rate, args.seconds), flush=True)
    return 0


if __name__ == "__main__":
    np.set_printoptions(precision=3)
    sys.exit(main())
