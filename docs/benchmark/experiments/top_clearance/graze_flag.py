"""Would a graze flag pick the toppling plans? Each answered plan of a benchmark run, replayed
in the model (simulated execution's physics) with `top_clearance` X for the arm behind the
tool: flagged when some step comes within X of an object's top from above or over its rim.
Cross-tabulated against the plan's MuJoCo execution (toppled, reached). Needs the code of
`85f60e5` (which has `top_clearance`):

    PYTHONPATH=<clone of 85f60e5> python graze_flag.py RUN_FOLDER... > graze_flag.txt
"""
import dataclasses
import sys
from pathlib import Path

import numpy as np

from rearrangement_planner.model.state import State
from rearrangement_planner.physics.options import simulation_options
from rearrangement_planner.physics.step import Invalid, Physics
from rearrangement_planner.tools.benchmark import load_trial_scene, plan_file, read_trials

CLEARANCES = (0.001, 0.003, 0.005, 0.01, 0.02)


def grazes(scene, arm_path, clearance):
    physics = Physics(scene, dataclasses.replace(simulation_options(), top_clearance=clearance))
    state = State(np.array(arm_path[0]), np.array(scene.object_poses))
    for q in arm_path[1:]:
        result = physics.step(state, q)
        if not result.valid:
            return result.reason is Invalid.OVER_TOP
        state = result.state
    return False


rows = []
for folder in map(Path, sys.argv[1:]):
    for row in read_trials(folder / "trials.csv"):
        if row["solved"] != "1":
            continue
        plan = np.load(plan_file(folder / "plans", row))
        # The scene by its set and name in this checkout (the run's clone may be gone).
        saved = Path(str(plan["scene_path"]))
        here = Path(__file__).resolve().parents[4] / "config" / "benchmark"
        scene = load_trial_scene(here / saved.parent.name / saved.name, str(plan["robot"]))
        flags = [grazes(scene, plan["arm_path"], c) for c in CLEARANCES]
        rows.append((row["scene"], row["seed"], row["executed_toppled"] not in ("0", ""),
                     row["executed_servo"] == "1", flags))
print(f"{len(rows)} solved plans of {', '.join(sys.argv[1:])}")
print("| clearance | flagged | flagged and toppling | flagged and reached | toppling, not flagged |")
print("|---|---|---|---|---|")
for i, c in enumerate(CLEARANCES):
    flagged = [r for r in rows if r[4][i]]
    print(f"| {c * 1000:.0f} mm | {len(flagged)} | {sum(r[2] for r in flagged)} of "
          f"{sum(r[2] for r in rows)} | {sum(r[3] for r in flagged)} of {sum(r[3] for r in rows)}"
          f" | {sum(r[2] and not r[4][i] for r in rows)} |")
