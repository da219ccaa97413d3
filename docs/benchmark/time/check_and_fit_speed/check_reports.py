"""The MuJoCo check's reports of the plans make_plans.py wrote: each plan executed servo and
ideal, and in 2 perturbed worlds (seed 3); writes every report (less wall time) as JSON to
argv[1] and prints the wall time. Run from a clone of each commit (PYTHONPATH=CLONE) and
compare the JSON files byte for byte.

    PYTHONPATH=CLONE AMENT_PREFIX_PATH=.venv .venv/bin/python check_reports.py OUT.json
"""
import sys, time, json, pickle
import numpy as np
from rearrangement_planner.execution.mujoco_check import check_execution, ExecutionOptions, check_perturbed
from rearrangement_planner.physics.validation import load_scene
if __name__ == "__main__":
    d = pickle.load(open("/tmp/mj_plans.pkl","rb"))
    res = []
    t=time.time()
    for name, traj, states in d:
        scene = load_scene(name)
        for arm in ("servo", "ideal"):
            r = check_execution(scene, traj, states, ExecutionOptions(arm=arm))
            dd = r.to_dict(); dd.pop("wall_time_s", None)
            res.append(dd)
        r = check_perturbed(scene, traj, 2, seed=3)
        res.append([x.to_dict() for x in r.reports])
    print("WALL", time.time()-t, file=sys.stderr)
    s = json.dumps(res, sort_keys=True, default=str)
    import re
    s = re.sub(r'"wall_time_s": [0-9.e-]+', '', s)
    open(sys.argv[1],"w").write(s)
