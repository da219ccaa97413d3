"""Time to a first plan of one PC-RRT tree, many seeds per scene: does a search's run time
have a heavy tail that restarts would cut? Usage: sweep.py OUT.jsonl MAX_ITER SEEDS SCENE..."""
import sys, json, multiprocessing as mp

def work(args):
    names, seeds, max_iter = args
    from rearrangement_planner.physics.validation import load_scene
    from rearrangement_planner.planning.planners.pcrrt import PCRRT, PCRRTOptions
    from rearrangement_planner.planning.requests.warmup import warm_up
    warm_up()
    out = []
    for name in names:
        scene = load_scene(f"config/benchmark/varied/{name}.yaml")
        for seed in seeds:
            r = PCRRT(scene, PCRRTOptions(max_iterations=max_iter)).plan(seed=seed)
            row = {"scene": name, "seed": seed, "solved": r.solved, "iterations": r.iterations,
                   "steps": r.propagation_steps, "time": round(r.plan_time, 3)}
            print(json.dumps(row), flush=True)
            out.append(row)
    return out

if __name__ == "__main__":
    out, max_iter, n = sys.argv[1], int(sys.argv[2]), int(sys.argv[3])
    names = sys.argv[4:]
    jobs = [(names[i::2], range(n), max_iter) for i in range(2)]
    with mp.get_context("spawn").Pool(2) as pool:
        results = pool.map(work, jobs)
    with open(out, "w") as f:
        for part in results:
            for r in part:
                f.write(json.dumps(r) + "\n")
