"""Pure conversion functions between ROS 2 messages and the core's types.

The only package that knows both: it imports message types and the core, nothing else of ROS.
"""

from .conversions import (
    configuration_to_joint_state,
    goal_to_pose_stamped,
    joint_state_to_configuration,
    msg_to_trajectory,
    objects_to_pose_array,
    pose_array_to_objects,
    pose_stamped_to_goal,
    trajectory_to_msg,
    yaw_to_quaternion,
)
from .diagnostics import diagnostics_to_status, status_to_diagnostics
from .markers import plan_markers
from .status import msg_to_status, status_to_msg

__all__ = [
    "configuration_to_joint_state",
    "diagnostics_to_status",
    "goal_to_pose_stamped",
    "joint_state_to_configuration",
    "msg_to_status",
    "msg_to_trajectory",
    "objects_to_pose_array",
    "plan_markers",
    "pose_array_to_objects",
    "pose_stamped_to_goal",
    "status_to_diagnostics",
    "status_to_msg",
    "trajectory_to_msg",
    "yaw_to_quaternion",
]
