"""planner_node refuses a bad scene at start with its one `[FATAL] cannot start: ...` line and a
non-zero exit, never a traceback."""

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
