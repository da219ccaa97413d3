"""planner_node refuses a bad scene at start with its one `[FATAL] cannot start: ...` line and a
non-zero exit, never a traceback; Ctrl-C mid-plan is quiet; the race's workers start with the
node."""

import os
import subprocess
import sys

import pytest

from rearrangement_planner.model.resources import scenes_dir

EASY = (scenes_dir() / "easy_push.yaml").read_bytes()


@pytest.mark.parametrize(("content", "expected"), [
    (EASY.replace(b"height: 0.0", b"height: 1" + b"0" * 400, 1),
     "table.height: must be a finite number (m), got an integer of 401 digits"),
    (b"robot: panda\n# caf\xe9\n", "is not UTF-8 text"),
    (b"robot: " + b"[" * 1000 + b"]" * 1000 + b"\n", "nests collections more than 20 deep"),
])
def test_a_bad_scene_stops_the_node_with_one_fatal_line(tmp_path, content, expected):
    scene = tmp_path / "bad.yaml"
    scene.write_bytes(content)
    env = {**os.environ, "ROS_DOMAIN_ID": str(190 + os.getpid() % 20),
           "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST"}
    run = subprocess.run([sys.executable, "-m", "rearrangement_planner.ros.node",
                          "--ros-args", "-p", f"scene:={scene}"],
                         capture_output=True, text=True, timeout=60, env=env)
    fatal = [line for line in run.stderr.splitlines() if "[FATAL]" in line]
    assert run.returncode == 1 and "Traceback" not in run.stderr, run.stderr
    assert len(fatal) == 1 and "cannot start:" in fatal[0] and expected in fatal[0], run.stderr


def test_ctrl_c_while_a_goal_plans_is_quiet(tmp_path):
    """SIGINT mid-plan cancels the plan, answers the goal PREEMPTED, joins the worker and exits
    0, with no traceback (the worker used to publish on a context that the signal had already
    shut down)."""
    import signal
    import threading
    import time

    import rclpy
    from geometry_msgs.msg import PoseArray
    from rclpy.context import Context
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.node import Node
    from sensor_msgs.msg import JointState

    from msg_adapters import configuration_to_joint_state, objects_to_pose_array
    from rearrangement_interfaces.action import PlanRearrangement
    from rearrangement_interfaces.msg import ErrorCode
    from rearrangement_planner.physics.validation import load_scene
    from rearrangement_planner.ros.client import action_client
    from rearrangement_planner.ros.sim.replay import wait_until

    domain = 210 + os.getpid() % 20
    env = {**os.environ, "ROS_DOMAIN_ID": str(domain),
           "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST"}
    node = subprocess.Popen([sys.executable, "-m", "rearrangement_planner.ros.node",
                             "--ros-args", "-p", "scene:=easy_push", "-p", "state_timeout:=5.0",
                             "-p", "record:=false"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env,
                            # Ctrl-C in a terminal: a suite run as a shell's background job
                            # starts with SIGINT ignored, and a child would inherit that
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    context = Context()
    rclpy.init(context=context, domain_id=domain)
    client = Node("ctrl_c_client", context=context)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(client)
    scene = load_scene("easy_push")
    joints = client.create_publisher(JointState, "/joint_states", 10)
    objects = client.create_publisher(PoseArray, "/rearrangement_planner/object_poses", 10)
    joint_msg = configuration_to_joint_state(scene.start_configuration, scene.robot.joint_names)
    objects_msg = objects_to_pose_array(scene.object_poses, "world")
    client.create_timer(0.05, lambda: (joints.publish(joint_msg), objects.publish(objects_msg)))
    action = action_client(client, PlanRearrangement, "/rearrangement_planner/plan_rearrangement")
    spinner = threading.Thread(target=executor.spin, daemon=True)
    spinner.start()
    try:
        assert action.wait_for_server(timeout_sec=120.0), "the node did not come up"
        time.sleep(0.5)
        goal = PlanRearrangement.Goal(use_goal_point=True, goal_radius=0.01, time_limit=60.0,
                                      settings=["goal_margin=0.0"])
        goal.goal_point.x, goal.goal_point.y = 0.93, 0.58
        feedback: list = []
        sent = action.send_goal_async(goal, feedback_callback=lambda m: feedback.append(
            m.feedback))
        assert wait_until(sent.done, 10.0) and sent.result().accepted
        assert wait_until(lambda: any(f.iterations > 0 for f in feedback), 30.0)
        result = sent.result().get_result_async()
        node.send_signal(signal.SIGINT)
        _, stderr = node.communicate(timeout=60)
        # the goal the shutdown cancelled got its result: PREEMPTED, as ErrorCode.msg says
        assert wait_until(result.done, 10.0), "no result for the goal the shutdown cancelled"
        assert result.result().result.error_code.val == ErrorCode.PREEMPTED
    finally:
        if node.poll() is None:
            node.kill()
        executor.shutdown()
        client.destroy_node()
        rclpy.shutdown(context=context)
        spinner.join(timeout=5.0)
    assert node.returncode == 0, stderr
    assert "Traceback" not in stderr and "Exception in thread" not in stderr, stderr


def test_the_node_starts_its_race_workers_with_it():
    """At start the node starts the worker processes its `trees` need (here 3 trees: 2
    workers), without waiting for them: it serves at once, and the first plan's warm-up waits
    for what is left of their start. Run as its own process, as a user starts it."""
    import time

    env = {**os.environ, "ROS_DOMAIN_ID": str(230 + os.getpid() % 3),   # 232 is the last
           "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST"}
    node = subprocess.Popen([sys.executable, "-m", "rearrangement_planner.ros.node",
                             "--ros-args", "-p", "scene:=easy_push", "-p", "record:=false",
                             "-p", "trees:=3"],
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, env=env)

    def tree_workers() -> int:
        """The node's child processes that multiprocessing spawned (/proc: their parent)."""
        count = 0
        for entry in os.listdir("/proc"):
            if not entry.isdigit():
                continue
            try:
                with open(f"/proc/{entry}/stat") as stat:
                    parent = int(stat.read().rsplit(")", 1)[1].split()[1])
                with open(f"/proc/{entry}/cmdline", "rb") as cmdline:
                    spawned = b"spawn_main" in cmdline.read()
            except (FileNotFoundError, ProcessLookupError, IndexError, ValueError):
                continue
            count += parent == node.pid and spawned
        return count

    try:
        deadline = time.monotonic() + 120.0
        while tree_workers() < 2 and time.monotonic() < deadline and node.poll() is None:
            time.sleep(0.2)
        assert tree_workers() == 2
    finally:
        node.kill()
        node.wait(30)
