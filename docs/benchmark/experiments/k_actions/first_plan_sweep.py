"""Search effectiveness of PC-RRT settings, a screen: one tree, PC-RRT alone (no shortcut, no
selection), bounded by 4,000 iterations, on the 35 varied scenes with seeds 0 and 1; two
processes. Usage (from the repository root): first_plan_sweep.py OUT.jsonl SETTING=VALUE|default ..."""
import sys, glob, os, json, multiprocessing as mp

def work(args):
    names, settings, seeds = args
    from rearrangement_planner.physics.validation import load_scene
    from rearrangement_planner.planning.planners.pcrrt import PCRRT, PCRRTOptions
    from rearrangement_planner.planning.requests.warmup import warm_up
    warm_up()
    out = []
    for name in names:
        scene = load_scene(f"config/benchmark/varied/{name}.yaml")
        for seed in seeds:
            for label in settings:
                kw = {} if label == "default" else {label.split("=")[0]: float(label.split("=")[1]) if "." in label else int(label.split("=")[1])}
                r = PCRRT(scene, PCRRTOptions(max_iterations=4000, **kw)).plan(seed=seed)
                out.append({"scene": name, "seed": seed, "setting": label, "solved": r.solved,
                            "iterations": r.iterations, "steps": r.propagation_steps,
                            "time": round(r.plan_time, 3)})
    return out

if __name__ == "__main__":
    names = sorted(os.path.basename(p)[:-5] for p in glob.glob("config/benchmark/varied/v*_s*.yaml"))
    settings = sys.argv[2:]
    jobs = [(names[i::2], settings, (0, 1)) for i in range(2)]
    with mp.get_context("spawn").Pool(2) as pool:
        results = pool.map(work, jobs)
    with open(sys.argv[1], "w") as f:
        for part in results:
            for r in part:
                f.write(json.dumps(r) + "\n")
