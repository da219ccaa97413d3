"""Search effectiveness of PC-RRT settings: one tree, the planner's own options, bounded by
iterations (machine-independent), on the varied scenes; prints one line per search."""
import sys, glob, os, json
from rearrangement_planner.physics.validation import load_scene
from rearrangement_planner.planning.planners.pcrrt import PCRRT, PCRRTOptions
from rearrangement_planner.planning.requests.warmup import warm_up
warm_up()
SETTINGS = {"default": {}, "push_goal_share=0.8": {"push_goal_share": 0.8},
            "push_bias=0.9": {"push_bias": 0.9}, "goal_bias=0.4": {"goal_bias": 0.4},
            "goal_weight=10": {"goal_weight": 10.0}, "push_steps=50": {"push_steps": 50},
            "k_actions=2": {"k_actions": 2}}
names = sorted(os.path.basename(p)[:-5] for p in glob.glob("config/benchmark/varied/v*_s*.yaml"))
out = open(sys.argv[1], "a")
for name in names:
    scene = load_scene(f"config/benchmark/varied/{name}.yaml")
    for seed in (0, 1):
        for label, kw in SETTINGS.items():
            r = PCRRT(scene, PCRRTOptions(max_iterations=4000, **kw)).plan(seed=seed)
            out.write(json.dumps({"scene": name, "seed": seed, "setting": label,
                                  "solved": r.solved, "iterations": r.iterations,
                                  "steps": r.propagation_steps, "time": round(r.plan_time, 3)}) + "\n")
            out.flush()
