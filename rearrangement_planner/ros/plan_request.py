"""One plan request of the node (docs/design.md), apart from the node's wiring: the settings from
the parameters, the inputs it plans from, the planning scene, the recording and the markers of
the result. `ros/node.py` calls these from its worker thread."""

from __future__ import annotations

import dataclasses
import threading
import time
import traceback
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from builtin_interfaces.msg import Time
from geometry_msgs.msg import PoseArray
from visualization_msgs.msg import MarkerArray

from msg_adapters import joint_state_to_configuration, plan_markers, pose_array_to_objects
from rearrangement_planner.io.plan_record import record_plan
from rearrangement_planner.io.recording import RecordingError
from rearrangement_planner.model.errors import InputError, SceneError
from rearrangement_planner.model.robot import RobotModel
from rearrangement_planner.model.scene import Goal, Scene
from rearrangement_planner.model.settings import SettingError
from rearrangement_planner.physics.validation import (
    SEPARATION_LIMIT,
    check_scene,
    load_scene,
    separate_objects,
)
from rearrangement_planner.planning.machinery.interface import (
    Outcome,
    PlanResult,
    Progress,
    ProgressCallback,
)
from rearrangement_planner.planning.requests.pipeline import PlanOutput, plan_scene
from rearrangement_planner.planning.requests.request import PlanRequest, request_settings
from rearrangement_planner.planning.requests.status import PlannerStatus
from rearrangement_planner.ros.action import (
    NO_STATE,
    goal_origins,
    goal_parameters,
    goal_point_pose,
)


def node_request(params: dict[str, Any], scene: Scene,
                 origins: dict[str, str] | None = None) -> PlanRequest:
    """The one plan request of the node's parameters on the planning `scene`
    (`PlanRequest.from_settings`: the CLI builds its request the same way). InputError names
    where the setting at fault came from: `origins[name]` (an action goal's field) or the
    parameter; the error's type carries the setting's name (`SettingError`)."""
    values = {s.name: params[s.name] for s in request_settings()}
    if values["trees"] > params["max_trees"]:
        where = (origins or {}).get("trees", "parameter trees")
        raise InputError(where, f"trees {values['trees']} is more than the node's max_trees "
                                f"{params['max_trees']} (a worker process each)")
    try:
        return PlanRequest.from_settings(scene, params["planner"], values,
                                         seed=int(params["seed"]))
    except SettingError as exc:
        where = (origins or {}).get(exc.name, f"parameter {exc.name}")
        raise InputError(where, str(exc)) from None


@dataclass(frozen=True)
class Input:
    """The last good message of one input topic, converted, with its receive time."""

    value: np.ndarray
    msg: Any
    received: float
    """time.monotonic() at reception (the staleness clock, docs/design.md `state_timeout`)."""


class Job:
    """One plan request, from submission to its answer."""

    def __init__(self, plan_id: str, source: str):
        self.plan_id = plan_id
        self.source = source
        self.submitted = time.monotonic()
        self.submitted_ns = time.time_ns()
        self.cancel = threading.Event()
        self.planned = threading.Event()   # planning has stopped (the answer may still follow)
        self.done = threading.Event()      # everything published, recorded and answered
        self.started: float | None = None
        self.outcome = ""
        self.summary = ""
        self.goal: Any = None
        """The action goal (rearrangement_interfaces/PlanRearrangement), None for ~/plan."""
        self.phase = "waiting"
        """What the job does now: waiting, planning, recording, executing (the feedback)."""
        self.output: PlanOutput | None = None
        self.recording = ""
        self.executed = False
        """The plan was sent to the controller for the goal (`execute`)."""
        self.feedback: list[tuple[int, Any]] = []
        """(time.time_ns(), feedback) of every action feedback sent (for the recording)."""
        self.trajectory: Any = None
        """The JointTrajectory of a solved plan."""
        self.frame = ""
        self.params: dict[str, Any] = {}
        """The parameters the job plans with (the node's, changed by its goal)."""
        self.attempt = 1
        """1 for the first plan; the closed loop's re-plans count up (`ros/replan.py`)."""
        self.attempts: list[Any] = []
        """The closed loop's `replan.Attempt`s (empty without one)."""


class Rejected(Exception):
    """A plan that ends before the planner runs (NO_STATE, invalid start or goal ...)."""

    def __init__(self, outcome: str, message: str):
        super().__init__(message)
        self.outcome = outcome
        self.message = message


FINAL_STATES = {Outcome.SUCCEEDED.value: "succeeded", Outcome.CANCELLED.value: "cancelled"}


