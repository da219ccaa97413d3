"""The node's parameters, declared once: the node's own (scene, inputs, outputs) are listed
here; the settings of a plan request are read from the option dataclasses
(`planning.requests.request.request_settings`: the planners', the pushing model's and the pipeline
stages'), so their default, range and description are written once, in the core, and the node
plans the CLI's default request. `config/planner.yaml` holds the same defaults
(a test checks it).

    ros2 param describe /rearrangement_planner time_limit
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor
from rclpy.node import Node
from rclpy.parameter import Parameter

from rearrangement_planner.execution.closed_loop import CLOSING
from rearrangement_planner.model.settings import SettingSpec
from rearrangement_planner.planning.requests.registry import PLANNER_NAMES
from rearrangement_planner.planning.requests.request import DEFAULT_PLANNER, request_settings

_INT32_MAX = 2**31 - 1


@dataclass(frozen=True)
class ParameterSpec:
    name: str
    default: bool | int | float | str | tuple[str, ...]
    description: str
    low: float | None = None
    high: float | None = None
    read_only: bool = False
    empty_type: str = "string"
    """The element type of an empty-list default ("string" or "double"): `[]` has no ROS
    type of its own."""

    def descriptor(self) -> ParameterDescriptor:
        descriptor = ParameterDescriptor(description=self.description, read_only=self.read_only)
        if self.low is not None and isinstance(self.default, bool):
            raise TypeError(f"parameter {self.name}: a bool has no range")
        if self.low is None or self.high is None:
            return descriptor
        if isinstance(self.default, int):
            descriptor.integer_range = [IntegerRange(from_value=int(self.low),
                                                     to_value=int(self.high), step=1)]
        else:
            descriptor.floating_point_range = [FloatingPointRange(
                from_value=float(self.low), to_value=float(self.high), step=0.0)]
        return descriptor

    @classmethod
    def of(cls, setting: SettingSpec) -> ParameterSpec:
        """The parameter of a core setting: same name, default, range and description."""
        description = setting.description
        if setting.choices:
            description += f" One of: {', '.join(setting.choices)}."
        return cls(setting.name, setting.default, description, setting.low, setting.high)


_NODE_FIRST: tuple[ParameterSpec, ...] = (
    ParameterSpec("scene", "default", "Scene: a shipped scene name (config/scenes) or a scene "
                  "YAML path (docs/design.md). Table, obstacles, object shapes and the default "
                  "goal.",
                  read_only=True),
    ParameterSpec("robot_description", "", "URDF of the robot (XML string); '' = the URDF of "
                  "the robot config the scene names.", read_only=True),
    ParameterSpec("object_ids", (), "Scene object names in the order of the poses on "
                  "~/object_poses; [] = scene order. Must list every scene object once."),
    ParameterSpec("goal_object", "", "Object to bring into the goal region; '' = the scene's."),
    ParameterSpec("goal_radius", 0.0, "Goal region radius, m; 0 = the scene's.", 0.0, 10.0),
    ParameterSpec("planning_frame", "world", "Frame of all inputs and outputs, the robot base "
                  "frame; '' = the robot config's base frame name. "
                  "Inputs in another frame are rejected (no tf here)."),
    ParameterSpec("max_object_tilt", 0.05, "Largest tilt from upright of a received object "
                  "pose, rad; objects must stand on the table.", 0.0, 1.5),
    ParameterSpec("state_timeout", 1.0, "Joint states and object poses older than this (receive "
                  "time, s) are stale (NO_STATE); 0 = never stale.", 0.0, 86400.0),
    ParameterSpec("planner", DEFAULT_PLANNER, f"Planning algorithm: {', '.join(PLANNER_NAMES)}. "
                  "A planner refuses a setting it does not read unless it has its default."),
    ParameterSpec("seed", 0, "Random seed: same scene, inputs, parameters and seed give the "
                  "same plan.", 0, _INT32_MAX),
)
_NODE_LAST: tuple[ParameterSpec, ...] = (
    ParameterSpec("record_dir", "~/.ros/rearrangement_plans", "Folder of the MCAP recordings "
                  "(<plan id>.mcap); '~' is expanded."),
    ParameterSpec("record", True, "Record every plan (success or failure) to MCAP."),
    ParameterSpec("record_limit_mb", 1000.0, "The recordings in record_dir take at most this "
                  "many MB: the oldest .mcap files there are deleted after each new one; "
                  "0 = no limit.", 0.0, 1e7),
    ParameterSpec("live_view_port", 0, "Serve the live view (Foxglove WebSocket: the scene, the "
                  "search, the answer, the executions) on this port of 127.0.0.1; 0 = off. "
                  "Read at start.", 0, 65535, read_only=True),
    ParameterSpec("auto_execute", False, "Publish every successful plan on joint_trajectory "
                  "right away (a fragile one only with execute_fragile)."),
    ParameterSpec("execute_fragile", False, "With auto_execute, publish a fragile plan too (one "
                  "whose robustness is below fragile_below; its answer says FRAGILE)."),
    ParameterSpec("plan_on_goal", False, "Start planning when a goal arrives on ~/goal."),
    ParameterSpec("max_trees", 4, "The most raced trees one request may ask for (its trees "
                  "setting): each tree past the first is a worker process of about 230 MB "
                  "that stays for the node's life. A request asking for more is refused "
                  "(INVALID_INPUT).", 1, 64),
    ParameterSpec("execution_timeout", 0.0, "How long an action goal with execute waits for "
                  "joint_states to reach the sent trajectory's last point, s (EXECUTION_FAILED "
                  "after); 0 = the trajectory's duration plus 10 s.", 0.0, 86400.0),
    ParameterSpec("replan_attempts", 0, "Closed loop for an action goal with execute: after "
                  "an execution, observe ~/object_poses; while the goal object is outside its "
                  "region, retreat out of contact, plan again from the observed state and "
                  "execute, up to this many times (a goal's replan_attempts >= 0 overrides); "
                  "0 = plan and execute once.", 0, 20),
    ParameterSpec("replan_closing", CLOSING, "With replan_attempts > 0: up to this many re-plans "
                  "more while each attempt leaves the goal object at least 1 cm nearer its "
                  "goal than the one before; 0 = never past replan_attempts.", 0, 20),
    ParameterSpec("divergence_bound", 0.05, "With replan_attempts > 0: while a plan runs, an "
                  "object observed farther than this from the pose the plan predicts at the "
                  "arm's progress stops the arm (empty trajectory) and the node re-plans from "
                  "there, m; 0 = do not watch.", 0.0, 10.0),
)

PARAMETERS: tuple[ParameterSpec, ...] = (
    _NODE_FIRST
    + tuple(ParameterSpec.of(s) for s in request_settings())
    + _NODE_LAST
)
"""Every parameter of the node, in the order of config/planner.yaml."""
DEFAULTS: dict[str, Any] = {p.name: p.default for p in PARAMETERS}


def declare_parameters(node: Node, parameters: tuple[ParameterSpec, ...]) -> None:
    """Declare every parameter on `node` with its descriptor."""
    for spec in parameters:
        if spec.default == ():
            # An empty list has no ROS type (rclpy would guess a byte array, and rcl's YAML
            # parser drops `[]`): declare the type, then set the empty default (which is why
            # such a parameter cannot be read-only).
            kind = {"string": Parameter.Type.STRING_ARRAY,
                    "double": Parameter.Type.DOUBLE_ARRAY}[spec.empty_type]
            declared = node.declare_parameter(spec.name, kind, spec.descriptor())
            if declared.type_ is Parameter.Type.NOT_SET:
                node.set_parameters([Parameter(spec.name, kind, [])])
        else:
            node.declare_parameter(spec.name, spec.default, spec.descriptor())


def read_parameters(node: Node, parameters: tuple[ParameterSpec, ...]) -> dict[str, Any]:
    """The current value of every parameter (string arrays as lists)."""
    values: dict[str, Any] = {}
    for spec in parameters:
        value = node.get_parameter(spec.name).value
        values[spec.name] = list(value) if isinstance(spec.default, tuple) else value
    return values
