"""Which solved plans would a tipping rule judged at the top of the wrist's capsules
(`PhysicsOptions.wrist_tip_at_top`) flag, against which plans toppled an object in MuJoCo?
Replays each plan's arm path in the model: the rollout's tip judgement (TOPPLED) and the
planner's tipping rule (the first refused step), with the rule on ("wrist") and off ("off").
Usage: classify.py RUN_DIR... (runs of `rearrangement-bench run`, their pc-rrt rows)"""
import csv
import sys
from pathlib import Path

import numpy as np


def run_plan(arm, scene, options, judge):
    import math
    from rearrangement_planner.physics import step as st
    ph = st.Physics(scene, options)
    world = ph.arrays
    M = len(scene.objects)
    objects = np.empty((len(arm), M, 3))
    objects[0] = scene.object_poses
    work = st.step_workspace(world, arm[0], objects[0])
    info = np.zeros(4 + ph.flag_count, dtype=np.int64)
    value = np.zeros(1 + M)
    carried = np.zeros(M)
    for i in range(1, len(arm)):
        info[:] = 0
        value[:] = 0.0
        code = st.step_kernel(arm[i - 1], arm[i], objects[i - 1], world, objects[i], info,
                              value, work)
        if code != 0:
            return f"invalid{code}" + (f"@{value[0]:.3f}" if code == st._TIPPING else "")
        if judge:
            for m in range(M):
                if value[1 + m] > 0.0:
                    carried[m] += math.hypot(*(objects[i, m, :2] - objects[i - 1, m, :2]))
                    if carried[m] >= value[1 + m]:
                        return f"toppled:{scene.objects[m].name}"
                else:
                    carried[m] = 0.0
    return "ok"


def main():
    import rearrangement_planner  # noqa: F401  (before numba)
    from rearrangement_planner.physics.options import PhysicsOptions
    from rearrangement_planner.planning.requests.robustness import rollout_options
    from rearrangement_planner.tools.benchmark import load_trial_scene, plan_file
    for run in map(Path, sys.argv[1:]):
        for row in csv.DictReader(open(run / "trials.csv")):
            if row["planner"] != "pc-rrt" or row["solved"] != "1":
                continue
            plan = np.load(plan_file(run / "plans", row))
            p = str(plan["scene_path"])
            scene = load_trial_scene(p[p.index("config/"):], "")
            arm = np.array(plan["arm_path"], dtype=float)
            out = {"scene": row["scene"], "seed": row["seed"],
                   "toppled": row["executed_toppled"], "reached": row["executed_servo"]}
            for name, on in (("off", False), ("wrist", True)):
                planner = PhysicsOptions(wrist_tip_at_top=on)
                out["rule_" + name] = run_plan(arm, scene, planner, False)
                out["judge_" + name] = run_plan(arm, scene, rollout_options(planner), True)
            print(out, flush=True)


if __name__ == "__main__":
    main()
