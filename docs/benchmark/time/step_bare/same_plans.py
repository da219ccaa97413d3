"""PC-RRT with the shipped options, seed 0, 1500 iterations (or the plan) on varied scenes:
counts, and the states of the plan / the tree's last nodes, saved to compare two commits."""
import sys, time, json
from pathlib import Path
import numpy as np
from rearrangement_planner.planning.planners.pcrrt import PCRRT, PCRRTOptions
from rearrangement_planner.planning.requests.warmup import warm_up
from rearrangement_planner.tools.benchmark import load_trial_scene
warm_up()
out = {}
for name in sys.argv[1].split(","):
    scene = load_trial_scene(Path("config/benchmark/varied") / f"{name}.yaml")
    planner = PCRRT(scene, PCRRTOptions(time_limit=1000, max_iterations=int(sys.argv[2])))
    t = time.perf_counter(); r = planner.plan(seed=0); s = time.perf_counter() - t
    states = [np.concatenate([x.q, x.objects.ravel()]).tolist() for x in r.states]
    out[name] = {"counts": [r.iterations, r.propagation_steps, r.tree_size], "best": r.best_goal_distance,
                 "solved": r.solved, "states": states, "seconds": s}
    print(name, r.iterations, r.propagation_steps, r.tree_size, r.solved, round(s, 2), flush=True)
Path(sys.argv[3]).write_text(json.dumps(out))
