"""Re-time saved plans with other TimingOptions and execute them (servo, nominal) in MuJoCo."""
import sys, json, time, numpy as np
from pathlib import Path
from rearrangement_planner.tools.benchmark import load_trial_scene, read_trials, plan_file
from rearrangement_planner.planning.requests.trajectory import time_parameterize, TimingOptions
from rearrangement_planner.execution.mujoco_check import check_execution, ExecutionOptions, check_perturbed

out = Path(sys.argv[1]); variants = json.loads(sys.argv[2]); perturbed = int(sys.argv[3]) if len(sys.argv) > 3 else 0
tot = {k: [0, 0, 0, 0.0, 0, 0] for k in variants}
for row in read_trials(out / "trials.csv"):
    if row["solved"] != "1":
        continue
    plan = np.load(plan_file(out / "plans", row))
    scene = load_trial_scene(str(plan["scene_path"]), str(plan["robot"]))
    line = [row["scene"], "csv:" + row["executed_servo"] + ("T" if row["executed_toppled"] not in ("0", "") else "")]
    for name, opts in variants.items():
        traj = time_parameterize(scene.robot, plan["arm_path"], TimingOptions(**opts))
        rep = check_execution(scene, traj, None, ExecutionOptions(arm="servo"))
        t = tot[name]; t[0] += rep.reached; t[1] += bool(rep.toppled); t[2] += 1; t[3] += traj.duration
        s = f"{name}:{int(rep.reached)}{'T' if rep.toppled else ''}/{traj.duration:.0f}s"
        if perturbed:
            pr = check_perturbed(scene, traj, perturbed, int(row["seed"]), ExecutionOptions(arm="servo"))
            k = sum(r.reached for r in pr.reports) if hasattr(pr, "reports") else round(pr.success_rate * perturbed)
            t[4] += k; t[5] += perturbed; s += f" p{k}"
        line.append(s)
    print(" ".join(line), flush=True)
for k, t in tot.items():
    print(f"TOTAL {k}: reached {t[0]}/{t[2]} toppled {t[1]} mean duration {t[3]/max(t[2],1):.1f}s perturbed {t[4]}/{t[5]}")
