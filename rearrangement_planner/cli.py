"""`rearrangement-plan SCENE.yaml`: plan one scene from the command line (DESIGN §8).

Exit codes: 0 solved, 1 not solved (timeout, start invalid, ...), 2 bad input (one line naming
the problem). The JSON result holds the fields of DESIGN §8; `--plot` writes a top view.
"""

from __future__ import annotations

import argparse
import json
import logging
import sys
import time
from pathlib import Path

import numpy as np

from .errors import RearrangementError
from .planner import PCRRT, PlannerOptions, PlanResult, Progress
from .scene import Scene, load_scene
from .trajectory import TimingOptions, Trajectory, time_parameterize

PLANNERS = ("pc-rrt",)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="rearrangement-plan",
        description="Plan a nonprehensile whole-arm rearrangement for one scene: the arm pushes "
                    "objects (any link, several at once) until the goal object is inside its "
                    "goal region. Exit code 0 = solved, 1 = not solved, 2 = bad input.")
    parser.add_argument("scene", type=Path, help="scene YAML file (DESIGN §3 format)")
    parser.add_argument("--planner", choices=PLANNERS, default="pc-rrt",
                        help="planning algorithm (default: pc-rrt, the physics-constrained "
                             "kinodynamic RRT of King et al.)")
    parser.add_argument("--time-limit", type=float, default=60.0, metavar="S",
                        help="planning budget in seconds; running out is a failure (default 60)")
    parser.add_argument("--seed", type=int, default=0, metavar="N",
                        help="random seed: the same scene, options and seed give the same plan "
                             "(default 0)")
    parser.add_argument("--shortcut", type=float, default=0.0, metavar="S",
                        help="seconds of path shortcutting after a plan is found (default 0: "
                             "none; shortcutting is not built yet and must be 0)")
    parser.add_argument("--json", type=Path, metavar="OUT",
                        help="write the result as JSON to OUT ('-' for standard output)")
    parser.add_argument("--record", type=Path, metavar="OUT.mcap",
                        help="record the plan to an MCAP file (arrives with the recording work)")
    parser.add_argument("--plot", type=Path, metavar="OUT.png",
                        help="write a top view PNG: table, objects at start and end, their "
                             "paths, the end-effector path and the goal region")
    parser.add_argument("--quiet", action="store_true", help="no progress line on stderr")
    return parser


def path_metrics(scene: Scene, result: PlanResult) -> dict:
    """Arm path length (joint space, rad; tool, m) and total object displacement (m)."""
    robot = scene.robot
    arm = result.arm_path
    tool = np.array([robot.tool_pose(q)[:3, 3] for q in arm])
    objects = np.array([s.objects[:, :2] for s in result.states])
    return {
        "path_length_rad": float(np.linalg.norm(np.diff(arm, axis=0), axis=1).sum()),
        "ee_path_length_m": float(np.linalg.norm(np.diff(tool, axis=0), axis=1).sum()),
        "object_displacement_m": float(np.linalg.norm(np.diff(objects, axis=0), axis=2).sum()),
    }


def trajectory_dict(trajectory: Trajectory) -> dict:
    return {
        "joint_names": list(trajectory.joint_names),
        "points": [{"positions": p.tolist(), "velocities": v.tolist(), "time_from_start": t}
                   for t, p, v in zip(trajectory.times.tolist(), trajectory.positions,
                                      trajectory.velocities, strict=True)],
    }


def result_dict(scene: Scene, planner: str, result: PlanResult,
                trajectory: Trajectory | None) -> dict:
    final = result.states[-1].objects if result.states else scene.object_poses
    record = {
        "solved": result.solved,
        "outcome": result.outcome.value,
        "message": result.message,
        "planner": planner,
        "seed": result.seed,
        "plan_time_s": result.plan_time,
        "iterations": result.iterations,
        "tree_size": result.tree_size,
        "propagation_steps": result.propagation_steps,
        "path_length_rad": None, "ee_path_length_m": None, "object_displacement_m": None,
        "goal_distance_m": float(scene.goal.distance(final[scene.goal_index, :2])),
        "final_object_poses": {o.name: final[i].tolist() for i, o in enumerate(scene.objects)},
        "trajectory": trajectory_dict(trajectory) if trajectory is not None else None,
    }
    if result.solved:
        record.update(path_metrics(scene, result))
    return record


def _progress_printer(quiet: bool):
    if quiet:
        return None

    def show(p: Progress) -> None:
        print(f"\rplanning: {p.elapsed:5.1f} s, {p.iterations} iterations, tree {p.tree_size}, "
              f"best goal distance {p.best_goal_distance:.3f} m", end="", file=sys.stderr,
              flush=True)

    return show


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.WARNING, format="%(message)s")
    try:
        if not args.time_limit > 0:
            raise RearrangementError(f"--time-limit must be positive, got {args.time_limit}")
        if args.shortcut != 0:
            raise RearrangementError("--shortcut: shortcutting is not built yet; use 0")
        if args.record is not None:
            raise RearrangementError("--record: MCAP recording is not built yet")
        scene = load_scene(args.scene)
    except RearrangementError as exc:
        print(f"rearrangement-plan: {exc}", file=sys.stderr)
        return 2
    planner = PCRRT(scene, PlannerOptions(time_limit=args.time_limit))
    started = time.monotonic()
    result = planner.plan(seed=args.seed, progress=_progress_printer(args.quiet))
    if not args.quiet:
        print(f"\r{result.outcome.value}: {result.message} "
              f"({time.monotonic() - started:.1f} s)", file=sys.stderr)
    trajectory = None
    if result.solved:
        trajectory = time_parameterize(scene.robot, result.arm_path, TimingOptions())
    record = result_dict(scene, args.planner, result, trajectory)
    text = json.dumps(record, indent=2)
    if args.json is not None:
        if str(args.json) == "-":
            print(text)
        else:
            args.json.write_text(text + "\n")
    if args.plot is not None:
        from .plot import plot_top_view  # matplotlib only when asked for

        robot = scene.robot
        states = result.states or (scene.initial_state(),)
        ee = np.array([robot.tool_pose(s.q)[:2, 3] for s in states]) if result.states \
            else np.zeros((0, 2))
        plot_top_view(scene, np.array([s.objects for s in states]), ee, args.plot,
                      title=f"{scene.source}: {result.outcome.value.lower()}, seed {args.seed}",
                      start_states_only=not result.solved)
    if not args.quiet:
        summary = {k: record[k] for k in ("solved", "plan_time_s", "iterations",
                                          "goal_distance_m")}
        print(json.dumps(summary), file=sys.stderr)
    return 0 if result.solved else 1


if __name__ == "__main__":
    sys.exit(main())
