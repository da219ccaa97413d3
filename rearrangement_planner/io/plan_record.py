"""The MCAP recording of one plan (docs/design.md): its inputs, trajectory, predicted object poses
and markers as the ROS messages the node exchanges, plus a metadata record.

    record_plan("plans/p1.mcap", output, plan_id="p1", parameters={...}, planning_frame="world")

The messages are built as plain data (`io.messages`), so recording needs no ROS install (the
CLI's `--record`); the node passes the messages it received as inputs (rclpy objects or plain
dicts are both encoded).

Topics (log time = `start_time_ns`, default now, unless stated; N = /rearrangement_planner):
  /joint_states                sensor_msgs/msg/JointState          the start arm state
  N/object_poses               geometry_msgs/msg/PoseArray         the start object poses
  N/goal                       geometry_msgs/msg/PoseStamped       the goal point
  N/markers                    visualization_msgs/msg/MarkerArray  scene (+ plan paths)
and when solved
  N/trajectory                 trajectory_msgs/msg/JointTrajectory
  N/predicted_object_poses     geometry_msgs/msg/PoseArray, one per trajectory point, logged and
                               stamped at start + time_from_start.
Metadata record "rearrangement_plan": plan_id, planner, seed, outcome, message, fragile
("true" for a fragile plan: `PlanOutput.fragile`), parameters
(JSON), scene (YAML of the scene file format), statistics (JSON result of docs/design.md without
the trajectory).
"""

from __future__ import annotations

import json
import math
import os
import time
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import yaml
from foxglove import messages as fg

from rearrangement_planner.io import foxglove_ros2, messages, scene3d
from rearrangement_planner.io.foxglove_ros2 import SCENE_UPDATE
from rearrangement_planner.io.recording import McapRecorder, RecordingError, define
from rearrangement_planner.model.errors import RearrangementError
from rearrangement_planner.model.resources import NODE_NAME
from rearrangement_planner.model.scene import Scene
from rearrangement_planner.planning.requests.pipeline import PlanOutput

NODE_NAMESPACE = f"/{NODE_NAME}"
"""The planner node's namespace: its topics are recorded under it."""
METADATA_NAME = "rearrangement_plan"
TOPICS = {
    "joint_state": "/joint_states",
    "object_poses": f"{NODE_NAMESPACE}/object_poses",
    "goal": f"{NODE_NAMESPACE}/goal",
    "trajectory": f"{NODE_NAMESPACE}/trajectory",
    "predicted_object_poses": f"{NODE_NAMESPACE}/predicted_object_poses",
    "markers": f"{NODE_NAMESPACE}/markers",
    "scene_3d": f"{NODE_NAMESPACE}/scene_3d",
    "plan_3d": f"{NODE_NAMESPACE}/plan_3d",
    "motion_3d": f"{NODE_NAMESPACE}/motion_3d",
}
MOTION_PERIOD = 0.5
"""s of trajectory between two recorded frames of the plan's motion (the arm and objects)."""


def record_plan(path: str | os.PathLike[str], output: PlanOutput, *, plan_id: str,
                parameters: Mapping[str, Any], planning_frame: str,
                joint_state: Any = None, object_poses: Any = None, goal: Any = None,
                start_time_ns: int | None = None, extra: Sequence[tuple] = ()) -> Path:
    """Record `output` to the MCAP file `path` and return its path.

    The inputs default to the plan's start state (its first state, or the scene's initial
    state for a plan without states) and the scene's goal, stamped at `start_time_ns`.
    `extra`: more messages to record, each (topic, type, message, log time (ns), QoS name).
    Raises RecordingError if anything cannot be recorded; the plan itself is untouched.
    """
    start = time.time_ns() if start_time_ns is None else int(start_time_ns)
    try:
        recorded = _messages(output, planning_frame, start, joint_state, object_poses,
                             goal) + list(extra)
        metadata = plan_metadata(output, plan_id, parameters)
    except RecordingError:
        raise
    except (RearrangementError, ValueError, TypeError) as exc:
        raise RecordingError(f"cannot record to {path}: building the messages failed: "
                             f"{exc}") from exc
    define(foxglove_ros2.definitions())
    with McapRecorder(path) as recorder:
        for topic, type_name, message, log_time, qos in recorded:
            recorder.write(topic, type_name, message, log_time, qos)
        recorder.metadata(METADATA_NAME, metadata)
    return recorder.path