def configured_scene(scene: str, robot_description: str) -> Scene:
    """The node's scene (parameter `scene`), with the robot from `robot_description` when
    given (else the robot the scene names). Raises RearrangementError."""
    loaded = load_scene(scene)
    if robot_description:
        loaded = load_scene(loaded.source,
                            robot=RobotModel(loaded.robot.config, urdf_xml=robot_description))
    return loaded


def object_ids(ids: list[str], scene: Scene) -> list[str]:
    """The order of the poses on ~/object_poses: parameter `object_ids`, or scene order."""
    names = list(scene.object_names)
    if not ids:
        return names
    unknown = [i for i in ids if i not in names]
    missing = [n for n in names if n not in ids]
    if unknown or missing or len(set(ids)) != len(ids):
        raise InputError("parameter object_ids",
                         f"is {ids}; list every scene object once ({', '.join(names)})")
    return ids


def objects_from_msg(msg: PoseArray, params: dict[str, Any], scene: Scene) -> np.ndarray:
    """The planar poses (M, 3) in scene order of a PoseArray in the order of parameter
    object_ids. InputError names the field at fault."""
    ids = object_ids(list(params["object_ids"]), scene)
    frame = params["planning_frame"] or scene.robot.config.base_frame
    poses = pose_array_to_objects(msg, ids, frame, params["max_object_tilt"])
    objects = np.empty_like(poses)
    for pose, name in zip(poses, ids, strict=True):
        objects[scene.object_index(name)] = pose
    return objects


def goal_inputs(goal: Any, params: dict[str, Any], scene: Scene,
                latest: dict[str, Input | None], replan: bool = False
                ) -> tuple[dict[str, Any], dict[str, Input | None]]:
    """The parameters and inputs of an action goal (`ros.action`): its settings over the
    parameters, and its start state (not for a `replan`: that starts from what is observed)
    and goal point, where it gives them, over the latest messages. InputError names the goal
    field at fault."""
    params = goal_parameters(goal, params)
    latest = dict(latest)
    now = time.monotonic()
    start = goal.start_joint_state
    if not start.name and (len(start.position) or len(start.velocity) or len(start.effort)):
        raise InputError("goal.start_joint_state.name",
                         f"is empty while the state gives {len(start.position)} positions; "
                         f"name every joint, or leave the whole start_joint_state empty to "
                         f"start from the latest joint_states")
    if start.name and not replan:
        try:
            q = joint_state_to_configuration(goal.start_joint_state, scene.robot.joint_names)
        except InputError as exc:
            raise InputError(f"goal.start_{exc.field}", exc.problem) from None
        latest["joint_states"] = Input(q, goal.start_joint_state, now)
    if goal.start_object_poses.poses and not replan:
        try:
            objects = objects_from_msg(goal.start_object_poses, params, scene)
        except InputError as exc:
            raise InputError(f"goal.start_{exc.field}", exc.problem) from None
        latest["object_poses"] = Input(objects, goal.start_object_poses, now)
    frame = params["planning_frame"] or scene.robot.config.base_frame
    pose = goal_point_pose(goal, frame)
    if pose is not None:
        latest["goal"] = Input(np.array([pose.pose.position.x, pose.pose.position.y]), pose, now)
    return params, latest


def fresh_inputs(latest: dict[str, Input | None], topics: dict[str, str],
                 state_timeout: float) -> dict[str, Input | None]:
    """The inputs to plan from (`latest`, by key); NO_STATE when the joint state or object
    poses are missing or older than `state_timeout` s (`topics` names them in the message)."""
    now = time.monotonic()
    for key, what in (("joint_states", "joint state"), ("object_poses", "object poses")):
        value, topic = latest[key], topics[key]
        if value is None:
            raise Rejected(NO_STATE, f"no {what} received on {topic} yet")
        age = now - value.received
        if state_timeout > 0 and age > state_timeout:
            raise Rejected(NO_STATE, f"the last {what} on {topic} is {age:.1f} s old "
                                     f"(state_timeout {state_timeout:g} s)")
    return latest


def observed_apart(scene: Scene, inputs: dict[str, Input | None]) -> dict[str, Input | None]:
    """`inputs` with the observed object poses moved apart where objects overlap
    (`separate_objects`; the recording keeps the message as received). Rejected
    (START_INVALID) when they overlap by more than SEPARATION_LIMIT."""
    objects = inputs["object_poses"]
    assert objects is not None
    apart = separate_objects(scene, objects.value)
    if apart is None:
        raise Rejected(Outcome.START_INVALID.value,
                       f"start invalid (object_poses): the observed objects overlap by more "
                       f"than {SEPARATION_LIMIT:g} m; not a state to re-plan from")
    return {**inputs, "object_poses": dataclasses.replace(objects, value=apart)}


