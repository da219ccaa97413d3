"""Per push segment of the goal object (a run of model steps that move it): what the segment
is (its length and turn in the model, the links that push, other objects moved with it,
the goal object's shape) and how much the model-vs-MuJoCo error of the goal object grows
over it (servo arm). Usage: segs.py RUN_DIR PLANNER OUT.jsonl"""
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
    from rearrangement_planner.planning.requests.robustness import rollout_options
    from rearrangement_planner.model.state import State
    out = []
    for path in job:
        plan = np.load(path)
        p = str(plan["scene_path"]); scene = load_trial_scene(p[p.index("config/"):], "")
        arm = np.array(plan["arm_path"], dtype=float)
        keep = [0] + [i for i in range(1, len(arm)) if np.max(np.abs(arm[i] - arm[i - 1])) > DUPLICATE_TOLERANCE]
        traj = time_parameterize(scene.robot, arm)
        ph = Physics(scene, rollout_options(PhysicsOptions()))
        g = scene.goal_index
        states = [State(arm[0], scene.object_poses)]
        links, moved = [frozenset()], [frozenset()]
        ok = True
        for q in arm[1:]:
            r = ph.step(states[-1], q)
            if not r.valid:
                ok = False; break
            states.append(r.state); links.append(r.pushing_links); moved.append(r.moved_objects)
        if not ok:
            continue
        rep = check_execution(scene, traj, None, ExecutionOptions(arm="servo"))
        exe = rep.executed_paths[:, g]
        pos = {k: i for i, k in enumerate(keep)}     # arm index -> trajectory point
        pred = np.array([s.objects[g] for s in states])
        err = lambda i: float(np.hypot(*(pred[i, :2] - exe[pos[i], :2]))) if i in pos else None
        i, n = 1, len(states)
        while i < n:
            if g in moved[i]:
                a = i - 1
                ls, others = set(), set()
                while i < n and g in moved[i]:
                    ls |= set(links[i]); others |= set(moved[i]) - {g}; i += 1
                b = i - 1
                ea, eb = err(a), err(b)
                if ea is None or eb is None:
                    continue
                d = pred[b] - pred[a]
                out.append({"plan": Path(path).name, "reached": bool(rep.reached), "shape": scene.objects[g].shape,
                            "length": round(float(np.hypot(d[0], d[1])), 4),
                            "turn": round(abs(float((d[2] + math.pi) % (2 * math.pi) - math.pi)), 4),
                            "links": sorted(ls), "others": len(others), "steps": b - a,
                            "err_a": round(ea, 4), "err_b": round(eb, 4)})
                print(json.dumps(out[-1]), flush=True)
            else:
                i += 1
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
