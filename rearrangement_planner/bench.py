"""`rearrangement-bench`: benchmarks.

    rearrangement-bench physics [--seconds S] [--json OUT]
    rearrangement-bench scenes [--scenes NAME ...] [--planners P ...] [--seeds N ...]
                               [--time-limit S] [--jsonl OUT]

measures the throughput of the quasistatic physics step (DESIGN §5) on the Panda at the default
scene's table: the arm, folded low so that forearm and wrist sweep at object height, rotates
about joint 1 through 1 and through 7 objects placed in its path, again and again. It prints a
JSON record: physics steps per second (one `Physics.step` call moving joint 1 by
`STEP_RAD`), substeps per second, the share of the time spent in contact and collision queries,
and how many steps moved an object (so that the figure is measured in contact, not in free
space).
"""

from __future__ import annotations

import argparse
import json
import math
import platform
import sys
import time
from pathlib import Path

from .physics import Physics
from .resources import scenes_dir
from .scene import Scene, load_scene, parse_scene

# Joint configuration with the forearm sloping down to 7 cm and the wrist at object height.
LOW_ARM = (-0.7677, 1.7127, 1.0578, -1.7876, 1.2966, 0.8244, -0.8218)
STEP_RAD = 0.005        # joint-1 motion per physics step: about 2.5 mm at the wrist
SWEEP_STEPS = 150       # steps per sweep, then the sweep starts again from the start state

# Objects in the sweep's path: (radius from the base, angle ahead of the arm), metres/radians.
ONE_OBJECT = [(0.43, 0.45)]
SEVEN_OBJECTS = [(0.43, 0.45), (0.56, 0.78), (0.36, 0.80), (0.50, 1.02), (0.65, 0.60),
                 (0.42, 1.18), (0.64, 1.00)]


def sweep_scene(placements: list[tuple[float, float]]) -> Scene:
    """The default scene's robot and table with cylinders at the given polar placements."""
    default = load_scene(scenes_dir() / "default.yaml")
    data = default.to_dict()
    data["start_configuration"] = list(LOW_ARM)
    data.pop("obstacles", None)
    data["objects"] = [
        {"name": f"object{i}", "shape": "cylinder", "radius": 0.03, "height": 0.12,
         "pose": [r * math.cos(a), r * math.sin(a), 0.0]}
        for i, (r, a) in enumerate(placements)]
    data["goal"] = {"object": "object0", "position": [0.5, 0.0], "radius": 0.1}
    return parse_scene(data, name=f"physics sweep, {len(placements)} objects",
                       robot=default.robot)


class _Timed:
    """Wraps a bound method and adds its run time to a shared counter."""

    def __init__(self, fn, totals: dict, key: str):
        self.fn, self.totals, self.key = fn, totals, key

    def __call__(self, *args, **kwargs):
        start = time.perf_counter()
        try:
            return self.fn(*args, **kwargs)
        finally:
            self.totals[self.key] += time.perf_counter() - start


def measure_physics(scene: Scene, seconds: float) -> dict:
    physics = Physics(scene)
    totals = {"contact_queries": 0.0}
    world = physics.world
    for name in ("arm_object_contacts", "arm_static_collision", "object_overlaps",
                 "object_obstacle_overlaps", "objects_off_table"):
        setattr(world, name, _Timed(getattr(world, name), totals, "contact_queries"))
    start_state = scene.initial_state()
    steps = substeps = pushing_steps = invalid = 0
    links: set[str] = set()
    t0 = time.perf_counter()
    while time.perf_counter() - t0 < seconds:
        state = start_state
        for _ in range(SWEEP_STEPS):
            q = state.q.copy()
            q[0] += STEP_RAD
            result = physics.step(state, q)
            steps += 1
            substeps += result.substeps
            if not result.valid:
                invalid += 1
                break
            if result.moved_objects:
                pushing_steps += 1
                links |= result.pushing_links
            state = result.state
    elapsed = time.perf_counter() - t0
    return {
        "objects": len(scene.objects),
        "steps": steps,
        "steps_per_second": round(steps / elapsed, 1),
        "substeps_per_second": round(substeps / elapsed, 1),
        "steps_pushing_share": round(pushing_steps / steps, 3),
        "contact_query_time_share": round(totals["contact_queries"] / elapsed, 3),
        "invalid_steps": invalid,
        "pushing_links": sorted(links),
    }


def physics_benchmark(seconds: float) -> dict:
    return {
        "benchmark": "physics",
        "step": f"Physics.step moving joint 1 by {STEP_RAD} rad (arm folded low, sweeping)",
        "python": platform.python_version(),
        "machine": platform.machine(),
        "results": [measure_physics(sweep_scene(ONE_OBJECT), seconds),
                    measure_physics(sweep_scene(SEVEN_OBJECTS), seconds)],
    }


def scene_trial(scene_name: str, planner: str, seed: int, time_limit: float) -> dict:
    """One planner run on one shipped scene: outcome, plan time and which objects moved."""
    from .pipeline import plan_scene
    from .planner import PlannerOptions

    scene = load_scene(scene_name)
    result = plan_scene(scene, planner, PlannerOptions(time_limit=time_limit), seed=seed).result
    moved: list[str] = []
    if result.states:
        first = result.states[0].objects
        moved = [o.name for i, o in enumerate(scene.objects)
                 if any(not (s.objects[i] == first[i]).all() for s in result.states)]
    return {"scene": scene_name, "planner": planner, "seed": seed,
            "outcome": result.outcome.value, "plan_time_s": round(result.plan_time, 2),
            "iterations": result.iterations, "moved": moved,
            "best_goal_distance_m": round(result.best_goal_distance, 3)}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="rearrangement-bench",
        description="Benchmarks of the rearrangement planner.")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    phys = sub.add_parser(
        "physics", help="physics steps per second with 1 and 7 objects in contact range",
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    phys.add_argument("--seconds", type=float, default=5.0,
                      help="measuring time per scene, s (default 5)")
    phys.add_argument("--json", type=Path, help="also write the JSON record to this file")
    scenes = sub.add_parser(
        "scenes", help="each planner on each shipped scene with several seeds (one line of "
                       "JSON per run: outcome, plan time, objects moved)")
    scenes.add_argument("--scenes", nargs="+", default=["easy_push", "default", "clutter",
                                                        "seven_objects"],
                        help="shipped scene names or scene files")
    scenes.add_argument("--planners", nargs="+", default=["pc-rrt", "static-rrt", "darrt"],
                        choices=["pc-rrt", "static-rrt", "darrt"])
    scenes.add_argument("--seeds", nargs="+", type=int, default=[0, 1, 2])
    scenes.add_argument("--time-limit", type=float, default=60.0, metavar="S",
                        help="planning budget per run, s (default 60)")
    scenes.add_argument("--jsonl", type=Path, help="also append the lines to this file")
    args = parser.parse_args(argv)
    if args.command == "scenes":
        if not args.time_limit > 0:
            parser.error("--time-limit must be positive")
        for scene_name in args.scenes:
            for planner in args.planners:
                for seed in args.seeds:
                    line = json.dumps(scene_trial(scene_name, planner, seed, args.time_limit))
                    print(line, flush=True)
                    if args.jsonl:
                        with args.jsonl.open("a") as f:
                            f.write(line + "\n")
        return 0
    if args.command != "physics":
        parser.print_help(sys.stderr)
        return 2
    if not args.seconds > 0:
        parser.error("--seconds must be positive")
    record = physics_benchmark(args.seconds)
    text = json.dumps(record, indent=2)
    print(text)
    if args.json:
        args.json.write_text(text + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