def planning_scene(configured_scene: Scene, inputs: dict[str, Input | None],
                   params: dict[str, Any]) -> Scene:
    """The configured scene with the received start state and goal, checked (the scene is not
    re-parsed: only the state and goal change). A joint at most LIMIT_TOLERANCE past a limit
    starts at the limit (`RobotModel.clamped`)."""
    joints, objects, received = (inputs["joint_states"], inputs["object_poses"],
                                 inputs["goal"])
    assert joints is not None and objects is not None    # `fresh_inputs` raised otherwise
    configured = configured_scene.goal
    goal = Goal(params["goal_object"] or configured.object,
                received.value if received is not None else configured.position,
                params["goal_radius"] if params["goal_radius"] > 0 else configured.radius)
    start = configured_scene.robot.clamped(joints.value)     # a hair past a limit: the limit
    scene = dataclasses.replace(configured_scene.with_start(start, objects.value), goal=goal)
    try:
        check_scene(scene)
    except SceneError as exc:
        raise Rejected(*_classify(exc, received is not None)) from None
    return scene


def run_plan(job: Job, params: dict[str, Any], configured: Scene,
             latest: dict[str, Input | None], topics: dict[str, str],
             progress: ProgressCallback, logger: Any
             ) -> tuple[str, str, Scene, PlanOutput | None, dict[str, Input | None]]:
    """Plan one request from the latest inputs: outcome, message, planning scene, plan
    output (None for NO_STATE) and the inputs used. Every failure becomes an outcome;
    nothing raises."""
    inputs: dict[str, Input | None] = {}
    scene, output = configured, None
    try:
        origins: dict[str, str] = {}
        if job.goal is not None:
            params, latest = goal_inputs(job.goal, params, configured, latest, job.attempt > 1)
            job.params, origins = params, goal_origins(job.goal)
        inputs = fresh_inputs(latest, topics, params["state_timeout"])
        if job.attempt > 1:        # a re-plan from observed poses: touching objects overlap
            inputs = observed_apart(configured, inputs)
        scene = planning_scene(configured, inputs, params)
        request = node_request(params, scene, origins)
        output = plan_scene(request, cancel=job.cancel, progress=progress)
        return output.result.outcome.value, output.result.message, scene, output, inputs
    except InputError as exc:
        outcome, message = Outcome.INVALID_INPUT.value, str(exc)
    except Rejected as exc:
        outcome, message = exc.outcome, exc.message
    except Exception as exc:  # noqa: BLE001 - INTERNAL, reported, the node keeps serving
        logger.error(f"plan {job.plan_id}: {traceback.format_exc()}")
        outcome = Outcome.INTERNAL.value
        message = f"internal error {type(exc).__name__}: {exc} (traceback in the node log)"
    if outcome != NO_STATE:   # a failure the recording can describe
        output = PlanOutput(scene, params["planner"],
                            PlanResult(Outcome(outcome), message, int(params["seed"])))
    return outcome, message, scene, output, inputs


def record(job: Job, output: PlanOutput | None, params: dict[str, Any], frame: str,
           inputs: dict[str, Input | None], logger: Any,
           extra: Callable[[str], list[tuple]] | None = None,
           plan_id: str = "") -> tuple[str, str | None]:
    """Record the plan as `plan_id` (default the job's), and the messages `extra(path)` gives
    (an action's goal, feedback and result): (the path written or 'not recorded: <reason>', a
    failure to report or None). A recording failure never loses the plan."""
    if not params["record"]:
        return "not recorded: parameter record is false", None
    if output is None:
        return "not recorded: no planning state", None

    def msg(key: str) -> Any:
        value = inputs.get(key)
        return value.msg if value is not None else None

    plan_id = plan_id or job.plan_id
    path = Path(params["record_dir"]).expanduser() / f"{plan_id}.mcap"
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        written = record_plan(path, output, plan_id=plan_id, parameters=params,
                              planning_frame=frame, joint_state=msg("joint_states"),
                              object_poses=msg("object_poses"), goal=msg("goal"),
                              start_time_ns=job.submitted_ns,
                              extra=extra(str(path)) if extra is not None else ())
    except (RecordingError, OSError) as exc:
        reason = str(exc)
    except Exception as exc:  # noqa: BLE001 - a recording bug must not lose the plan
        logger.error(f"plan {plan_id}: {traceback.format_exc()}")
        reason = f"internal error {type(exc).__name__}: {exc}"
    else:
        prune_recordings(path.parent, params["record_limit_mb"] * 1e6, keep=path)
        return str(written), None
    return (f"not recorded: {reason}",
            f"plan {plan_id}: recording to {path} failed: {reason}")


