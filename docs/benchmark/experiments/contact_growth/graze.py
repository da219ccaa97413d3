"""How far MuJoCo moves the goal object while the model leaves it still (the arm grazes it
where the model's contact shapes pass clear, or it slides on after a push): per plan, the
executed motion over trajectory intervals in which the model's goal object does not move,
split into the first 0.3 s after a model push (coasting) and the rest (an unmodelled touch).
Usage: graze.py RUN_DIR PLANNER OUT.jsonl"""
import sys, json, math, multiprocessing as mp
from pathlib import Path
import numpy as np

def work(job):
    import rearrangement_planner  # noqa
    from rearrangement_planner.tools.benchmark import load_trial_scene
    from rearrangement_planner.planning.requests.trajectory import time_parameterize, DUPLICATE_TOLERANCE
    from rearrangement_planner.execution.mujoco_check import check_execution, ExecutionOptions
    from rearrangement_planner.physics.step import Physics
    from rearrangement_planner.physics.options import PhysicsOptions
    from rearrangement_planner.planning.requests.robustness import rollout_options, rollout_kernel
    out = []
    for path in job:
        plan = np.load(path)
        p = str(plan["scene_path"]); scene = load_trial_scene(p[p.index("config/"):], "")
        arm = np.array(plan["arm_path"], dtype=float)
        keep = [0] + [i for i in range(1, len(arm)) if np.max(np.abs(arm[i] - arm[i - 1])) > DUPLICATE_TOLERANCE]
        traj = time_parameterize(scene.robot, arm)
        ph = Physics(scene, rollout_options(PhysicsOptions()))
        objects = np.empty((len(arm), *scene.object_poses.shape)); objects[0] = scene.object_poses
        if rollout_kernel(arm, objects, ph.arrays, ph.flag_count) != 0:
            continue
        rep = check_execution(scene, traj, None, ExecutionOptions(arm="servo"))
        row = {"plan": Path(path).name, "reached": bool(rep.reached), "objects": len(scene.objects)}
        for label, idx in (("goal", [scene.goal_index]), ("others", [i for i in range(len(scene.objects)) if i != scene.goal_index])):
            coast = touch = pushed = 0.0
            touch_events = 0
            for m in idx:
                pred = objects[keep, m]
                exe = rep.executed_paths[:, m]
                last_push_t = -1e9
                in_touch = False
                for k in range(1, len(keep)):
                    dm = float(np.hypot(*(pred[k, :2] - pred[k - 1, :2])))
                    de = float(np.hypot(*(exe[k, :2] - exe[k - 1, :2])))
                    if dm > 1e-5:
                        pushed += de; last_push_t = traj.times[k]; in_touch = False
                    elif traj.times[k] - last_push_t <= 0.3:
                        coast += de
                    else:
                        touch += de
                        if de > 0.002 and not in_touch:
                            touch_events += 1; in_touch = True
                        elif de <= 0.002:
                            in_touch = False
            row[label] = {"coast": round(coast, 4), "touch": round(touch, 4), "pushed": round(pushed, 4), "touch_events": touch_events}
        print(json.dumps(row), flush=True)
        out.append(row)
    return out

if __name__ == "__main__":
    import csv
    from rearrangement_planner.tools.benchmark import plan_file
    run = Path(sys.argv[1])
    rows = [r for r in csv.DictReader(open(run / "trials.csv")) if r["planner"] == sys.argv[2] and r["solved"] == "1"]
    paths = [str(plan_file(run / "plans", r)) for r in rows]
    with mp.get_context("spawn").Pool(2) as pool:
        parts = pool.map(work, [paths[0::2], paths[1::2]])
    with open(sys.argv[3], "w") as f:
        for part in parts:
            for r in part: f.write(json.dumps(r) + "\n")
