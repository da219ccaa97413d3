"""Which nominal support pressure (c scale) predicts MuJoCo best? Every solved plan of a run,
executed once in MuJoCo with the servo arm, and replayed in the rollout physics with every
object's c scaled by each of SCALES (centre of friction at the centre): the goal object's
final position and yaw error against MuJoCo's. Usage (from the repository root): cscale.py RUN_DIR PLANNER OUT.jsonl"""
import sys, json, math, dataclasses, multiprocessing as mp
from pathlib import Path
import numpy as np

SCALES = (0.8, 1.0, 1.3, 1.6, 1.85)

def work(job):
    import rearrangement_planner  # noqa: F401  (before numba: the cache dir)
    from rearrangement_planner.tools.benchmark import plan_file, load_trial_scene
    from rearrangement_planner.planning.requests.trajectory import time_parameterize, DUPLICATE_TOLERANCE
    from rearrangement_planner.execution.mujoco_check import check_execution, ExecutionOptions
    from rearrangement_planner.physics.step import Physics
    from rearrangement_planner.physics.options import PhysicsOptions
    from rearrangement_planner.planning.requests.robustness import rollout_options, rollout_kernel
    from rearrangement_planner.model.scene import SupportPressure
    out = []
    for path in job:
        plan = np.load(path)
        fix = lambda p: p[p.index("config/"):] if "config/" in p else p   # the run's clone -> here
        scene = load_trial_scene(fix(str(plan["scene_path"])), fix(str(plan["robot"])))
        arm = np.array(plan["arm_path"], dtype=float)
        keep = [0] + [i for i in range(1, len(arm)) if np.max(np.abs(arm[i] - arm[i - 1])) > DUPLICATE_TOLERANCE]
        traj = time_parameterize(scene.robot, arm)
        if len(keep) != len(traj.times):
            continue
        rep = check_execution(scene, traj, None, ExecutionOptions(arm="servo"))
        g = scene.goal_index
        mj = np.array(rep.objects[g].pose)
        row = {"plan": Path(path).name, "objects": len(scene.objects), "shape": scene.objects[g].shape,
               "mj_reached": bool(rep.reached), "toppled": list(rep.toppled)}
        for s in SCALES:
            objs = tuple(dataclasses.replace(o, support=SupportPressure(s)) for o in scene.objects)
            sc = dataclasses.replace(scene, objects=objs)
            ph = Physics(sc, rollout_options(PhysicsOptions()))
            objects = np.empty((len(arm), *scene.object_poses.shape))
            objects[0] = scene.object_poses
            code = rollout_kernel(arm, objects, ph.arrays, ph.flag_count)
            end = objects[-1, g] if code == 0 else None
            if end is None:
                row[f"c{s}"] = {"code": int(code)}
                continue
            dyaw = (end[2] - mj[2] + math.pi) % (2 * math.pi) - math.pi
            # error along the way, at the trajectory points
            pred = objects[keep, g, :2]
            exe = rep.executed_paths[:, g, :2]
            n = min(len(pred), len(exe))
            row[f"c{s}"] = {"code": 0, "pos": round(float(np.hypot(*(end[:2] - mj[:2]))), 4),
                            "yaw": round(abs(float(dyaw)), 4),
                            "path": round(float(np.mean(np.hypot(*(pred[:n] - exe[:n]).T))), 4),
                            "reached": bool(sc.goal.reached(end[:2]))}
        print(json.dumps(row), flush=True)
        out.append(row)
    return out

if __name__ == "__main__":
    run, planner, dest = Path(sys.argv[1]), sys.argv[2], sys.argv[3]
    import csv
    rows = [r for r in csv.DictReader(open(run / "trials.csv")) if r["planner"] == planner and r["solved"] == "1"]
    from rearrangement_planner.tools.benchmark import plan_file
    paths = [str(plan_file(run / "plans", r)) for r in rows]
    paths = [p for p in paths if Path(p).exists()]
    with mp.get_context("spawn").Pool(2) as pool:
        parts = pool.map(work, [paths[0::2], paths[1::2]])
    with open(dest, "w") as f:
        for part in parts:
            for r in part:
                f.write(json.dumps(r) + "\n")
