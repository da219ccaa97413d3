"""The planner node's publishers (docs/design.md "The ROS 2 node"), in one place: each
publishes only while the node's context is valid, so that a worker finishing its job after
Ctrl-C stays quiet."""

from __future__ import annotations

from typing import Any

from diagnostic_msgs.msg import DiagnosticArray
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from trajectory_msgs.msg import JointTrajectory
from visualization_msgs.msg import MarkerArray

from msg_adapters import status_to_diagnostics, status_to_msg
from rearrangement_interfaces.msg import PlannerStatus as PlannerStatusMsg
from rearrangement_planner.planning.requests.status import PlannerStatus


class Outputs:
    """`~/trajectory` (every solved plan, latched), `joint_trajectory` (the controller
    command), `~/markers` (latched), `~/status` (rearrangement_interfaces/PlannerStatus) and
    the same status on `/diagnostics` (diagnostic_msgs/DiagnosticArray, named after the
    node's fully qualified name)."""

    def __init__(self, node: Node):
        self._node = node
        latched = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                             durability=DurabilityPolicy.TRANSIENT_LOCAL)
        self.trajectory = node.create_publisher(JointTrajectory, "~/trajectory", latched)
        self.command = node.create_publisher(
            JointTrajectory, "joint_trajectory",
            QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                       durability=DurabilityPolicy.VOLATILE))
        self.markers = node.create_publisher(MarkerArray, "~/markers", latched)
        self._status = node.create_publisher(PlannerStatusMsg, "~/status", 10)
        self._diagnostics = node.create_publisher(DiagnosticArray, "/diagnostics", 10)

    def publish(self, publisher: Any, msg: Any) -> None:
        """Publish unless the node's context has shut down."""
        if self._node.context.ok():
            publisher.publish(msg)

    def status(self, status: PlannerStatus) -> None:
        stamp = self._node.get_clock().now().to_msg()
        self.publish(self._status, status_to_msg(status, stamp))
        self.publish(self._diagnostics, status_to_diagnostics(
            status, stamp, self._node.get_fully_qualified_name()))
