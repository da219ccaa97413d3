"""`python -m rearrangement_planner.ros.sim.node_demo` (`make demo`): the whole job, in one process.

Starts `world_sim` (the simulated arm, objects and trajectory controller) and `planner_node`
on a scene, each a real ROS 2 node on one executor. The planner receives the joint state and
the object poses from world_sim, as from a robot and a perception system; the demo sends one
goal to the action `/rearrangement_planner/plan_rearrangement` (the scene's goal, `execute`):
the node plans, sends the trajectory on `/joint_trajectory` to world_sim, which executes it open
loop, faster than real time (`--time-scale`), and answers once the arm has reached its end.
Prints the plan summary, world_sim's outcome (goal object distance, in the region or not,
objects moved), the MCAP of the plan and a top view PNG of the execution (the objects' true
paths and the tool path). With `--replan N` the node closes the loop (`ros/replan.py`): when
the observed goal object misses its region, the arm backs out of contact, the node plans again
from the observed state and executes, up to N times; the answer and world_sim's outcomes are
printed attempt by attempt.

The planner plans for the goal radius minus its `goal_margin` (`--goal-margin`, default the
node's parameter), world_sim judges the scene's radius: open-loop execution never reproduces
the planner's physics exactly, so a plan ending on the region's edge would miss it.

A fragile plan (robustness below the node's fragile_below) is executed only with
`--execute-fragile`, as the node's parameter `execute_fragile` says; without it the demo ends
at the answer.

Exit code 0 when the goal object ends inside its goal region, 1 otherwise (also for a fragile
plan not sent), 2 for bad arguments. ROS_DOMAIN_ID is taken from the environment; discovery
defaults to this machine (ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST) unless set.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

import numpy as np


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="python -m rearrangement_planner.ros.sim.node_demo",
        description="Run world_sim and planner_node on a scene: plan from world_sim's state, "
                    "execute the plan open loop in world_sim, print the outcome.")
    parser.add_argument("--scene", default="default",
                        help="shipped scene name or scene YAML path (default: default)")
    parser.add_argument("--seed", type=int, default=0, help="planner seed (default 0)")
    parser.add_argument("--time-limit", type=float, default=60.0, metavar="S",
                        help="planning budget in seconds (default 60)")
    parser.add_argument("--record-dir", type=Path, default=Path("out"),
                        help="folder for the MCAP recording (default: out/)")
    parser.add_argument("--plot", type=Path, default=None, metavar="OUT.png",
                        help="top view PNG of the execution (default: out/<scene>.png)")
    parser.add_argument("--time-scale", type=float, default=10.0, metavar="K",
                        help="world_sim runs the trajectory K times faster than real time "
                             "(default 10)")
    parser.add_argument("--execute-fragile", action="store_true",
                        help="execute the plan even when it is fragile (its robustness is "
                             "below fragile_below; the node's parameter execute_fragile)")
    parser.add_argument("--goal-margin", type=float, default=None, metavar="M",
                        help="the planner's goal_margin: plan for the goal radius minus M "
                             "metres (default: the node's, config/planner.yaml)")
    parser.add_argument("--replan", type=int, default=0, metavar="N",
                        help="closed loop: after an execution that leaves the goal object "
                             "outside its region, retreat, observe and plan again, up to N "
                             "times (the goal's replan_attempts; default 0: open loop)")
    parser.add_argument("--divergence-bound", type=float, default=None, metavar="M",
                        help="with --replan: stop the arm when an object strays this far from "
                             "its predicted path, m (default the node's parameter; 0: do not "
                             "watch)")
    parser.add_argument("--live", nargs="?", type=int, const=8765, default=None,
                        metavar="PORT",
                        help="the node serves its live view (the scene, the search, the answer "
                             "and the executions, for Foxglove) on ws://127.0.0.1:PORT (default "
                             "8765; the node's live_view_port)")
    parser.add_argument("--live-hold", type=float, default=0.0, metavar="S",
                        help="with --live: keep the nodes up S seconds after the demo ends, to "
                             "look at the live view (default 0)")
    world = parser.add_argument_group(
        "simulated world", "make world_sim differ from what the planner sees, to probe "
                           "open-loop robustness")
    world.add_argument("--engine", choices=("mujoco", "quasistatic"), default="mujoco",
                       help="world_sim's physics: mujoco (default: an independent engine, the "
                            "arm's real collision meshes, free rigid objects) or quasistatic "
                            "(the planner's own model)")
    world.add_argument("--pose-noise", type=float, default=0.0, metavar="M",
                       help="std dev of the true objects' offset from their published poses, "
                            "m (default 0)")
    world.add_argument("--friction-scale", type=float, default=1.0, metavar="F",
                       help="multiplies the simulated objects' frictions (default 1)")
    world.add_argument("--world-seed", type=int, default=0, metavar="N",
                       help="seed of the pose offsets (default 0)")
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    # rclpy and the message packages only once the environment is set.
    from rclpy.parameter import Parameter

    from rearrangement_planner.model.errors import RearrangementError
    from rearrangement_planner.physics.validation import load_scene
    from rearrangement_planner.ros.node import PlannerNode
    from rearrangement_planner.ros.sim.replay import Session
    from rearrangement_planner.ros.sim.world_sim import WorldSim

    try:
        for flag, value in (("--time-limit", args.time_limit), ("--time-scale", args.time_scale)):
            if not value > 0:
                raise RearrangementError(f"{flag} must be positive, got {value}")
        for flag, value, high in (("--pose-noise", args.pose_noise, 0.5),
                                  ("--friction-scale", args.friction_scale, 100.0),
                                  ("--world-seed", args.world_seed, 2**31 - 1),
                                  ("--replan", args.replan, 20),
                                  ("--live", args.live or 0, 65535),
                                  ("--live-hold", args.live_hold, 3600.0),
                                  ("--divergence-bound", args.divergence_bound or 0.0, 10.0)):
            if not 0 <= value <= high:
                raise RearrangementError(f"{flag} must be in [0, {high:g}], got {value}")
        scene = load_scene(args.scene)
        if args.goal_margin is not None and not 0 <= args.goal_margin < scene.goal.radius:
            raise RearrangementError(f"--goal-margin must be in [0, {scene.goal.radius:g}) "
                                     f"(the goal radius), got {args.goal_margin}")
        args.record_dir.mkdir(parents=True, exist_ok=True)
    except (RearrangementError, OSError) as exc:
        print(f"node_demo: {exc}", file=sys.stderr)
        return 2
    plot_path = args.plot or args.record_dir / f"{Path(scene.source).stem}.png"
    extra = [] if args.goal_margin is None else [Parameter("goal_margin",
                                                           value=float(args.goal_margin))]
    if args.divergence_bound is not None:
        extra.append(Parameter("divergence_bound", value=float(args.divergence_bound)))
    if args.live is not None:
        extra.append(Parameter("live_view_port", value=int(args.live)))

    with Session(name="demo") as session:
        try:
            world = session.add(WorldSim(context=session.context, parameter_overrides=[
                Parameter("scene", value=args.scene),
                Parameter("engine", value=args.engine),
                Parameter("time_scale", value=float(args.time_scale)),
                Parameter("pose_noise", value=float(args.pose_noise)),
                Parameter("friction_scale", value=float(args.friction_scale)),
                Parameter("seed", value=args.world_seed)]))
            planner = session.add(PlannerNode(context=session.context, parameter_overrides=[
                Parameter("scene", value=args.scene), Parameter("seed", value=args.seed),
                Parameter("time_limit", value=float(args.time_limit)),
                Parameter("record_dir", value=str(args.record_dir.resolve())),
                Parameter("execute_fragile", value=bool(args.execute_fragile)), *extra]))
        except RearrangementError as exc:
            print(f"node_demo: {exc}", file=sys.stderr)
            return 2
        planning_radius = scene.goal.radius - planner.get_parameter("goal_margin").value
        if planner.live.view is not None:
            print(f"live view: {planner.live.view.url} (in Foxglove: Open connection; layout "
                  f"config/foxglove_layout.json)", flush=True)
        code = _run(session, world, planner, scene, args, planning_radius, plot_path)
        if planner.live.view is not None and args.live_hold > 0:
            print(f"live view stays up {args.live_hold:g} s", flush=True)
            time.sleep(args.live_hold)
        return code


def _run(session, world, planner, scene, args, planning_radius: float, plot_path: Path) -> int:
    from rearrangement_interfaces.action import PlanRearrangement
    from rearrangement_interfaces.msg import ErrorCode
    from rearrangement_planner.model.resources import NODE_NAME
    from rearrangement_planner.ros.client import ClientError, PlannerClient
    from rearrangement_planner.ros.sim.replay import BagError, OutcomeListener

    node = session.node
    client = PlannerClient(node, f"/{NODE_NAME}")
    outcomes = OutcomeListener(node, "/world_sim/outcome")
    try:
        client.wait_ready()
        ready = _wait(lambda: node.count_subscribers("/joint_states") >= 1
                      and world.command_publisher_count() >= 1, 10.0)
        if not ready:
            raise BagError("world_sim and planner_node did not connect in 10 s")
        time.sleep(0.5)   # a few rounds of world_sim's joint states and object poses
        perturbed = (f", pose noise {args.pose_noise:g} m (seed {args.world_seed}), friction "
                     f"x{args.friction_scale:g}"
                     if args.pose_noise > 0 or args.friction_scale != 1.0 else "")
        print(f"world_sim: {scene.source}, {len(scene.objects)} objects, {args.engine} physics, "
              f"joint states 50 Hz, object poses 30 Hz, time scale {args.time_scale:g}"
              f"{perturbed}", flush=True)
        print(f"goal to /{NODE_NAME}/plan_rearrangement: plan (seed {args.seed}, time limit "
              f"{args.time_limit:g} s, '{scene.goal.object}' within {planning_radius:.3f} m of "
              f"({scene.goal.position[0]:.2f}, {scene.goal.position[1]:.2f})) and execute "
              f"in world_sim at time scale {args.time_scale:g}, "
              + (f"re-planning up to {args.replan} times ..." if args.replan else
                 "open loop ..."), flush=True)
        goal = PlanRearrangement.Goal(goal_object=scene.goal.object, use_goal_point=True,
                                      execute=True, replan_attempts=args.replan)
        goal.goal_point.x, goal.goal_point.y = (float(v) for v in scene.goal.position)
        seen = outcomes.count()
        reply = client.plan(goal, timeout=(args.replan + 1) * (args.time_limit + 180.0))
        head, *attempts = reply.message.split("; attempt ")
        print("\n  attempt ".join([head, *attempts]), flush=True)
        print(f"error code: {reply.outcome}; recording: {reply.mcap or 'none'}")
        if not reply.result.trajectory.points:
            return 1
        if reply.result.error_code.val == ErrorCode.FRAGILE_PLAN:
            print("node_demo: the plan is fragile and the node did not send it; "
                  "--execute-fragile sends it (the node's parameter execute_fragile)",
                  file=sys.stderr)
            return 1
        outcome = outcomes.wait_next(seen, 30.0)
        time.sleep(1.0)         # a re-plan's executions: their outcomes have all arrived
        for outcome in outcomes.outcomes[seen:]:
            print(f"outcome: {outcome['message']}")
        if reply.result.error_code.val not in (ErrorCode.SUCCESS, ErrorCode.GOAL_NOT_REACHED):
            return 1      # a fragile plan is not sent; an execution or observation failed
        _plot(world, outcome, plot_path,
              f"{Path(scene.source).stem}: open loop in world_sim ({args.engine}), "
              f"{outcome['status']}")
        print(f"top view: {plot_path}")
        return 0 if outcome["status"] == "SUCCEEDED" else 1
    except (BagError, ClientError) as exc:
        print(f"node_demo: {exc}", file=sys.stderr)
        return 1


def _plot(world, outcome: dict, out_path: Path, title: str) -> None:
    """Top view of the execution world_sim recorded: the objects' true paths, the tool."""
    from rearrangement_planner.io.plot import plot_top_view

    record = next(r for r in reversed(world.executions) if r.number == outcome["execution"])
    plot_top_view(world.world, np.array(record.objects), np.array(record.tool), out_path,
                  title=title)


def _wait(predicate, timeout: float) -> bool:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if predicate():
            return True
        time.sleep(0.02)
    return bool(predicate())


if __name__ == "__main__":
    sys.exit(main())
