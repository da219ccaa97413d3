"""RViz markers of a plan (docs/design.md "The ROS 2 node", the `~/markers` topic), built by
`rearrangement_planner.io.messages.plan_markers` (the same markers the recording holds)."""

from __future__ import annotations

import numpy as np
from builtin_interfaces.msg import Time
from visualization_msgs.msg import MarkerArray

from rearrangement_planner.io import messages
from rearrangement_planner.model.scene import Scene

from .plain import from_plain, time_to_plain


def plan_markers(scene: Scene, object_paths: np.ndarray | None, ee_path: np.ndarray | None,
                 frame: str, stamp: Time | None = None) -> MarkerArray:
    """The markers of `scene` and a plan in it, as a MarkerArray (`io.messages.plan_markers`
    says what is drawn)."""
    plain = messages.plan_markers(scene, object_paths, ee_path, frame, time_to_plain(stamp))
    return from_plain(plain, MarkerArray)
