"""The MuJoCo check's reports of the plans make_plans.py wrote: each plan executed servo and
ideal, and in 2 perturbed worlds (seed 3); writes every report, less its wall time, as JSON to
argv[1] and prints the wall time. Run from a clone of each commit (PYTHONPATH=CLONE) and
compare the JSON files byte for byte.

    PYTHONPATH=CLONE AMENT_PREFIX_PATH=.venv .venv/bin/python check_reports.py OUT.json
"""
import json
import pickle
import re
import sys
import time

from rearrangement_planner.execution.mujoco_check import (
    ExecutionOptions,
    check_execution,
    check_perturbed,
)
from rearrangement_planner.physics.validation import load_scene

if __name__ == "__main__":
    with open("/tmp/mj_plans.pkl", "rb") as f:
        plans = pickle.load(f)
    reports = []
    start = time.time()
    for name, trajectory, states in plans:
        scene = load_scene(name)
        for arm in ("servo", "ideal"):
            reports.append(check_execution(scene, trajectory, states,
                                           ExecutionOptions(arm=arm)).to_dict())
        perturbed = check_perturbed(scene, trajectory, 2, seed=3)
        reports.append([r.to_dict() for r in perturbed.reports])
    print("wall", time.time() - start, file=sys.stderr)
    text = re.sub(r'"wall_time_s": [0-9.e-]+', "", json.dumps(reports, sort_keys=True,
                                                              default=str))
    with open(sys.argv[1], "w") as f:
        f.write(text)
