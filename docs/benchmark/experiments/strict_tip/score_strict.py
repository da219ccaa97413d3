"""Diagnostic (docs/experiments.md, "A push the tipping rule refuses, counted as a topple in the
rollouts"): the answered plans of benchmark runs (their trials.csv and plans/) scored by 20
rollouts of the shipped kind (the tip judgement) and by 20 in which a push the planner's
tipping rule refuses ends the rollout as a failure, the same worlds drawn from seed 7; each
line carries the nominal MuJoCo execution's verdict (servo arm). From the checkout:

    python docs/benchmark/experiments/strict_tip/score_strict.py RUN_DIR [RUN_DIR ...]"""
import csv, dataclasses, json, sys
from pathlib import Path
import numpy as np
from rearrangement_planner.physics.options import PhysicsOptions
from rearrangement_planner.physics.validation import load_scene
from rearrangement_planner.planning.requests import robustness as rb
from rearrangement_planner.model.perturbation import Perturbation

def strict_options(options):
    return dataclasses.replace(rb.rollout_options(options), tipping=True, tip_judgement=False)

def score(scene, arm, seed, strict):
    rng = np.random.default_rng(seed)
    opts = strict_options(PhysicsOptions()) if strict else rb.rollout_options(PhysicsOptions())
    why = [rb.rollout(Perturbation().apply(scene, rng), arm, opts) for _ in range(20)]
    return sum(w == "" for w in why) / 20, why

for folder in sys.argv[1:]:
    folder = Path(folder)
    for row in csv.DictReader(open(folder / "trials.csv")):
        if row["solved"] not in ("True", "1"):
            continue
        plan = np.load(folder / "plans" / f"{row['scene']}__pc-rrt__{row['seed']}.npz")
        scene = load_scene(str(plan["scene_path"]))
        arm = plan["arm_path"]
        s0, w0 = score(scene, arm, 7, False)
        s1, w1 = score(scene, arm, 7, True)
        print(json.dumps({"run": folder.name, "scene": row["scene"], "seed": row["seed"],
                          "robustness": float(row["robustness"]), "ship": s0, "strict": s1,
                          "reached": row["executed_servo"] == "1" and row["executed_toppled"] == "0",
                          "toppled": row["executed_toppled"] not in ("0", ""),
                          "strict_why": {k: w1.count(k) for k in set(w1)}}), flush=True)
