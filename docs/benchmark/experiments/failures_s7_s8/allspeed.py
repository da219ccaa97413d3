"""Execute a run's saved plans with the servo arm, retimed so that every contact shape's axis end
points (not only the tool) move no faster than max_tool_speed."""
import sys, json
from pathlib import Path
import numpy as np
from rearrangement_planner.tools.benchmark import plan_file, load_trial_scene, read_trials
from rearrangement_planner.planning.requests import trajectory as tr
from rearrangement_planner.execution.mujoco_check import check_execution, ExecutionOptions
from rearrangement_planner.physics import kernels

_orig = tr._segment_rate_limits
def all_shapes(robot, positions, steps, options):
    base = _orig(robot, positions, steps, options)
    chain = kernels.compiled_chain(robot)
    pts = []
    for q in positions:
        poses = chain.shape_poses(q)
        ends = []
        for s, shape in enumerate(robot.contact_shapes):
            half = 0.5 * shape.dims[1] if shape.kind == "capsule" else 0.0
            a, b = kernels.segment(poses, s, half)
            ends.append(a); ends.append(b)
        pts.append(np.array(ends))
    pts = np.array(pts)                      # (N, 2S, 3)
    chords = np.linalg.norm(np.diff(pts, axis=0), axis=2).max(axis=1)
    with np.errstate(divide="ignore"):
        return np.minimum(base, options.max_tool_speed / chords)
tr._segment_rate_limits = all_shapes

out = Path(sys.argv[1]); planner = sys.argv[2]
for row in read_trials(out / "trials.csv"):
    if row["planner"] != planner or row["solved"] != "1":
        continue
    plan = np.load(plan_file(out / "plans", row))
    scene = load_trial_scene(str(plan["scene_path"]), str(plan["robot"]))
    traj = tr.time_parameterize(scene.robot, plan["positions"])
    rep = check_execution(scene, traj, None, ExecutionOptions(arm="servo"))
    goal = scene.objects[scene.goal_index].name
    print(json.dumps({"scene": row["scene"], "seed": row["seed"], "was": [row["executed_servo"], row["executed_toppled"], row["trajectory_s"]],
                      "now": [str(int(rep.reached)), str(len(rep.toppled)), round(traj.duration, 2)]}), flush=True)
