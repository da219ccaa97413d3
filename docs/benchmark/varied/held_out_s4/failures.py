"""How the shipped default's failing plans of held-out varied seed 4 fail (docs/benchmark.md,
"Both planners' candidates measured"): each solved plan that missed or toppled is executed again
with the servo arm, and every object that moved or toppled is printed.

    AMENT_PREFIX_PATH=.venv .venv/bin/python docs/benchmark/varied/held_out_s4/failures.py \
        docs/benchmark/experiments/alternate_planner/varied_s4/trials.csv \
        docs/benchmark/varied/held_out_s4/plans pc-rrt:alternate_planner=same
"""
import csv
import sys
from pathlib import Path

import numpy as np

from rearrangement_planner.execution.mujoco_check import ExecutionOptions, check_execution
from rearrangement_planner.physics.validation import load_scene
from rearrangement_planner.planning.requests.trajectory import TimingOptions, time_parameterize
from rearrangement_planner.tools.benchmark import plan_file

trials, plans, planner = Path(sys.argv[1]), Path(sys.argv[2]), sys.argv[3]
for row in csv.DictReader(open(trials)):
    if row["planner"] != planner or row["solved"] != "1":
        continue
    if row["executed_servo"] == "1" and int(row["executed_toppled"] or 0) == 0:
        continue
    scene = load_scene(Path("config/benchmark/varied") / f"{row['scene']}.yaml")
    plan = np.load(plan_file(plans, row))
    trajectory = time_parameterize(scene.robot, plan["arm_path"], TimingOptions())
    assert np.allclose(trajectory.positions, plan["positions"])
    report = check_execution(scene, trajectory, None, ExecutionOptions(arm="servo"))
    print(f"{row['scene']} robustness {row['robustness']} reached {report.reached} goal "
          f"{report.goal_distance_m:.2f} m from its point, toppled {list(report.toppled)}, "
          f"objects met {list(report.object_contacts)}, pushing links {row['pushing_links']}")
    for spec, outcome in zip(scene.objects, report.objects, strict=True):
        if outcome.moved_m > 0.005 or outcome.toppled:
            goal = " (goal)" if spec.name == scene.objects[scene.goal_index].name else ""
            print(f"    {spec.name}{goal} {spec.shape} {np.round(spec.size, 3).tolist()} "
                  f"mu_s {spec.support_friction:.2f} moved {outcome.moved_m:.2f} m, "
                  f"tilted {outcome.max_tilt_deg:.0f} deg")
