"""`make demo` (until the planner lands): one straight push of the goal object, simulated.

Loads and validates a scene, puts the tool on the pushing plane behind the goal object (IK on
the pushing manifold, DESIGN §6), then drives the tool in a straight line towards the goal point
with the Jacobian-pseudoinverse projection (King et al. §V) and every step through the
quasistatic physics (DESIGN §5), and reports what happened: how far the goal object got, which
links pushed, which objects moved, and why the push stopped. This is a single hand-made push
primitive, not a plan: PC-RRT replaces it.
"""

from __future__ import annotations

import argparse
import logging
import math
import sys

import numpy as np

from .errors import RearrangementError
from .manifold import ik_on_manifold, project_step, tool_planar_pose
from .physics import Physics
from .scene import load_scene
from .state import State

log = logging.getLogger("rearrangement_planner.demo")

STAND_OFF = 0.10   # m, tool behind the goal object's centre at the start of the push
SPEED = 0.05       # m/s, tool speed along the push
DT = 0.05          # s, propagation step


def straight_push(scene_path: str, max_steps: int = 400) -> dict:
    scene = load_scene(scene_path)
    robot, goal = scene.robot, scene.goal
    physics = Physics(scene)
    g = scene.goal_index
    start_xy = scene.object_poses[g, :2]
    direction = np.asarray(goal.position) - start_xy
    distance0 = float(np.linalg.norm(direction))
    direction /= distance0
    yaw = math.atan2(direction[1], direction[0])
    pre_push = start_xy - direction * STAND_OFF
    q = ik_on_manifold(robot, pre_push[0], pre_push[1], yaw, scene.table.height,
                       scene.start_configuration, rng=np.random.default_rng(0))
    if q is None:
        raise RearrangementError(f"no pushing configuration reaches {pre_push.round(3)}")
    state = State(q, scene.object_poses)
    problem = physics.check_state(state)
    if problem is not None:
        raise RearrangementError(f"the pre-push configuration is invalid: {problem[1]}")
    links: set[str] = set()
    moved: set[int] = set()
    stop = "step limit"
    steps = 0
    for steps in range(1, max_steps + 1):
        if goal.reached(state.objects[g, :2]):
            stop = "goal reached"
            break
        tool_xy = tool_planar_pose(robot, state.q)[:2]
        heading = np.asarray(goal.position) - tool_xy
        heading /= max(np.linalg.norm(heading), 1e-9)
        action = np.array([heading[0] * SPEED, heading[1] * SPEED, 0.0])
        q_next = project_step(robot, state.q, action, DT, scene.table.height)
        result = physics.step(state, q_next)
        if not result.valid:
            stop = f"invalid step: {result.reason.value} ({result.detail})"
            break
        state = result.state
        links |= result.pushing_links
        moved |= result.moved_objects
    final = state.objects[g, :2]
    return {
        "scene": str(scene_path),
        "pre_push_tool_xy": pre_push.round(3).tolist(),
        "steps": steps,
        "stopped_because": stop,
        "goal_object": goal.object,
        "goal_distance_before_m": round(distance0, 3),
        "goal_distance_after_m": round(goal.distance(final), 3),
        "goal_reached": bool(goal.reached(final)),
        "pushing_links": sorted(links),
        "moved_objects": sorted(scene.objects[i].name for i in moved),
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("scene", help="scene YAML file")
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    try:
        report = straight_push(args.scene)
    except RearrangementError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    log.info("Straight push of '%s' in %s (a single push primitive; the planner is next):",
             report["goal_object"], report["scene"])
    for key, value in report.items():
        log.info("  %-24s %s", key, value)
    return 0


if __name__ == "__main__":
    sys.exit(main())
