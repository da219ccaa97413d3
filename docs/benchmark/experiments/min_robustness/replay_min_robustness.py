"""A lower min_robustness, replayed on a run of the shipped default (planner 'pc-rrt') beside
its first candidate alone (any other label, e.g. 'pc-rrt:candidates=1'), same seeds: where the
first candidate scored at least the threshold, the request answers with it (that arm's row),
else as shipped. 'switched': requests whose answer changes. Usage:
python3 replay_min_robustness.py TRIALS.csv"""
import csv, sys, statistics
rows = list(csv.DictReader(open(sys.argv[1])))
ship = {(r["scene"], r["seed"]): r for r in rows if r["planner"] == "pc-rrt"}
first = {(r["scene"], r["seed"]): r for r in rows if r["planner"] != "pc-rrt"}
def reached(r): return r["executed_servo"] == "1" and r["executed_toppled"] in ("0",)
def topp(r): return r["executed_toppled"] not in ("", "0")
for thr in (1.01, 1.0, 0.95, 0.9, 0.85, 0.8, 0.75, 0.7, 0.6):
    R = T = 0; times = []; pert = 0; n = 0; switched = 0
    for k, s in ship.items():
        f = first[k]
        use = f if (f["robustness"] and float(f["robustness"]) >= thr) else s
        switched += use is f and s is not f and s["candidates"] != "1"
        R += reached(use); T += topp(use); times.append(float(use["plan_time_s"]))
        if use["perturbed_trials"]: pert += int(use["perturbed_reached"]); n += int(use["perturbed_trials"])
    print(f"thr {thr}: reached {R}/{len(ship)} toppling {T} median {statistics.median(times):.2f} perturbed {pert}/{n} switched {switched}")
