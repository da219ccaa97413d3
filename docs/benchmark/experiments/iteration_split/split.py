"""Where a PC-RRT iteration's time goes: one tree, no shortcut, no selection, up to MAX_ITER
iterations per search, every varied scene with seeds 0 and 1, with wall-clock timers around the
compiled propagation and the Python pieces around it (each timer adds about 0.3 us per call).
Usage: split.py MAX_ITER [SCENE...] (default: the 35 varied scenes)"""
import json
import sys
import time
from pathlib import Path


def main():
    import rearrangement_planner  # noqa: F401  (before numba)
    from rearrangement_planner.physics.validation import load_scene
    from rearrangement_planner.planning.machinery import propagation as pg
    from rearrangement_planner.planning.machinery import push_policy as pp
    from rearrangement_planner.planning.machinery import tree as tr
    from rearrangement_planner.planning.planners import pcrrt as pc
    from rearrangement_planner.planning.requests.warmup import warm_up
    warm_up()
    spent: dict[str, float] = {}
    calls: dict[str, int] = {}

    def timed(owner, name, key):
        original = getattr(owner, name)

        def wrapper(*args, **kwargs):
            t = time.perf_counter()
            try:
                return original(*args, **kwargs)
            finally:
                spent[key] = spent.get(key, 0.0) + time.perf_counter() - t
                calls[key] = calls.get(key, 0) + 1
        setattr(owner, name, wrapper)

    timed(pg, "_propagate_kernel", "compiled propagation (Project + physics)")
    timed(pg, "propagate", "propagate() in all")
    pp.propagate = pg.propagate                # push_policy imported it by name
    pc.constrained_prop.__globals__["propagate"] = pg.propagate
    timed(pc.PCRRT, "_sample", "sample a state")
    timed(pc.PCRRT, "_sample_action", "sample an action")
    timed(tr.Tree, "nearest", "nearest")
    timed(tr.Tree, "add", "tree add")
    timed(pc.PCRRT, "_arm_feature", "arm feature (tool x, y)")
    timed(pc.PCRRT, "_distance", "distance to the sample")
    timed(pc.PCRRT, "_iteration", "iteration in all")
    max_iter = int(sys.argv[1])
    names = sys.argv[2:] or sorted(p.stem for p in Path("config/benchmark/varied").glob("*.yaml"))
    total, iterations, steps = 0.0, 0, 0
    for name in names:
        scene = load_scene(f"config/benchmark/varied/{name}.yaml")
        for seed in (0, 1):
            t = time.perf_counter()
            r = pc.PCRRT(scene, pc.PCRRTOptions(max_iterations=max_iter)).plan(seed=seed)
            total += time.perf_counter() - t
            iterations += r.iterations
            steps += r.propagation_steps
    kernel = spent["compiled propagation (Project + physics)"]
    rows = {key: {"s": round(v, 3), "share": round(v / total, 3), "calls": calls[key],
                  "us_per_iteration": round(v / iterations * 1e6, 1)}
            for key, v in spent.items()}
    rows["propagate() around the compiled call"] = {
        "s": round(spent["propagate() in all"] - kernel, 3),
        "share": round((spent["propagate() in all"] - kernel) / total, 3),
        "us_per_iteration": round((spent["propagate() in all"] - kernel) / iterations * 1e6, 1)}
    print(json.dumps({"searches": 2 * len(names), "max_iterations": max_iter, "seconds": round(total, 2),
                      "iterations": iterations, "steps": steps,
                      "us_per_iteration": round(total / iterations * 1e6, 1),
                      "us_per_step_compiled": round(kernel / steps * 1e6, 2), "parts": rows},
                     indent=1))


if __name__ == "__main__":
    main()
