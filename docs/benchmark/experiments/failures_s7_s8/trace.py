import sys, numpy as np
from pathlib import Path
from rearrangement_planner.tools.benchmark import plan_file, load_trial_scene, read_trials
from rearrangement_planner.planning.requests.trajectory import time_parameterize, DUPLICATE_TOLERANCE
from rearrangement_planner.execution.mujoco_check import check_execution, ExecutionOptions
from rearrangement_planner.physics.step import Physics
from rearrangement_planner.physics.options import PhysicsOptions
out = Path(sys.argv[1]); scene_name, seed, planner = sys.argv[2], sys.argv[3], sys.argv[4]
row = next(r for r in read_trials(out / "trials.csv") if r["scene"] == scene_name and r["seed"] == seed and r["planner"] == planner)
plan = np.load(plan_file(out / "plans", row))
scene = load_trial_scene(str(plan["scene_path"]), str(plan["robot"]))
arm = plan["arm_path"]; ph = Physics(scene, PhysicsOptions())
states = [scene.initial_state()]; links = [""]
for q in arm[1:]:
    r = ph.step(states[-1], q); states.append(r.state); links.append(",".join(sorted(l.replace("panda_","") for l in r.pushing_links)) if r.moved_objects else "")
keep = [0] + [i for i in range(1, len(arm)) if np.max(np.abs(arm[i] - arm[i - 1])) > DUPLICATE_TOLERANCE]
traj = time_parameterize(scene.robot, arm)
pred = [states[i] for i in keep]; plinks = [links[i] for i in keep]
rep = check_execution(scene, traj, pred, ExecutionOptions(arm="ideal"))
g = scene.goal_index; ex = rep.executed_paths[:, g]
pp = np.array([s.objects[g] for s in pred])
first = next(j for j in range(1, len(pp)) if np.any(pp[j] != pp[j-1]))
step = int(sys.argv[5]) if len(sys.argv) > 5 else 5
for j in range(first - 5, min(len(pp), first + 400), step):
    print(f"t={traj.times[j]:6.2f} pred {pp[j,0]:.3f},{pp[j,1]:.3f},{pp[j,2]:+.2f}  exec {ex[j,0]:.3f},{ex[j,1]:.3f},{ex[j,2]:+.2f}  err {np.hypot(*(pp[j,:2]-ex[j,:2]))*1000:5.1f}mm  {plinks[j]}")