def prune_recordings(folder: Path, limit_bytes: float, keep: Path) -> list[Path]:
    """Delete the oldest recordings (`*.mcap` in `folder`, by modification time) until the
    folder's recordings take at most `limit_bytes` (0: no limit), never `keep` (the one just
    written); returns those deleted. A file that cannot be deleted is left."""
    if limit_bytes <= 0:
        return []
    files = []
    for file in folder.glob("*.mcap"):
        try:
            stat = file.stat()
        except OSError:
            continue
        files.append((stat.st_mtime, stat.st_size, file))
    total = sum(size for _, size, _ in files)
    deleted = []
    for _, size, file in sorted(files):
        if total <= limit_bytes:
            break
        if file == keep:
            continue
        try:
            file.unlink()
        except OSError:
            continue
        total -= size
        deleted.append(file)
    return deleted


def planning_status(job: Job, progress: Progress | None, message: str) -> PlannerStatus:
    """The ~/status of a running plan: its id, the message and the planner's progress."""
    elapsed = time.monotonic() - job.started if job.started is not None else 0.0
    if progress is None:
        return PlannerStatus("planning", message, plan_id=job.plan_id, elapsed=elapsed)
    return PlannerStatus("planning", message, plan_id=job.plan_id,
                         iterations=progress.iterations, tree_size=progress.tree_size,
                         best_goal_distance=progress.best_goal_distance, elapsed=elapsed)


def summary_line(plan_id: str, outcome: str, message: str, output: PlanOutput | None,
                 recording: str, rollouts: int) -> str:
    """The one-line answer of ~/plan (and the final ~/status message): "plan ID: OUTCOME in
    T s, N iterations, mcap PATH", then "; why" unless it succeeded, then the robustness (the
    3D judge's, with what its nominal world saw, or the model's rollouts'), and for a fragile
    plan the sentence that says so (`PlanOutput.fragile_note`)."""
    r = output.result if output is not None else None
    plan_time, iterations = (r.plan_time, r.iterations) if r else (0.0, 0)
    summary = (f"plan {plan_id}: {outcome} in {plan_time:.2f} s, {iterations} iterations, "
               f"mcap {recording}")
    if outcome != Outcome.SUCCEEDED.value:
        summary += f"; {message}"
    if output is not None and output.judged is not None:
        judged = output.judged
        summary += (f"; robustness {output.robustness:.0%} of {judged.worlds} perturbed 3D "
                    f"worlds (nominal: {'reached' if judged.reached else judged.failure}; "
                    f"{judged.planner}, {judged.mends} mends)")
    elif output is not None and output.robustness is not None:
        summary += f"; robustness {output.robustness:.0%} of {rollouts} perturbed rollouts"
    if output is not None and output.fragile:
        summary += f"; {output.fragile_note()}"
    return summary


def final_summary(job: Job, outcome: str, message: str, recording: str, executed: bool,
                  sendable: bool) -> str:
    """The job's answer (`summary_line`), with what its execution did: the message of one
    that reached the plan's end, or why a fragile plan was not sent."""
    summary = summary_line(job.plan_id, outcome, message, job.output, recording,
                           job.params["rollouts"])
    if executed and outcome == Outcome.SUCCEEDED.value:
        summary += f"; {message}"
    if job.goal is not None and job.goal.execute and not sendable:
        summary += "; not executed (parameter execute_fragile is false)"
    return summary


def result_markers(scene: Scene, output: PlanOutput | None, frame: str,
                   stamp: Time) -> MarkerArray:
    """The markers of the planning scene and, when solved, the plan's paths."""
    if output is None or output.trajectory is None:
        return plan_markers(scene, None, None, frame, stamp)
    robot = scene.robot
    object_paths = np.array([s.objects for s in output.trajectory_states])
    ee_path = np.array([robot.tool_pose(q)[:3, 3] for q in output.trajectory.positions])
    return plan_markers(scene, object_paths, ee_path, frame, stamp)


def _classify(exc: SceneError, goal_received: bool) -> tuple[str, str]:
    """Outcome and message of a planning scene that does not validate: the start state is the
    joint state and object poses, the goal the received goal and the goal parameters."""
    field = exc.field
    if field.startswith("goal"):
        source = {"goal.object": "parameter goal_object", "goal.radius": "parameter goal_radius",
                  "goal.position": "~/goal" if goal_received else "the scene"}
        where = source.get(field.split("[")[0], "the goal")
        return Outcome.GOAL_INVALID.value, f"goal invalid ({where}): {exc}"
    if field.startswith("start_configuration"):
        return Outcome.START_INVALID.value, f"start invalid (joint_states): {exc}"
    if field.startswith("objects"):
        return Outcome.START_INVALID.value, f"start invalid (object_poses): {exc}"
    return Outcome.INVALID_INPUT.value, str(exc)
