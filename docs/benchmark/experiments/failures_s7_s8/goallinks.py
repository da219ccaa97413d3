"""Which links push the goal object in each solved plan, and whether the plan reached."""
import sys, json
from pathlib import Path
import numpy as np
from rearrangement_planner.tools.benchmark import plan_file, load_trial_scene, read_trials
from rearrangement_planner.physics.step import Physics
from rearrangement_planner.physics.options import PhysicsOptions
for out in sys.argv[1:]:
    out = Path(out)
    for row in read_trials(out / "trials.csv"):
        if row["solved"] != "1": continue
        p = plan_file(out / "plans", row)
        if not p.is_file(): continue
        plan = np.load(p)
        scene = load_trial_scene(str(plan["scene_path"]), str(plan["robot"]))
        g = scene.goal_index; ph = Physics(scene, PhysicsOptions(tipping=False, max_turn=0.0))
        st = scene.initial_state(); goal_links = {}; other_links = {}
        for q in plan["arm_path"][1:]:
            r = ph.step(st, q)
            if r.valid and r.moved_objects:
                d = goal_links if g in r.moved_objects else other_links
                travel = 1.0
                for l in r.pushing_links: d[l.replace("panda_", "")] = d.get(l.replace("panda_", ""), 0) + 1
            st = r.state
        print(json.dumps({"scene": row["scene"], "seed": row["seed"], "planner": row["planner"], "reached": row["executed_servo"], "toppled": row["executed_toppled"], "goal": goal_links, "other": other_links}), flush=True)