def _messages(output: PlanOutput, frame: str, start: int, joint_state: Any,
              object_poses: Any, goal: Any) -> list[tuple]:
    """(topic, type, message, log time (ns), qos) of every message to record."""
    scene = output.scene
    stamp = messages.time(start)
    start_state = output.result.states[0] if output.result.states else scene.initial_state()
    if joint_state is None:
        joint_state = messages.joint_state(start_state.q, scene.robot.joint_names, stamp)
    if object_poses is None:
        object_poses = messages.pose_array(start_state.objects, frame, _centre_heights(scene),
                                           stamp)
    if goal is None:
        goal = messages.goal_pose(scene.goal.position, frame, scene.table.height, stamp)
    recorded: list[tuple] = [
        (TOPICS["joint_state"], "sensor_msgs/msg/JointState", joint_state, start, "sensor"),
        (TOPICS["object_poses"], "geometry_msgs/msg/PoseArray", object_poses, start,
         "reliable"),
        (TOPICS["goal"], "geometry_msgs/msg/PoseStamped", goal, start, "reliable"),
    ]
    object_paths = ee_path = None
    trajectory = output.trajectory
    if trajectory is not None:
        trajectory_msg = messages.joint_trajectory(trajectory)
        recorded.append((TOPICS["trajectory"], "trajectory_msgs/msg/JointTrajectory",
                         trajectory_msg, start, "transient_local"))
        heights = _centre_heights(scene)
        for point, state in zip(trajectory_msg["points"], output.trajectory_states,
                                strict=True):
            t = start + messages.nanoseconds(point["time_from_start"])
            recorded.append((TOPICS["predicted_object_poses"], "geometry_msgs/msg/PoseArray",
                             messages.pose_array(state.objects, frame, heights, messages.time(t)),
                             t, "reliable"))
        object_paths = np.array([state.objects for state in output.trajectory_states])
        ee_path = np.array([scene.robot.tool_pose(q)[:3, 3] for q in trajectory.positions])
    recorded.append((TOPICS["markers"], "visualization_msgs/msg/MarkerArray",
                     messages.plan_markers(scene, object_paths, ee_path, frame, stamp), start,
                     "reliable"))
    return recorded + _scene_3d(output, start_state.q, start, object_paths, ee_path)


def _scene_3d(output: PlanOutput, q: np.ndarray, start: int, object_paths: Any,
              ee_path: Any) -> list[tuple]:
    """The scene at the start, the answer's paths and its motion as Foxglove SceneUpdates
    (`io.scene3d`) recorded as foxglove_msgs/msg/SceneUpdate (`io.foxglove_ros2`), so that a
    recording opened in Foxglove shows the 3D scene at once."""
    scene = output.scene
    def entry(topic: str, update: fg.SceneUpdate, t: int) -> tuple:
        return topic, SCENE_UPDATE, foxglove_ros2.as_ros2(update), t, "reliable"

    recorded: list[tuple] = [entry(TOPICS["scene_3d"], scene3d.scene_update(scene, q), start)]
    trajectory = output.trajectory
    if trajectory is None or object_paths is None:
        return recorded
    recorded.append(entry(TOPICS["plan_3d"], scene3d.paths_update(scene, object_paths, ee_path),
                          start))
    shown = -math.inf
    for t, q_t, state in zip(trajectory.times, trajectory.positions, output.trajectory_states,
                             strict=True):
        if t - shown < MOTION_PERIOD and t < trajectory.duration:
            continue
        shown = t
        update = fg.SceneUpdate(entities=[scene3d.arm_entity(scene, q_t),
                                          *scene3d.object_entities(scene, state.objects)])
        recorded.append(entry(TOPICS["motion_3d"], update, start + int(t * 1e9)))
    return recorded


def plan_metadata(output: PlanOutput, plan_id: str, parameters: Mapping[str, Any]
                  ) -> dict[str, str]:
    """The "rearrangement_plan" metadata record: every value a string, the structured ones as
    JSON (parameters, statistics) or YAML (scene)."""
    result = output.result
    statistics = output.to_dict()
    statistics.pop("trajectory", None)
    return {
        "plan_id": str(plan_id),
        "planner": output.planner,
        "seed": str(result.seed),
        "outcome": result.outcome.value,
        "message": result.message,
        "fragile": str(output.fragile).lower(),
        "parameters": _json(parameters),
        "scene": yaml.safe_dump(_jsonable(output.scene.to_dict()), sort_keys=False),
        "statistics": _json(statistics),
    }


def _json(value: Any) -> str:
    return json.dumps(_jsonable(value), sort_keys=True, allow_nan=False)


def _jsonable(value: Any) -> Any:
    """`value` with numpy values as Python ones, paths as strings and non-finite floats as the
    strings "inf", "-inf", "nan" (strict JSON has no such numbers)."""
    if isinstance(value, Mapping):
        return {str(k): _jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple, np.ndarray)):
        return [_jsonable(v) for v in value]
    if isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, float) and not math.isfinite(value):
        return str(value)
    if isinstance(value, os.PathLike):
        return os.fspath(value)
    return value


def _centre_heights(scene: Scene) -> np.ndarray:
    """z (m) of every object's centre: the prisms stand on the table top."""
    return np.array([scene.table.height + 0.5 * o.height for o in scene.objects])
