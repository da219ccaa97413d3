"""When a toppled plan's goal object first strays from its predicted pose in a servo execution."""
import sys, json
from pathlib import Path
import numpy as np
from rearrangement_planner.tools.benchmark import plan_file, load_trial_scene, read_trials
from rearrangement_planner.planning.requests.trajectory import time_parameterize, DUPLICATE_TOLERANCE
from rearrangement_planner.execution.mujoco_check import check_execution, ExecutionOptions
from rearrangement_planner.physics.step import Physics
from rearrangement_planner.physics.options import PhysicsOptions

out = Path(sys.argv[1])
for row in read_trials(out / "trials.csv"):
    if row["solved"] != "1" or row["planner"] != "pc-rrt":
        continue
    plan = np.load(plan_file(out / "plans", row))
    scene = load_trial_scene(str(plan["scene_path"]), str(plan["robot"]))
    arm = plan["arm_path"]
    ph = Physics(scene, PhysicsOptions())
    states = [scene.initial_state()]
    for q in arm[1:]:
        r = ph.step(states[-1], q)
        states.append(r.state if r.valid else states[-1].__class__(q=q, objects=states[-1].objects) if False else r.state)
    keep = [0] + [i for i in range(1, len(arm)) if np.max(np.abs(arm[i] - arm[i - 1])) > DUPLICATE_TOLERANCE]
    traj = time_parameterize(scene.robot, arm)
    if len(keep) != len(traj.times):
        print("mismatch", row["scene"], len(keep), len(traj.times)); continue
    pred = [states[i] for i in keep]
    rep = check_execution(scene, traj, pred, ExecutionOptions(arm=sys.argv[2]))
    g = rep.objects[scene.goal_index]
    first_push = next((traj.times[j] for j in range(1, len(pred)) if np.any(pred[j].objects[scene.goal_index] != pred[j-1].objects[scene.goal_index])), None)
    print(json.dumps({"scene": row["scene"], "seed": row["seed"], "planner": row["planner"], "toppled": rep.toppled, "reached": row["executed_servo"],
        "goal_err_from": g.error_from_s, "goal_final_err": round(g.final_error_m or 0, 3), "goal_largest": round(g.max_error_m or 0, 3),
        "first_goal_push_t": None if first_push is None else round(float(first_push), 2), "duration": round(traj.duration, 1),
        "others_err_from": [o.error_from_s for i, o in enumerate(rep.objects) if i != scene.goal_index],
        "contacts": list(rep.object_contacts), "tracking": round(rep.max_tracking_error_rad, 4)}), flush=True)
